"""Reliability campaign: random regular drivetrains on several solvers, checked (regmech.bench.fuzz).

    python benchmarks/fuzz.py --models 200                  # seeds 0..199, report in benchmarks/results/fuzz.md
    python benchmarks/fuzz.py --models 500 --seed 1000 --jobs 2
    python benchmarks/fuzz.py --show 17                     # print the reproducer script of seed 17
    python benchmarks/fuzz.py --only 17 42 --verbose        # re-run some seeds, print their verdicts

Each model runs in a child process of its own: a run past ``--run-limit`` seconds is stopped inside the
child (a cooperative alarm between residual calls; the finding "budget"), and a child that does not answer
within the model's hard limit (``--model-limit``, default 6 x run limit + 60 s) is killed (a hang: the
finding "hang"). Verdicts are appended to ``--jsonl`` as they come, so ``--resume`` continues an interrupted
campaign and ``--recheck`` runs the models with findings again (after a fix); the Markdown report (``--out``)
is written from that file at the end (``--report-only`` rewrites it).
"""

from __future__ import annotations

import argparse
import collections
import json
import multiprocessing as mp
import os
import platform
import re
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
CAUSES_BEGIN, CAUSES_END = "<!-- fuzz-causes:begin -->", "<!-- fuzz-causes:end -->"


#: the families models are drawn from (``--families``): None all of them, or a tuple (``FAMILIES_BASIC``: the
#: models a seed drew with the first 26 families, to recheck the verdicts of the earliest runs)
FAMILY_SET = None


def _families(name):
    from regmech.bench.fuzz import FAMILIES_BASIC, FAMILIES_NO_IMPACTS
    return {"all": None, "basic": FAMILIES_BASIC, "no_impacts": FAMILIES_NO_IMPACTS}[name]


def _child(seed, conn, run_limit, max_calls, families=None):
    from regmech.bench.fuzz import evaluate, generate_seed
    try:
        spec = generate_seed(seed, families=families)
        v = evaluate(spec, time_limit_s=run_limit, max_calls=max_calls)
        conn.send(v.to_dict())
    except BaseException as exc:      # noqa: BLE001 - reported, never raised in the parent
        conn.send({"name": f"fuzz_{seed}", "seed": seed, "status": "finding", "families": [], "runs": [],
                   "findings": [{"kind": "crash", "detail": f"evaluate() itself: {type(exc).__name__}: {exc}",
                                 "run": "", "where": ""}], "refusals": [], "wall_s": 0.0, "n_components": 0})
    finally:
        conn.close()


def _warm_up():
    """Compile one small model of every family in the parent, so that forked children inherit the
    class kernels (each class's symbolic work is done once, not once per model)."""
    import warnings
    from regmech.bench.fuzz import FAMILIES, generate_seed
    for k, fam in enumerate(FAMILIES):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                generate_seed(10_000_000 + k, require=[fam], n_steps=1).build().compile()
        except Exception:           # noqa: BLE001 - the campaign reports it on its own model
            pass


def _start(seed, run_limit, max_calls, ctx):
    parent, child = ctx.Pipe(duplex=False)
    p = ctx.Process(target=_child, args=(seed, child, run_limit, max_calls, FAMILY_SET), daemon=True)
    p.start()
    child.close()
    return {"seed": seed, "proc": p, "conn": parent, "t0": time.perf_counter()}


def _lost(seed, kind, detail, wall):
    from regmech.bench.fuzz import generate_seed
    spec = generate_seed(seed, families=FAMILY_SET)
    return {"name": spec.name, "seed": seed, "status": "finding", "families": spec.families, "runs": [],
            "findings": [{"kind": kind, "detail": detail, "run": "", "where": ""}], "refusals": [],
            "wall_s": wall, "n_components": 0}


def _poll(job, model_limit):
    """The verdict of a running child, or None while it runs; kills it past ``model_limit``."""
    p, conn = job["proc"], job["conn"]
    wall = time.perf_counter() - job["t0"]
    v = None
    if conn.poll():
        try:
            v = conn.recv()
        except EOFError:          # the child died without an answer
            p.join(5.0)
            v = _lost(job["seed"], "crash", f"the child process died (exit code {p.exitcode})", wall)
    elif not p.is_alive():
        v = _lost(job["seed"], "crash", f"the child process died (exit code {p.exitcode})", wall)
    elif wall > model_limit:
        p.kill()
        v = _lost(job["seed"], "hang", f"no verdict within {model_limit:g} s: killed", wall)
    if v is None:
        return None
    p.join(5.0)
    if p.is_alive():
        p.kill()
        p.join()
    conn.close()
    v["process_s"] = wall
    return v


def load(path):
    from regmech.bench.fuzz import GROSS
    out = {}
    if path.exists():
        for line in path.read_text().splitlines():
            if line.strip():
                v = json.loads(line)
                for f in v["findings"]:     # verdicts written before the wrong-answer kind existed
                    if f["kind"] == "disagreement" and v.get("pairs", {}).get(f["run"], (0.0,))[0] > GROSS:
                        f["kind"] = "wrong-answer"
                out[v["seed"]] = v
    return out


def campaign(args):
    jsonl = Path(args.jsonl)
    jsonl.parent.mkdir(parents=True, exist_ok=True)
    seeds = args.only if args.only else list(range(args.seed, args.seed + args.models))
    done = load(jsonl) if args.resume or args.recheck else {}
    if args.recheck:
        # run again the models with findings (after a change of the checks or a fix) and those with a
        # family of --recheck-with; keep the other verdicts
        again = set(args.recheck_with or ())
        seeds = [s for s in seeds if s in done and (done[s]["status"] == "finding" or again & set(done[s]["families"]))]
        done = {s: v for s, v in done.items() if s not in seeds}
        jsonl.write_text("".join(json.dumps(v) + "\n" for v in done.values()))
    elif not args.resume and not args.only and jsonl.exists():
        jsonl.unlink()
    todo = [s for s in seeds if s not in done]
    model_limit = args.model_limit or 6 * args.run_limit + 60.0
    ctx = mp.get_context("fork")
    _warm_up()
    t0 = time.perf_counter()
    running = []
    results = {}
    queue = list(todo)
    with open(jsonl, "a") as fh:
        while queue or running:
            while queue and len(running) < args.jobs:
                running.append(_start(queue.pop(0), args.run_limit, args.max_calls, ctx))
            time.sleep(0.02)
            for job in list(running):
                v = _poll(job, model_limit)
                if v is None:
                    continue
                running.remove(job)
                s = job["seed"]
                results[s] = v
                fh.write(json.dumps(v) + "\n")
                fh.flush()
                print(f"[{len(results)}/{len(todo)} {time.perf_counter() - t0:.0f} s] seed {s}: {v['status']} "
                      f"({v['process_s']:.1f} s) {','.join(v['families'])}", file=sys.stderr)
                if args.verbose:
                    for f in v["findings"]:
                        print(f"    {f['kind']} [{f['run']}] {f['detail']}", file=sys.stderr)
                    for r in v["refusals"]:
                        print(f"    refused [{r[0]}] {r[1]}: {r[2]}", file=sys.stderr)
    return time.perf_counter() - t0


# ----------------------------------------------------------------------------- report
def _cause(f):
    """A grouping key for a finding: its kind and what it involves (component class, error, run pair)."""
    kind, detail, run = f["kind"], f["detail"], f["run"]
    if kind == "crash":
        m = re.match(r"(\w+) \(not a regmech error\): (.*?)( \(at (.*)\))?$", detail)
        if m:
            return f"crash: {m.group(1)} at {m.group(4) or '?'}"
        return "crash: " + detail[:80]
    if kind in ("loss-supplies-power", "lossless-dissipates"):
        cls = (f.get("where") or "").split(" ")[0]
        return f"{kind}: {cls}"
    if kind in ("wrong-answer", "disagreement", "range-accuracy", "convergent-accuracy", "ill-conditioned"):
        return kind
    if kind in ("power-balance", "energy-books", "budget", "nonfinite"):
        return f"{kind}: {run}"
    return kind


def _norm_refusal(cls, msg):
    """A refusal's message with numbers and quoted names replaced, for counting kinds of refusals."""
    msg = re.sub(r"'[^']*'", "'…'", msg)
    msg = re.sub(r"[-+]?\d[\d.eE+-]*", "#", msg)
    return f"{cls}: {msg[:110]}"


def report(jsonl, out, wall, args):
    import regmech
    from regmech.bench.fuzz import FAMILIES, RUNS
    verdicts = sorted(load(Path(jsonl)).values(), key=lambda v: v["seed"])
    if args.only is None and not args.report_only:
        keep = set(range(args.seed, args.seed + args.models))
        verdicts = [v for v in verdicts if v["seed"] in keep]
    n = len(verdicts)
    status = collections.Counter(v["status"] for v in verdicts)
    lines = ["# Reliability: random regular drivetrains", ""]
    try:
        import numpy, scipy
        versions = f"numpy {numpy.__version__}, scipy {scipy.__version__}"
    except ImportError:    # pragma: no cover
        versions = ""
    seeds = [v["seed"] for v in verdicts]
    lines += [f"`python benchmarks/fuzz.py --models {n} --seed {min(seeds) if seeds else 0}` "
              f"({platform.machine()}, {os.cpu_count()} cores, python {platform.python_version()}, {versions}, "
              f"regmech {getattr(regmech, '__version__', '?')}; {args.jobs} job(s), run limit {args.run_limit:g} s, "
              f"work budget {args.max_calls} evaluations per run" + (f", {wall:.0f} s wall" if wall else "") + ").",
              "",
              "Each model is generated by `regmech.bench.fuzz.generate_seed(seed)` (a regular drivetrain of 2 to 7 "
              "components drawn from every family, parameters across decades) and run on "
              + ", ".join(f"`{label}` ({solver}{''.join(f', {k}={v:g}' for k, v in opts.items())})"
                          for label, solver, opts in RUNS)
              + " (expm only on models that are linear between friction events). Checks per run: no exception "
              "that is not a regmech error, no NaN/inf, the power balance at every output instant, the energy "
              "books, no loss element supplying power, every pair of returned runs within the sum of their "
              "claims (1e4 x rtol of the range of each kind of signal, or a fixed-step run's tol), the default "
              "call (`default`: `m.simulate(t_end, dt_out)`) within the default accuracy 1e-3 of the tight reference "
              "in the accuracy contract's measure, the budget. "
              "`python benchmarks/fuzz.py --show SEED` prints a finding's model as a script.", ""]
    any_ref = sum(1 for v in verdicts if v["refusals"])
    lines += ["| models run | passed (every run returned, every check held) | refused (a run stopped with a named "
              "regmech error, no finding) | with findings | models with at least one refused run |",
              "|---:|---:|---:|---:|---:|",
              f"| {n} | {status['pass']} | {status['refused']} | {status['finding']} | {any_ref} |", ""]
    # per run
    per_run = collections.defaultdict(collections.Counter)
    for v in verdicts:
        for o in v["runs"]:
            per_run[o["label"]][o["status"]] += 1
    lines += ["| run | returned | refused | crash | over budget | not applicable |", "|---|---:|---:|---:|---:|---:|"]
    for label, _, _ in RUNS:
        c = per_run[label]
        lines.append(f"| {label} | {c['ok']} | {c['refused']} | {c['crash']} | {c['budget']} | {c['skipped']} |")
    lines.append("")
    # findings by cause
    groups = collections.defaultdict(list)
    for v in verdicts:
        seen = set()
        for f in v["findings"]:
            key = _cause(f)
            if key in seen:
                continue
            seen.add(key)
            groups[key].append((v, f))
    lines += ["## Findings by kind", ""]
    if not groups:
        lines += ["None.", ""]
    else:
        lines += ["| kind (what is involved) | models | seeds (first 8) | example |", "|---|---:|---|---|"]
        for key, items in sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0])):
            ex = items[0][1]["detail"].replace("|", "/")
            ex = ex if len(ex) <= 220 else ex[:217] + "..."
            lines.append(f"| {key} | {len(items)} | {', '.join(str(v['seed']) for v, _ in items[:8])} | "
                         f"seed {items[0][0]['seed']} [{items[0][1]['run']}]: {ex} |")
        lines.append("")
    # refusals
    ref = collections.Counter()
    ref_seeds = collections.defaultdict(list)
    for v in verdicts:
        for label, cls, msg in v["refusals"]:
            key = f"{label}: {_norm_refusal(cls, msg)}"
            ref[key] += 1
            ref_seeds[key].append(v["seed"])
    lines += ["## Refusals (a solver stopped with a regmech error)", ""]
    if not ref:
        lines += ["None.", ""]
    else:
        lines += ["| run: error (numbers and names elided) | runs | seeds (first 6) |", "|---|---:|---|"]
        for key, cnt in ref.most_common():
            lines.append(f"| {key.replace('|', '/')} | {cnt} | {', '.join(map(str, ref_seeds[key][:6]))} |")
        lines.append("")
    # coverage
    cov = collections.Counter(f for v in verdicts for f in v["families"])
    bad = collections.Counter(f for v in verdicts if v["status"] == "finding" for f in v["families"])
    lines += ["## Families covered", "",
              "| family | models | with findings |", "|---|---:|---:|"]
    for fam in FAMILIES:
        lines.append(f"| {fam} | {cov[fam]} | {bad[fam]} |")
    lines.append("")
    walls = sorted(v.get("process_s", v["wall_s"]) for v in verdicts)
    if walls:
        lines += [f"Time per model (all runs and checks, child process): median {walls[len(walls) // 2]:.1f} s, "
                  f"max {walls[-1]:.1f} s.", ""]
    kept = ""
    if Path(out).exists():
        old = Path(out).read_text()
        if CAUSES_BEGIN in old and CAUSES_END in old:
            kept = old[old.index(CAUSES_BEGIN): old.index(CAUSES_END) + len(CAUSES_END)]
    lines += ["## Findings by cause (written by hand from the verdicts; kept when the report is rewritten)", "",
              kept or f"{CAUSES_BEGIN}\n(not analysed yet)\n{CAUSES_END}", ""]
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text("\n".join(lines) + "\n")
    print(f"wrote {out}", file=sys.stderr)
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", type=int, default=100, help="number of models (seeds --seed .. --seed + N - 1)")
    ap.add_argument("--seed", type=int, default=0, help="first seed")
    ap.add_argument("--only", type=int, nargs="+", help="run these seeds only (report not rewritten)")
    ap.add_argument("--jobs", type=int, default=1, help="models run at once (child processes)")
    ap.add_argument("--run-limit", type=float, default=60.0, help="wall-clock limit of one solver run [s]")
    ap.add_argument("--model-limit", type=float, default=None, help="hard limit of one model's child process [s]")
    ap.add_argument("--max-calls", type=int, default=2_000_000, help="work budget of one run (equation evaluations)")
    ap.add_argument("--out", default=str(RESULTS / "fuzz.md"), help="Markdown report")
    ap.add_argument("--jsonl", default=str(RESULTS / "fuzz" / "verdicts.jsonl"), help="verdicts, one JSON a line")
    ap.add_argument("--resume", action="store_true", help="keep the verdicts already in --jsonl, run the rest")
    ap.add_argument("--recheck", action="store_true", help="run the models with findings in --jsonl again")
    ap.add_argument("--recheck-with", nargs="+", metavar="FAMILY", help="with --recheck: also the models with these")
    ap.add_argument("--report-only", action="store_true", help="rewrite the report from --jsonl")
    ap.add_argument("--show", type=int, help="print the reproducer script of this seed and exit")
    ap.add_argument("--verbose", action="store_true")
    ap.add_argument("--families", choices=("all", "basic", "no_impacts"), default="all",
                    help="families to draw from: all; basic (the first 26, without the drivetrain components) or "
                         "no_impacts (all but hard_stop and thermal_friction) draw the models of earlier runs' seeds, "
                         "e.g. to --recheck them: runs up to seed 69999 used no_impacts")
    args = ap.parse_args(argv)
    global FAMILY_SET
    FAMILY_SET = _families(args.families)
    if args.show is not None:
        from regmech.bench.fuzz import generate_seed
        print(generate_seed(args.show, families=FAMILY_SET).script("ida", rtol=1e-8))
        return 0
    wall = 0.0
    if not args.report_only:
        if args.only:
            args.jsonl = str(Path(args.jsonl).with_name("only.jsonl"))
            if Path(args.jsonl).exists():
                Path(args.jsonl).unlink()
        wall = campaign(args)
    if args.only:
        return 0
    report(args.jsonl, args.out, wall, args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
