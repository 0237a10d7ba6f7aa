"""Reliability campaign: random *regular* drivetrains, run on several solvers and checked.

Two halves, used by ``tests/fuzz`` (hypothesis, a fixed-seed subset) and by
``benchmarks/fuzz.py`` (a long campaign with a report):

**The generator** (``generate(rng)``, ``generate_seed(seed)``) grows a model
from one mass by attaching components of every family (``FAMILIES``) to the
masses already there, with parameters drawn across decades. It builds only
models that obey the rules of the regular mechanical system, so a
``RegularityError`` is a bug of the generator, never a finding:

* every device flange lands on a mass (``Inertia``, ``Mass``, a wheel's
  inertia or axle) or on the ground (``Fixed``); devices never meet;
* friction devices have a mass (or the ground) on each side;
* the model grows as a tree of rigid links: a rigid device (rigid ``Shaft``,
  gears, planetary, differential) always brings at least one new mass, so
  rigid constraints never close a loop; only compliant and friction devices
  close loops, and only between masses of different rigid groups;
* at most one prescribed-motion source (``Speed``, ``Position``, ...) per
  rigid group, and none on a group that has a start value; at most one mass
  per rigid group gets start values (a second could contradict it);
* link stiffnesses come from a natural frequency drawn in [1, 10^2.5] rad/s
  and the masses they join, so the spectrum stays where a tight reference
  can resolve it (IDA's round-off refusal at rtol 1e-10 starts near a
  spread of 7e3).

A generated model is a ``ModelSpec``: the Python *source* of a script that
builds it with the public API only. ``spec.build()`` executes exactly that
source, so ``spec.script()`` is a standalone reproducer of any finding.

**The checks** (``evaluate(spec)``) run the model on every solver of
``RUNS`` (two at the answer tolerance rtol 1e-8, two tight references,
``expm`` when the model is linear between friction events, and the default
call) and return a
``Verdict``: ``pass``, ``refused`` (a solver stopped with a regmech error:
its class and message) or ``finding`` (a list of ``Finding(kind, detail)``):

``crash``
    an exception that is not a regmech error;
``budget``
    a run exceeded its work budget (residual/RHS evaluations) or time limit;
``nonfinite``
    NaN or inf in a returned signal;
``power-balance``
    at an output instant, ``sum_b m_b v_b a_b + sum_d P_d != 0`` (the rate of
    kinetic energy against the power all devices absorb, sources included,
    from the result's own ``.kinetic``/``.a``/``.power`` signals) beyond the
    run's claimed error times the power scale;
``energy-books``
    the books ``kinetic + stored + dissipated = work in`` do not close
    (integrated on the output grid, see ``energy_checks``);
``loss-supplies-power``
    a friction or loss element (clutch, brake, one-way clutch, bearing
    friction, friction contact, lossy gear and planetary, damper, road load,
    tyre) supplies power, or a dissipative element with stored energy
    (spring-damper, elasto-backlash) has falling accumulated dissipation;
    ``lossless-dissipates``: an ideal element (spring, rigid shaft, ideal
    gear, planetary, differential, rolling, backlash) dissipates or supplies;
``wrong-answer``, ``disagreement``, ``range-accuracy``
    two solver runs that both returned differ by more than the sum of what
    each claims (``claimed_error``, ``agreement``): by far, by a little, or
    only against the range of a signal that varies little;
``convergent-accuracy``
    a disagreement (not by far) that shrinks with the tolerance: the same two
    solvers at the other tolerance level (``COMPANIONS``) differ at least
    ``CONVERGENCE`` times less (or more, for the references), and every run
    involved makes the same mode changes as its companion. The runs converge
    to one answer on one path; the looser of them is less accurate than the
    stand-in claim ``CLAIM_PER_RTOL * rtol`` (an accuracy shortfall of
    tolerance-proportional step control, not a different answer);
``ill-conditioned``
    a ``wrong-answer`` or ``disagreement`` of two runs at plain tolerances that
    the model's own sensitivity explains (``conditioning``): the tight
    reference, re-run with every mass perturbed by a relative amount equal to
    the larger rtol of the pair, moves by at least ``EXPLAINED_SHARE`` of the
    pair's difference or by ``GROSS`` times the pair's claims. Perturbations
    of the size of the tolerance grow to the size of the difference, so no
    solver at that rtol can do better (seed 20152, a rattle of ~100 contacts:
    a 1e-8 perturbation of the masses moves the wheel speed by 5 % of its
    range). Such a model's global error is what
    the accuracy contract measures: the default call must meet its accuracy
    or refuse (``default-accuracy``);
``default-accuracy``
    the default call (``RUNS`` label ``default``: ``m.simulate(t_end, dt_out)``,
    solver auto at the default accuracy 1e-3) is further from the tight
    reference than it promises, in the accuracy contract's measure
    (``default_accuracy``);
``generator``
    the generated model is refused before any solver runs (a bug here).
"""

from __future__ import annotations

import math
import random
import time
import traceback
from dataclasses import asdict, dataclass, field

import numpy as np

# ============================================================================ generator

#: component families and their weight in a random plan (every family appears in a long campaign)
FAMILIES = {
    # masses are created by the others; links
    "spring": 3, "damper": 2, "spring_damper": 3, "shaft_rigid": 2, "shaft_elastic": 3,
    "backlash": 2, "elasto_backlash": 2,
    # gears
    "ideal_gear": 3, "lossy_gear": 3, "planetary": 2, "lossy_planetary": 2, "differential": 2,
    "limited_slip_differential": 2,
    # friction
    "clutch": 3, "brake": 3, "one_way_clutch": 2, "bearing_friction": 2, "friction_contact": 3,
    # vehicle
    "wheel": 2, "magic_formula_wheel": 1, "road_load": 1, "engine": 1,
    # sources
    "torque": 4, "force": 3, "speed": 2, "position": 2,
    # electric machines and closed-loop control (sources too: they feed work in)
    "dc_motor": 2, "electric_motor": 2, "pi_control": 2,
    # drivetrain components: stops, loads, friction laws, transmissions
    "end_stop": 2, "elasto_gap": 1, "speed_load": 2, "stribeck_clutch": 2, "linear_brake": 1, "vehicle_load": 1,
    "gearbox": 1, "torque_converter": 1,
    # rigid impacts and friction heating inside the DAE
    "hard_stop": 2, "thermal_friction": 2,
}
#: the 26 families before the drivetrain components (stops, loads, friction laws, transmissions), in their
#: order: ``generate(families=FAMILIES_BASIC)`` draws the models the earliest fuzz runs drew for the same seeds
#: (regression tests pinned to such a seed use it)
FAMILIES_BASIC = tuple(FAMILIES)[:26]
#: every family but ``hard_stop`` and ``thermal_friction``: the models of fuzz seeds 60000-69999
#: (``benchmarks/results/fuzz/verdicts.jsonl``) as they were drawn
FAMILIES_NO_IMPACTS = tuple(f for f in FAMILIES if f not in ("hard_stop", "thermal_friction"))
#: signal types drawn for sources and normal forces ("callable": a lambda of t)
SIGNALS = ("Constant", "Step", "Ramp", "Sine", "Table", "Pulse", "callable")
#: families that need a translational mass to attach to
TRANSLATIONAL_FAMILIES = {"friction_contact", "force", "road_load", "linear_brake", "vehicle_load", "elasto_gap"}
SOURCE_FAMILIES = {"torque", "force", "speed", "position", "engine", "dc_motor", "electric_motor", "pi_control"}


def _fmt(x: float) -> str:
    """A float written with 4 significant digits (the script stays readable; the value is what it says)."""
    x = float(f"{float(x):.4g}")
    return repr(x) if x != int(x) or abs(x) >= 1e15 else repr(float(int(x)))


@dataclass
class ModelSpec:
    """A generated model: the statements that build it (public API only) and how to run it."""

    name: str
    lines: list
    t_end: float
    dt_out: float
    families: list
    seed: int | None = None
    linear: bool | None = None      # filled by evaluate(): expm applies

    def source(self) -> str:
        head = ["import math", "import regmech as rm", "from regmech.components import *",
                "from regmech.components.laws import Stribeck",
                "from regmech.signals import *"]
        if any("ThermalMass(" in line for line in self.lines):
            head.append("from regmech.components.heat import ThermalMass")
        head += ["", f"m = rm.Model({self.name!r})"]
        return "\n".join(head + list(self.lines)) + "\n"

    def script(self, solver: str = "ida", **options) -> str:
        """A standalone reproducer: the model, then one run."""
        opts = "".join(f", {k}={v!r}" for k, v in options.items())
        return (self.source() + f"res = m.simulate({self.t_end!r}, dt_out={self.dt_out!r}, "
                f"solver={solver!r}{opts})\nprint(res.stats)\n")

    def build(self):
        """Execute the source and return the model ``m`` (the reproducer runs exactly this)."""
        ns: dict = {}
        exec(compile(self.source(), f"<fuzz model {self.name}>", "exec"), ns)   # noqa: S102 - our own text
        return ns["m"]


@dataclass
class _Body:
    var: str            # the component variable that carries the start values (or None: not startable)
    flange: str         # expression of a flange of the mass ("J3.flange_b", "wheel1.hub")
    domain: str
    mass: float
    group: int
    start: str | None   # "inertia" | "mass" | "wheel" | None


class _Gen:
    """One model's generation state (see the module docstring for the rules it keeps)."""

    def __init__(self, rng, name, references="any"):
        self.rng = rng
        self.name = name
        self.references = references
        self.comps: dict[str, dict] = {}          # var -> {"cls": ..., "kw": {param: source}}
        self.order: list[str] = []
        self.conns: list[tuple[str, str]] = []
        self.bodies: list[_Body] = []
        self.parent: dict[int, int] = {}
        self.driven: set[int] = set()              # rigid groups with a prescribed-motion source
        self.high_start: dict[int, _Body] = {}      # group -> body that must start fast (one-way clutch side b)
        self.at_zero: list[_Body] = []              # bodies whose groups start at position 0 (inside a hard stop)
        self.count: dict[str, int] = {}
        self.used: list[str] = []
        self.grounds: dict[str, str] = {}
        self.t_end = 10 ** rng.uniform(-0.7, 0.3)
        self.tau_scale = 10 ** rng.uniform(-1.0, 2.5)     # torques [N m]
        self.f_scale = 10 ** rng.uniform(0.0, 3.0)        # forces [N]
        self.omega_max = 1.0

    # -- helpers -------------------------------------------------------------
    def u(self, a, b):
        return self.rng.uniform(a, b)

    def dec(self, a, b):
        """A value spread evenly over the decades 10^a .. 10^b."""
        return 10 ** self.rng.uniform(a, b)

    def chance(self, p):
        return self.rng.random() < p

    def pick(self, seq):
        return seq[self.rng.randrange(len(seq))]

    def new_name(self, prefix):
        k = self.count.get(prefix, 0) + 1
        self.count[prefix] = k
        return f"{prefix}{k}"

    def add(self, prefix, cls, **kw):
        var = self.new_name(prefix)
        self.comps[var] = {"cls": cls, "kw": dict(kw)}
        self.order.append(var)
        return var

    def connect(self, a, b):
        self.conns.append((a, b))

    def ground(self, domain):
        if domain not in self.grounds:
            var = "fixed" if domain == "rotational" else "wall"
            self.comps[var] = {"cls": "Fixed", "kw": {} if domain == "rotational" else {"domain": "'translational'"}}
            self.order.append(var)
            self.grounds[domain] = var
        return f"{self.grounds[domain]}.flange"

    def find(self, g):
        while self.parent[g] != g:
            self.parent[g] = self.parent[self.parent[g]]
            g = self.parent[g]
        return g

    def union(self, *bodies):
        roots = {self.find(b.group) for b in bodies}
        root = min(roots)
        for r in roots:
            self.parent[r] = root
        if roots & self.driven:
            self.driven |= {root}
        for r in roots:
            if r in self.high_start and root not in self.high_start:
                self.high_start[root] = self.high_start[r]

    def _body(self, var, flange, domain, mass, start):
        g = len(self.parent)
        self.parent[g] = g
        b = _Body(var, flange, domain, mass, g, start)
        self.bodies.append(b)
        return b

    def new_mass(self, domain, mass=None):
        if domain == "rotational":
            J = mass if mass is not None else self.dec(-2.0, 1.0)
            var = self.add("J", "Inertia", J=_fmt(J))
            return self._body(var, f"{var}.{self.pick(('flange_a', 'flange_b'))}", domain, float(_fmt(J)), "inertia")
        m = mass if mass is not None else self.dec(-1.0, 3.0)
        var = self.add("M", "Mass", m=_fmt(m))
        return self._body(var, f"{var}.{self.pick(('flange_a', 'flange_b'))}", domain, float(_fmt(m)), "mass")

    def flange(self, body):
        """A flange of the mass (inertias and masses have two; either one is the same node)."""
        if body.start in ("inertia", "mass"):
            return f"{body.var}.{self.pick(('flange_a', 'flange_b'))}"
        return body.flange

    def anchor(self, domain):
        """An existing mass of the domain to attach to (a new one when there is none)."""
        cands = [b for b in self.bodies if b.domain == domain]
        return self.pick(cands) if cands else self.new_mass(domain)

    def stiffness(self, *masses):
        """c = omega^2 * reduced mass, omega drawn in [1, 10^2.5] rad/s."""
        omega = self.dec(0.0, 2.5)
        self.omega_max = max(self.omega_max, omega)
        if len(masses) == 1:
            red = masses[0]
        else:
            red = masses[0] * masses[1] / (masses[0] + masses[1])
        return omega ** 2 * red, omega, red

    def damping(self, omega, red, allow_zero=True):
        if allow_zero and self.chance(0.2):
            return 0.0
        return 2.0 * self.dec(-3.0, 0.0) * omega * red

    # -- signals -------------------------------------------------------------
    def signal(self, lo, hi, kinds=SIGNALS, start_at_zero=False):
        """Source text of a signal of a random type with values in [lo, hi] (``start_at_zero``: a Sine
        starts at t = 0, so that it has no jump or corner later)."""
        kind = self.pick(kinds)
        T = self.t_end
        val = lambda: self.u(lo, hi)                               # noqa: E731
        if kind == "Constant":
            return f"Constant({_fmt(val())})"
        if kind == "Step":
            a, b = val(), val()
            return f"Step(height={_fmt(b - a)}, start_time={_fmt(self.u(0.05, 0.9) * T)}, offset={_fmt(a)})"
        if kind == "Ramp":
            a, b = val(), val()
            t0 = self.u(0.0, 0.6) * T
            return (f"Ramp(height={_fmt(b - a)}, duration={_fmt(self.u(0.05, 0.5) * T)}, start_time={_fmt(t0)}, "
                    f"offset={_fmt(a)})")
        if kind == "Sine":
            mid, half = (lo + hi) / 2, (hi - lo) / 2
            off = mid + self.u(-0.5, 0.5) * half
            amp = (half - abs(off - mid)) * self.u(0.2, 1.0)
            f = self.dec(0.0, 1.3) / T
            phase, start = self.u(0, 2 * math.pi), self.pick((0.0, self.u(0, 0.5) * T))
            return (f"Sine(amplitude={_fmt(amp)}, freq_hz={_fmt(f)}, phase={_fmt(phase)}, "
                    f"offset={_fmt(off)}, start_time={_fmt(0.0 if start_at_zero else start)})")
        if kind == "Table":
            n = self.rng.randint(2, 5)
            ts = sorted({round(self.u(0.0, T), 6) for _ in range(n)} | {0.0})
            return "Table([" + ", ".join(f"({_fmt(t)}, {_fmt(val())})" for t in ts) + "])"
        if kind == "Pulse":
            a, b = val(), val()
            return (f"Pulse(amplitude={_fmt(b - a)}, width={_fmt(self.u(10, 90))}, period={_fmt(T / self.dec(0.3, 1.3))}, "
                    f"start_time={_fmt(self.u(0, 0.3) * T)}, offset={_fmt(a)})")
        # a callable: no breakpoints known, smooth
        mid, half = (lo + hi) / 2, (hi - lo) / 2
        form = self.rng.randrange(3)
        if form == 0:
            amp = half * self.u(0.2, 1.0)
            off = mid + self.u(-1, 1) * (half - amp)
            return (f"lambda t: {_fmt(off)} + {_fmt(amp)} * math.sin({_fmt(2 * math.pi * self.dec(0, 1.3) / T)} * t "
                    f"+ {_fmt(self.u(0, 6.28))})")
        if form == 1:
            a, b = val(), val()
            return f"lambda t: {_fmt(a)} + {_fmt(b - a)} * (1.0 - math.exp(-t / {_fmt(self.u(0.05, 0.5) * T)}))"
        a, b = val(), val()
        return (f"lambda t: {_fmt((a + b) / 2)} + {_fmt((b - a) / 2)} * math.tanh((t - {_fmt(self.u(0.1, 0.8) * T)}) "
                f"/ {_fmt(self.u(0.02, 0.2) * T)})")

    def normalized(self):
        """A normalised normal force in [0, 1] (any signal type)."""
        if self.chance(0.15):
            return self.pick(("1.0", "0.0"))
        return self.signal(0.0, 1.0)

    def mu_kwargs(self):
        if self.chance(0.3):
            n = self.rng.randint(1, 4)
            ws = sorted({0.0} | {round(self.dec(-1, 2), 4) for _ in range(n)})
            return {"mu_table": "[" + ", ".join(f"({_fmt(w)}, {_fmt(self.u(0.05, 0.9))})" for w in ws) + "]"}
        return {"mu": _fmt(self.u(0.05, 0.9))}

    # -- families ------------------------------------------------------------
    def link(self, family, domain=None):
        """A two-flange compliant (or rigid) link from an existing mass to a new one, to the ground,
        or (compliant only) between two masses of different rigid groups."""
        domain = domain or ("rotational" if family in ("shaft_rigid", "shaft_elastic") or self.chance(0.7)
                            else "translational")
        a = self.anchor(domain)
        where = self.rng.random()
        rigid = family == "shaft_rigid"
        others = [b for b in self.bodies if b.domain == domain and self.find(b.group) != self.find(a.group)]
        if not rigid and where < 0.15:
            b, mb = None, None
        elif not rigid and where < 0.3 and others:
            b = self.pick(others)
            mb = b.mass
        else:
            b = self.new_mass(domain)
            mb = b.mass
        c, omega, red = self.stiffness(a.mass, *(() if mb is None else (mb,)))
        dom = {} if domain == "rotational" else {"domain": "'translational'"}
        if family == "spring":
            var = self.add("spring", "Spring", c=_fmt(c), **dom)
        elif family == "damper":
            var = self.add("damper", "Damper", d=_fmt(self.damping(omega, red, allow_zero=False)), **dom)
        elif family == "spring_damper":
            var = self.add("sd", "SpringDamper", c=_fmt(c), d=_fmt(self.damping(omega, red)), **dom)
        elif family == "shaft_rigid":
            var = self.add("shaft", "Shaft", stiffness="None")
        elif family == "shaft_elastic":
            var = self.add("shaft", "Shaft", stiffness=_fmt(c), damping=_fmt(self.damping(omega, red)))
        elif family == "backlash":
            var = self.add("bl", "Backlash", c=_fmt(c), b=_fmt(self.pick((0.0, self.dec(-3, -0.5)))), **dom)
        else:
            var = self.add("ebl", "ElastoBacklash", c=_fmt(c), d=_fmt(self.damping(omega, red)),
                           b=_fmt(self.pick((0.0, self.dec(-3, -0.5)))), **dom)
        ends = [self.flange(a), self.ground(domain) if b is None else self.flange(b)]
        if self.chance(0.5):
            ends.reverse()
        self.connect(f"{var}.flange_a", ends[0])
        self.connect(f"{var}.flange_b", ends[1])
        if rigid:
            self.union(a, b)
        return a, b

    def gear(self, family):
        a = self.anchor("rotational")
        if family in ("ideal_gear", "lossy_gear"):
            ratio = self.pick((1, -1)) * self.dec(-1, 1)
            b = self.new_mass("rotational", mass=a.mass * ratio ** -2 * self.dec(-1, 1))
            if family == "ideal_gear":
                var = self.add("gear", "IdealGear", ratio=_fmt(ratio))
            else:
                var = self.add("lgear", "LossyGear", ratio=_fmt(ratio), loss_table=self.loss_table())
            ends = [self.flange(a), self.flange(b)]
            if self.chance(0.5):
                ends.reverse()
            self.connect(f"{var}.flange_a", ends[0])
            self.connect(f"{var}.flange_b", ends[1])
            if self.chance(0.15):
                # a moving housing: the support on a third mass
                s = self.new_mass("rotational")
                self.connect(f"{var}.support", self.flange(s))
                self.union(a, b, s)
            else:
                self.union(a, b)
            return
        if family in ("planetary", "lossy_planetary"):
            ratio = self.dec(0.1, 0.7)
            if family == "planetary":
                var = self.add("planet", "Planetary", ratio=_fmt(ratio))
            else:
                var = self.add("lplanet", "LossyPlanetary", ratio=_fmt(ratio), loss_table=self.loss_table())
            ports = ["sun", "carrier", "ring"]
            self.rng.shuffle(ports)
            self.connect(f"{var}.{ports[0]}", self.flange(a))
            joined = [a]
            for p in ports[1:]:
                if p == "ring" and self.chance(0.3):
                    self.connect(f"{var}.ring", self.ground("rotational"))   # ring held: an ordinary reduction
                else:
                    nb = self.new_mass("rotational")
                    self.connect(f"{var}.{p}", self.flange(nb))
                    joined.append(nb)
            self.union(*joined)
            return
        ratio = self.pick((1.0, self.dec(0, 0.7)))
        left, right = None, None
        if family == "differential":
            var = self.add("diff", "Differential", ratio=_fmt(ratio))
            left, right = self.new_mass("rotational"), self.new_mass("rotational")
            self.connect(f"{var}.left", self.flange(left))
            self.connect(f"{var}.right", self.flange(right))
        else:
            var = self.add("lsd", "LimitedSlipDifferential", ratio=_fmt(ratio),
                           preload=_fmt(self.tau_scale * self.dec(-1, 0.7) / 0.005),
                           mu=_fmt(self.u(0.05, 0.3)), cgeo=_fmt(0.05), peak=_fmt(self.u(1.0, 1.5)),
                           J_side=_fmt(a.mass * self.dec(-2, -0.5)))
            J_side = float(self.comps[var]["kw"]["J_side"])
            left = self._body(None, f"{var}.left", "rotational", J_side, None)
            right = self._body(None, f"{var}.right", "rotational", J_side, None)
        self.connect(f"{var}.carrier", self.flange(a))
        self.union(a, left, right)

    def loss_table(self):
        n = self.rng.randint(1, 3)
        ws = sorted({0.0} | {round(self.dec(-1, 2), 4) for _ in range(n - 1)})
        rows = []
        for w in ws:
            ideal = self.chance(0.1)
            e1, e2 = (1.0, 1.0) if ideal else (self.u(0.5, 1.0), self.u(0.5, 1.0))
            b1, b2 = (0.0, 0.0) if ideal or self.chance(0.3) else (self.tau_scale * self.dec(-3, -0.5),
                                                                  self.tau_scale * self.dec(-3, -0.5))
            rows.append(f"[{_fmt(w)}, {_fmt(e1)}, {_fmt(e2)}, {_fmt(b1)}, {_fmt(b2)}]")
        return "[" + ", ".join(rows) + "]"

    def friction(self, family, thermal=None):
        """A friction element of ``family``; ``thermal``: the source of a ``ThermalMass`` for a clutch or brake."""
        if family == "friction_contact":
            a = self.anchor("translational")
            fn = self.signal(0.0, 1.0 * self.f_scale)
            var = self.add("contact", "FrictionContact", fn=fn, peak=_fmt(self.u(1.0, 1.6)), **self.mu_kwargs())
            other = self.new_mass("translational") if self.chance(0.5) else None
            ends = [self.flange(a), self.ground("translational") if other is None else self.flange(other)]
            if self.chance(0.5):
                ends.reverse()
            self.connect(f"{var}.flange_a", ends[0])
            self.connect(f"{var}.flange_b", ends[1])
            return
        a = self.anchor("rotational")
        if family == "bearing_friction":
            n = self.rng.randint(1, 3)
            ws = sorted({0.0} | {round(self.dec(-1, 2), 4) for _ in range(n - 1)})
            tab = "[" + ", ".join(f"({_fmt(w)}, {_fmt(self.tau_scale * self.dec(-2, 0))})" for w in ws) + "]"
            var = self.add("bearing", "BearingFriction", tau_table=tab, peak=_fmt(self.u(1.0, 1.5)))
            self.connect(f"{var}.flange", self.flange(a))
            return
        # capacity mu * cgeo * fn_max near the torque scale
        mu = self.mu_kwargs()
        cgeo = self.dec(-1.5, 0)
        fn_max = self.tau_scale * self.dec(-1, 0.7) / (0.5 * cgeo)
        kw = dict(mu, peak=_fmt(self.u(1.0, 1.6)), cgeo=_fmt(cgeo), fn_max=_fmt(fn_max),
                  f_normalized=self.normalized())
        if thermal is not None:
            kw["thermal"] = thermal
        if family == "brake":
            var = self.add("brake", "Brake", **kw)
            self.connect(f"{var}.flange", self.flange(a))
            return
        cls, prefix = ("Clutch", "clutch") if family == "clutch" else ("OneWayClutch", "owc")
        var = self.add(prefix, cls, **kw)
        others = [b for b in self.bodies if b.domain == "rotational" and self.find(b.group) != self.find(a.group)]
        b = self.pick(others) if others and family == "clutch" and self.chance(0.3) else self.new_mass("rotational")
        if family == "one_way_clutch":
            # a freewheel must start with w_rel = w_b - w_a >= 0: the new side b starts fast
            self.connect(f"{var}.flange_a", self.flange(a))
            self.connect(f"{var}.flange_b", self.flange(b))
            self.high_start[self.find(b.group)] = b
            return
        ends = [self.flange(a), self.flange(b)]
        if self.chance(0.5):
            ends.reverse()
        self.connect(f"{var}.flange_a", ends[0])
        self.connect(f"{var}.flange_b", ends[1])

    def vehicle_body(self):
        """A translational mass for wheels to carry (an existing one or a new vehicle)."""
        cands = [b for b in self.bodies if b.domain == "translational" and b.start == "mass"]
        if cands and self.chance(0.6):
            return self.pick(cands)
        return self.new_mass("translational", mass=self.dec(1.5, 3.3))

    def wheel(self, family):
        a = self.anchor("rotational")
        body = self.vehicle_body()
        radius = self.dec(-1, 0)
        J = self.dec(-1.5, 0.5)
        if family == "wheel":
            fn = self.signal(0.3 * body.mass * 9.81, 1.0 * body.mass * 9.81,
                             kinds=("Constant", "Sine", "Table", "callable", "Step"))
            var = self.add("wheel", "Wheel", radius=_fmt(radius), J=_fmt(J), m_axle=_fmt(self.dec(0, 1.7)),
                           c_tyre=_fmt(self.dec(4, 5.5)), d_tyre=_fmt(self.dec(1.5, 3)), mu=_fmt(self.u(0.3, 1.1)),
                           peak=_fmt(self.u(1.0, 1.3)), fn=fn)
            kw = self.comps[var]["kw"]
            m_axle = float(kw["m_axle"])
            self.omega_max = max(self.omega_max, math.sqrt(float(kw["c_tyre"]) / 0.5))
            hub = self._body(var, f"{var}.hub", "rotational", J, "wheel")
            axle = self._body(var, f"{var}.axle", "translational", m_axle, "wheel")
            self.union(hub, axle)
            # the axle carries the vehicle: joined directly (one node) or through a suspension link
            if self.chance(0.6):
                self.connect(f"{var}.axle", self.flange(body))
                self.union(axle, body)
            else:
                c, omega, red = self.stiffness(m_axle, body.mass)
                sd = self.add("susp", "SpringDamper", c=_fmt(c), d=_fmt(self.damping(omega, red)),
                              domain="'translational'")
                self.connect(f"{sd}.flange_a", f"{var}.axle")
                self.connect(f"{sd}.flange_b", self.flange(body))
        else:
            fn = body.mass * 9.81 * self.u(0.3, 1.0)
            var = self.add("mfw", "MagicFormulaWheel", radius=_fmt(radius), J=_fmt(J), fn=_fmt(fn),
                           D=_fmt(self.u(0.3, 1.1)))
            hub = self._body(var, f"{var}.hub", "rotational", J, "mf_wheel")
            # the slip law is stiff near standstill: dF/dv = fn D C B / v_eps (defaults C 1.9, B 10,
            # v_eps 0.5 m/s) acting on the wheel inertia seen at the tread, J / r^2: a rate [1/s]
            self.omega_max = max(self.omega_max, radius ** 2 * fn * float(_fmt(self.comps[var]["kw"]["D"])) * 38.0 / J)
            self.connect(f"{var}.axle", self.flange(body))
        # the drive: a shaft from an existing rotational mass to the hub
        if self.chance(0.5):
            self.union(a, hub)
            sh = self.add("shaft", "Shaft", stiffness="None")
        else:
            c, omega, red = self.stiffness(a.mass, J)
            sh = self.add("shaft", "Shaft", stiffness=_fmt(c), damping=_fmt(self.damping(omega, red)))
        self.connect(f"{sh}.flange_a", self.flange(a))
        self.connect(f"{sh}.flange_b", hub.flange)

    def stop_or_gap(self, family):
        """An end stop of a mass against the ground or another mass, or an elastic gap between two."""
        domain = "translational" if family == "elasto_gap" or self.chance(0.5) else "rotational"
        a = self.anchor(domain)
        others = [b for b in self.bodies if b.domain == domain and self.find(b.group) != self.find(a.group)]
        b = self.pick(others) if others and self.chance(0.4) else None
        c, omega, red = self.stiffness(a.mass, *(() if b is None else (b.mass,)))
        c, omega = c * 100.0, omega * 10.0          # contacts are stiffer than the links
        self.omega_max = max(self.omega_max, omega)
        d = _fmt(self.damping(omega, red))
        dom = {"domain": f"'{domain}'"}
        if family == "end_stop":
            lo = -self.dec(-3, 0)
            var = self.add("stop", "EndStop", lower=_fmt(lo), upper=_fmt(lo + self.dec(-3, 0.3)), c=_fmt(c), d=d, **dom)
            self.connect(f"{var}.flange", self.flange(a))
            if b is not None:
                self.connect(f"{var}.support", self.flange(b))
            return
        var = self.add("gap", "ElastoGap", c=_fmt(c), d=d, phi_rel0=_fmt(self.u(-1.0, 1.0) * self.dec(-3, 0)), **dom)
        ends = [self.flange(a), self.ground(domain) if b is None else self.flange(b)]
        if self.chance(0.5):
            ends.reverse()
        self.connect(f"{var}.flange_a", ends[0])
        self.connect(f"{var}.flange_b", ends[1])

    def hard_stop(self):
        """A rigid stop (impacts with restitution ``e``) of a mass against the ground or another mass; the limits
        hold 0, and the groups of both sides start at position 0 (a start outside the limits is refused)."""
        domain = "translational" if self.chance(0.5) else "rotational"
        a = self.anchor(domain)
        others = [b for b in self.bodies if b.domain == domain and self.find(b.group) != self.find(a.group)]
        b = self.pick(others) if others and self.chance(0.4) else None
        lo = -self.dec(-3, 0)
        e = 0.0 if self.chance(0.25) else self.u(0.2, 0.95)
        cls = "LinearHardStop" if domain == "translational" else "HardStop"
        var = self.add("hstop", cls, lower=_fmt(lo), upper=_fmt(self.dec(-3, 0.3)), e=_fmt(e))
        self.connect(f"{var}.flange", self.flange(a))
        self.at_zero.append(a)
        if b is not None:
            self.connect(f"{var}.support", self.flange(b))
            self.at_zero.append(b)

    def thermal_friction(self):
        """A clutch or brake with a thermal mass inside the DAE and fade: its capacity falls as it heats. The
        heat capacity is drawn so that the run's slip heat raises the temperature by ~0.1-300 K, and the fade
        acts over 1-30 K above the start."""
        energy = self.tau_scale * self.dec(0, 1.5) * self.t_end          # a slip heat scale [J]
        C = energy / self.dec(2, 4.5)
        G = 0.0 if self.chance(0.3) else C * self.dec(-2, 0)
        fade = f"[(293.15, 1.0), ({_fmt(293.15 + self.dec(0, 1.5))}, {_fmt(self.u(0.4, 0.95))})]"
        self.friction(self.pick(("brake", "clutch")), thermal=f"ThermalMass(C={_fmt(C)}, G={_fmt(G)}, fade={fade})")

    def speed_load(self):
        """One of the speed-dependent loads (linear, quadratic, sign, inverse) on a mass, opposing motion."""
        kind = self.pick(("Linear", "Quadratic", "Sign", "Inverse"))
        if self.chance(0.6):
            a = self.anchor("rotational")
            cls = "SignTorque" if kind == "Sign" else f"{kind}SpeedDependentTorque"
            kw = dict(tau_nominal=_fmt(self.tau_scale * self.dec(-1.5, 0)), w_nominal=_fmt(self.dec(-0.5, 1.5)))
        else:
            a = self.anchor("translational")
            cls = "SignForce" if kind == "Sign" else f"{kind}SpeedDependentForce"
            kw = dict(f_nominal=_fmt(self.f_scale * self.dec(-1.5, 0)), v_nominal=_fmt(self.dec(-0.5, 1.5)))
        if kind in ("Sign", "Inverse"):
            kw["w_eps"] = _fmt(self.dec(-2, -0.5))
        var = self.add("load", cls, **kw)
        self.connect(f"{var}.flange", self.flange(a))

    def stribeck_friction(self, family):
        """A clutch or brake with a Stribeck law, or a translational brake (``LinearBrake``)."""
        mu_k = self.u(0.05, 0.6)
        law = (f"Stribeck(mu_s={_fmt(mu_k * self.u(1.0, 1.8))}, mu_k={_fmt(mu_k)}, w_s={_fmt(self.dec(-1.5, 0.5))}, "
               f"mu_v={_fmt(self.pick((0.0, self.dec(-4, -2))))}, delta={_fmt(self.pick((1.0, 2.0)))})")
        if family == "linear_brake":
            a = self.anchor("translational")
            var = self.add("lbrake", "LinearBrake", mu_law=law, fn_max=_fmt(self.f_scale * self.dec(-1, 0.5) / mu_k),
                           f_normalized=self.normalized())
            self.connect(f"{var}.flange", self.flange(a))
            return
        a = self.anchor("rotational")
        cgeo = self.dec(-1.5, 0)
        kw = dict(mu_law=law, cgeo=_fmt(cgeo), fn_max=_fmt(self.tau_scale * self.dec(-1, 0.7) / (mu_k * cgeo)),
                  f_normalized=self.normalized())
        if self.chance(0.4):
            var = self.add("sbrake", "Brake", **kw)
            self.connect(f"{var}.flange", self.flange(a))
            return
        var = self.add("sclutch", "Clutch", **kw)
        b = self.new_mass("rotational")
        self.connect(f"{var}.flange_a", self.flange(a))
        self.connect(f"{var}.flange_b", self.flange(b))

    def vehicle_load(self):
        body = self.anchor("translational")
        grade = self.pick(("0.0", self.signal(-0.15, 0.15, kinds=("Constant", "Ramp", "Table", "Sine"))))
        wind = self.pick(("0.0", self.signal(-5.0, 5.0, kinds=("Constant", "Step", "Sine", "callable"))))
        var = self.add("vload", "VehicleLoad", m=_fmt(body.mass), c_r=_fmt(self.u(0.005, 0.03)),
                       c_drag=_fmt(self.dec(-1.5, 0.3)), grade=grade, wind=wind, v_eps=_fmt(self.dec(-2, -0.5)))
        self.connect(f"{var}.flange", self.flange(body))

    def transmission(self, family):
        """A Gearbox (2 to 4 gears, one shift inside the run) or a TorqueConverter between a mass and a new
        one: both are subsystems whose inner masses the energy checks see."""
        a = self.anchor("rotational")
        if family == "gearbox":
            n = self.rng.randint(2, 4)
            ratios = [_fmt(self.pick((1, 1, 1, -1)) * self.dec(-0.3, 0.7)) for _ in range(n)]
            g0, g1 = self.rng.randint(0, n), self.rng.randint(1, n)
            T = self.t_end
            ts = self.u(0.1, 0.4) * T
            rel, eng = self.u(0.02, 0.15) * T, self.u(0.05, 0.3) * T
            eff = self.pick(("None", "None", "[" + ", ".join(_fmt(self.u(0.9, 1.0)) for _ in range(n)) + "]"))
            J_out = self.dec(-2.0, 0.0)
            var = self.add("gbox", "Gearbox", ratios="[" + ", ".join(ratios) + "]",
                           gear=f"[(0.0, {g0}), ({_fmt(ts)}, {g1 if g1 != g0 else (g0 % n) + 1})]",
                           capacity=_fmt(self.tau_scale * self.dec(-0.3, 0.7)), efficiency=eff,
                           J_in=_fmt(a.mass * self.dec(-1, 0)), J_out=_fmt(J_out), J_gear=_fmt(a.mass * self.dec(-2, -1)),
                           release_time=_fmt(rel), engage_time=_fmt(eng), shift_delay=_fmt(rel * self.u(0.5, 1.5)))
            out = self._body(None, f"{var}.flange_b", "rotational", float(_fmt(J_out)), None)
        else:
            k0 = self.dec(0.5, 1.5)
            var = self.add("conv", "TorqueConverter",
                           K_table=f"[(0.0, {_fmt(k0)}), (0.5, {_fmt(k0 * 1.1)}), (0.9, {_fmt(k0 * 1.6)})]",
                           TR_table=f"[(0.0, {_fmt(self.u(1.5, 2.4))}), (0.85, 1.0), (1.0, 1.0)]",
                           J_pump=_fmt(a.mass * self.dec(-1, 0)), J_turbine=_fmt(self.dec(-2, 0)),
                           lockup=self.pick(("0.0", self.signal(0.0, 1.0, kinds=("Ramp", "Step", "Constant")))),
                           lockup_capacity=_fmt(self.tau_scale * self.dec(-0.3, 0.7)))
            out = self._body(None, f"{var}.turbine", "rotational", float(self.comps[var]["kw"]["J_turbine"]), None)
        ends = ("flange_a", "flange_b") if family == "gearbox" else ("pump", "turbine")
        self.connect(f"{var}.{ends[0]}", self.flange(a))
        # the far side: a new mass joined to the box's output inertia (one rigid group)
        b = self.new_mass("rotational")
        self.connect(f"{var}.{ends[1]}", self.flange(b))
        self.union(out, b)

    def road_load(self):
        body = self.anchor("translational")
        var = self.add("road", "RoadLoad", f_roll=_fmt(self.f_scale * self.dec(-2, -0.5)),
                       c_drag=_fmt(self.dec(-1.5, 0.3)), grade=_fmt(self.pick((0.0, self.u(-0.15, 0.15)))),
                       m=_fmt(body.mass), v_eps=_fmt(self.dec(-2, -0.5)))
        self.connect(f"{var}.flange", self.flange(body))

    def source(self, family):
        if family == "torque":
            a = self.anchor("rotational")
            amp = self.tau_scale * self.dec(-0.5, 0.5)
            var = self.add("drive", "Torque", tau=self.signal(-amp, amp))
            self.connect(f"{var}.flange", self.flange(a))
            if self.chance(0.15):
                others = [b for b in self.bodies if b.domain == "rotational" and b is not a]
                if others:
                    self.connect(f"{var}.support", self.flange(self.pick(others)))     # reaction on a mass
            return
        if family == "force":
            a = self.anchor("translational")
            amp = self.f_scale * self.dec(-0.5, 0.5)
            var = self.add("push", "Force", f=self.signal(-amp, amp))
            self.connect(f"{var}.flange", self.flange(a))
            return
        if family == "engine":
            a = self.anchor("rotational")
            n = self.rng.randint(2, 4)
            ws = sorted({round(self.dec(0, 2.5), 3) for _ in range(n)} | {0.0})
            tab = "[" + ", ".join(f"({_fmt(w)}, {_fmt(self.tau_scale * self.u(0.2, 1.0))})" for w in ws) + "]"
            var = self.add("engine", "Engine", torque_map=tab, throttle=self.signal(0.0, 1.0))
            self.connect(f"{var}.flange", self.flange(a))
            return
        if family == "dc_motor":
            # stall torque k u / R of the order of the model's torques, electrical time constant 1..100 ms
            a = self.anchor("rotational")
            r, k = self.dec(-1.5, 0.5), self.dec(-1.0, 0.5)
            amp = self.tau_scale * r / k * self.dec(-0.5, 0.5)
            var = self.add("dcm", "DCMotor", u=self.signal(-amp, amp), R=_fmt(r), L=_fmt(r * self.dec(-3, -1)),
                           k=_fmt(k))
            self.connect(f"{var}.flange", self.flange(a))
            return
        if family == "electric_motor":
            a = self.anchor("rotational")
            tau_max = self.tau_scale * self.dec(-0.5, 0.5)
            var = self.add("emot", "ElectricMotor", command=self.signal(-1.0, 1.0), tau_max=_fmt(tau_max),
                           p_max=_fmt(tau_max * self.dec(0.0, 2.0)))       # base speed 1..100 rad/s
            self.connect(f"{var}.flange", self.flange(a))
            return
        if family == "pi_control":
            # senses one inertia, drives it (or, sometimes, another one); closed-loop bandwidth ~1..30 rad/s
            a = self.anchor("rotational")
            others = [b for b in self.bodies if b.domain == "rotational" and b is not a]
            b = self.pick(others) if others and self.chance(0.2) else a
            u_max = self.tau_scale * self.dec(-0.3, 0.3)
            amp = self.dec(-1, 1.3)
            var = self.add("pi", "PI", w_ref=self.signal(-amp, amp), k=_fmt(a.mass * self.dec(0.0, 1.5)),
                           T_i=_fmt(self.dec(-1.0, 0.5)), u_max=_fmt(u_max), u_min=_fmt(-u_max))
            self.connect(f"{var}.sensor", self.flange(a))
            self.connect(f"{var}.flange", self.flange(b))
            return
        # prescribed motion: one per rigid group, on a group without start values (assigned later)
        domain = "rotational" if self.chance(0.7) else "translational"
        cands = [b for b in self.bodies if b.domain == domain and self.find(b.group) not in self.driven
                 and self.find(b.group) not in self.high_start]
        a = self.pick(cands) if cands else self.new_mass(domain)
        amp = self.dec(-1, 1.3)
        # a reference is smooth when the motion it prescribes has no jump in speed: a speed reference
        # without jumps, a position reference without jumps or corners (a Sine that starts later than
        # t = 0 jumps, or has a corner, where it starts)
        if family == "speed":
            rough = not self.chance(0.9)
            smooth_kinds, rough_kinds = ("Constant", "Sine", "callable", "Ramp", "Table"), ("Step", "Pulse")
            cls, param = ("Speed", "w_ref") if domain == "rotational" else ("LinearSpeed", "v_ref")
        else:
            rough = not self.chance(0.85)
            smooth_kinds, rough_kinds = ("Constant", "Sine", "callable"), ("Ramp", "Table", "Step", "Pulse")
            cls, param = ("Position", "phi_ref") if domain == "rotational" else ("LinearPosition", "s_ref")
        if self.references != "any":
            rough = self.references == "rough"
        if rough:
            ref = self.signal(-amp, amp, kinds=rough_kinds)
        else:
            ref = self.signal(-amp, amp, kinds=smooth_kinds, start_at_zero=self.references == "smooth")
        var = self.add("motor" if family == "speed" else "servo", cls, **{param: ref},
                       **({} if domain == "rotational" else {"domain": "'translational'"}))
        self.connect(f"{var}.flange", self.flange(a))
        self.driven.add(self.find(a.group))

    def apply(self, family):
        self.used.append(family)
        if family in ("spring", "damper", "spring_damper", "shaft_rigid", "shaft_elastic", "backlash",
                      "elasto_backlash"):
            self.link(family)
        elif family in ("ideal_gear", "lossy_gear", "planetary", "lossy_planetary", "differential",
                        "limited_slip_differential"):
            self.gear(family)
        elif family in ("clutch", "brake", "one_way_clutch", "bearing_friction", "friction_contact"):
            self.friction(family)
        elif family in ("wheel", "magic_formula_wheel"):
            self.wheel(family)
        elif family == "road_load":
            self.road_load()
        elif family in ("end_stop", "elasto_gap"):
            self.stop_or_gap(family)
        elif family == "speed_load":
            self.speed_load()
        elif family in ("stribeck_clutch", "linear_brake"):
            self.stribeck_friction(family)
        elif family == "vehicle_load":
            self.vehicle_load()
        elif family in ("gearbox", "torque_converter"):
            self.transmission(family)
        elif family == "hard_stop":
            self.hard_stop()
        elif family == "thermal_friction":
            self.thermal_friction()
        else:
            self.source(family)

    # -- start values and output ----------------------------------------------
    def starts(self):
        groups: dict[int, list[_Body]] = {}
        for b in self.bodies:
            groups.setdefault(self.find(b.group), []).append(b)
        inside_stops = {self.find(b.group) for b in self.at_zero}
        for g, members in groups.items():
            if g in self.driven:
                continue
            startable = [b for b in members if b.start is not None]
            if not startable:
                continue
            fast = self.high_start.get(g)
            if fast is not None and fast.start is not None:
                b, w0 = fast, self.dec(1.5, 2.3)
            elif self.chance(0.6):
                b, w0 = self.pick(startable), self.pick((0.0, 1.0, -1.0)) * self.dec(-1, 1.3)
            else:
                continue
            phi0 = self.pick((None, self.pick((1, -1)) * self.dec(-3, 0)))
            if g in inside_stops:
                phi0 = None
            kw = self.comps[b.var]["kw"]
            if b.start == "inertia":
                kw["w0"] = _fmt(w0)
                if phi0 is not None:
                    kw["phi0"] = _fmt(phi0)
            elif b.start == "mass":
                kw["v0"] = _fmt(w0)
                if phi0 is not None:
                    kw["s0"] = _fmt(phi0)
            elif b.start == "wheel":
                r = float(kw["radius"])
                kw["w0"] = _fmt(w0)
                kw["v0"] = _fmt(w0 * r)      # rolling without slip at the start
            elif b.start == "mf_wheel":
                kw["w0"] = _fmt(w0)

    def lines(self):
        out = []
        for var in self.order:
            c = self.comps[var]
            args = "".join(f", {k}={v}" for k, v in c["kw"].items())
            out.append(f"{var} = m.add({c['cls']}({var!r}{args}))")
        for a, b in self.conns:
            out.append(f"m.connect({a}, {b})")
        return out


def generate(rng, families=None, n_steps=None, require=(), name="fuzz", references="any") -> ModelSpec:
    """A random regular drivetrain drawn with ``rng`` (a ``random.Random`` or hypothesis' ``st.randoms()``).

    ``families``: draw only from these (keys of ``FAMILIES``; default all); ``require``: families that
    appear at least once; ``n_steps``: number of components attached (default 2..7, at least
    ``len(require)``). A source is added when the plan has none. ``references`` of the prescribed-motion
    sources: ``"any"`` (mostly smooth; a jump of speed in 10 to 15 %), ``"smooth"`` (no jump of speed),
    ``"rough"`` (steps and pulses of speed, corners and jumps of position).
    """
    if references not in ("any", "smooth", "rough"):
        raise ValueError(f"references must be 'any', 'smooth' or 'rough', got {references!r}")
    pool = dict(FAMILIES) if families is None else {f: FAMILIES[f] for f in families if f in FAMILIES}
    unknown = (set(families or ()) | set(require)) - set(FAMILIES)
    if unknown:
        raise ValueError(f"unknown families {sorted(unknown)}; choose from {sorted(FAMILIES)}")
    g = _Gen(rng, name, references)
    n = max(n_steps if n_steps is not None else rng.randint(2, 7), len(require))
    names, weights = list(pool), [pool[f] for f in pool]
    plan = list(require)
    while len(plan) < n:
        plan.append(rng.choices(names, weights)[0])
    if require:
        rng.shuffle(plan)
    first = "translational" if (plan[0] in TRANSLATIONAL_FAMILIES or plan[0] in ("force",)) else "rotational"
    g.new_mass(first)
    for fam in plan:
        g.apply(fam)
    if not any(f in SOURCE_FAMILIES for f in plan):
        # something must drive the model (a start speed alone is often all at rest)
        g.apply("torque" if any(b.domain == "rotational" for b in g.bodies) else "force")
    g.starts()
    t_end = float(_fmt(g.t_end))
    # output grid fine enough for the energy books on the fastest designed mode (omega dt <= 0.1)
    dt = min(t_end / 400.0, 0.1 / g.omega_max)
    n_out = max(400, min(20000, int(math.ceil(t_end / dt))))
    return ModelSpec(name=name, lines=g.lines(), t_end=t_end, dt_out=t_end / n_out, families=sorted(set(g.used)))


def generate_seed(seed: int, families=None, n_steps=None, require=()) -> ModelSpec:
    """The model of fuzz seed ``seed`` (``random.Random(seed)``)."""
    spec = generate(random.Random(seed), families=families, n_steps=n_steps, require=require, name=f"fuzz_{seed}")
    spec.seed = seed
    return spec


# ============================================================================ checks

#: claimed global error of an adaptive run at ``rtol``, relative to the range of each kind of signal,
#: as a multiple of rtol (the hard-case answer tolerance: 1e-4 at rtol 1e-8), until runs carry their
#: own estimate (the accuracy contract); plus an absolute part of ``ABS_CLAIM`` times the run's atol
CLAIM_PER_RTOL = 1e4
ABS_CLAIM = 100.0
#: the energy checks of a run hold to its claimed relative error (``claimed_error``) times these factors
#: of the power scale (pointwise balance, loss signs) and of the energy scale (books; plus ``QUAD_SAFETY``
#: times the quadrature's own error estimate, trapezoid on the output grid against every other point).
#: The pointwise balance gets 100: IDA's outputs are its interpolating polynomial and its derivative
#: between steps, whose residual is not the converged one (measured up to 7e4 x rtol of the power scale at
#: rtol 1e-10; the ODE-form solvers, whose accelerations come from the equations, balance to round-off)
POWER_FACTOR = 100.0
LOSS_FACTOR = 1.0
ENERGY_FACTOR = 1.0
QUAD_SAFETY = 4.0

#: a disagreement beyond this many times the claims is a wrong answer, not an accuracy shortfall
GROSS = 100.0
#: the runs of one solver at two tolerances (loose label -> tight label, rtol 100 times smaller): a pair's
#: difference beyond the claims that shrinks with the tolerance is told from a path difference by them
COMPANIONS = {"ida": "ida_ref", "dop853": "dop853_ref"}
#: the pair at the other tolerance level must be at least this many times closer (of the 100 a
#: tolerance-proportional error would give; IDA's global error went as rtol^0.8 on seed 86)
CONVERGENCE = 10.0

#: (label, solver, options); ``tight`` runs are the references
RUNS = (
    ("ida", "ida", {"rtol": 1e-8}),           # as a user writes it: compiled callbacks where the model allows
    ("dop853", "scipy:DOP853", {"rtol": 1e-8}),
    ("ida_ref", "ida", {"rtol": 1e-10, "native": False}),     # the Python callbacks: a reference of its own path
    ("dop853_ref", "scipy:DOP853", {"rtol": 1e-10, "max_steps": 400_000}),
    ("expm", "expm", {"tol": 1e-4}),          # only for models linear between friction events
    ("default", "auto", {}),                  # the default call m.simulate(t_end, dt_out): ``default_accuracy``
)
#: runs judged by the accuracy contract against a reference (``default_accuracy``), not by ``agreement``
CONTRACT_RUNS = ("default",)
#: references of ``default_accuracy``, in order of preference
REFERENCE_RUNS = ("dop853_ref", "ida_ref")
#: work budget of one run: evaluations of the model equations (residual / right-hand side)
DEFAULT_MAX_CALLS = 600_000

LOSS_CLASSES = ("Clutch", "Brake", "OneWayClutch", "BearingFriction", "FrictionContact", "LossyGear",
                "LossyPlanetary", "Damper", "RoadLoad", "MagicFormulaTyre", "ConverterFluid", "_SpeedLoad")
LOSSLESS_CLASSES = ("Spring", "IdealGear", "Planetary", "Differential", "Rolling", "Backlash")


@dataclass
class Finding:
    kind: str
    detail: str
    run: str = ""
    where: str = ""        # component (class 'name') most involved, for grouping


@dataclass
class RunOutcome:
    label: str
    solver: str
    options: dict
    status: str                    # ok | refused | crash | budget | skipped
    error: str = ""                # class name of the error
    message: str = ""
    wall_s: float = 0.0
    claim_rel: float = math.nan
    claim_abs: float = 0.0
    metrics: dict = field(default_factory=dict)   # the energy checks' measured values (energy_checks)


@dataclass
class Verdict:
    name: str
    seed: int | None
    status: str                    # pass | refused | finding
    families: list
    runs: list = field(default_factory=list)
    findings: list = field(default_factory=list)
    refusals: list = field(default_factory=list)      # (run label, error class, message)
    wall_s: float = 0.0
    n_components: int = 0
    pairs: dict = field(default_factory=dict)         # run pair -> (difference / allowance on both scales)

    def to_dict(self):
        return asdict(self)


def _first_line(exc, limit=400):
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def claimed_error(label, solver, options, res) -> tuple[float, float]:
    """``(relative, absolute)`` bound a run claims on its global error of positions and speeds.

    Relative to the range of the signals of one kind (as ``regmech.solvers.richardson`` measures).
    Fixed-step runs with an estimate claim ``max(tol, estimate)``; adaptive runs ``CLAIM_PER_RTOL * rtol``
    and ``ABS_CLAIM * atol`` (atol defaults to rtol/100). This is the one place to switch to the
    accuracy contract's ``res.stats.error_estimate`` once every solver reports one.
    """
    est = getattr(res.stats, "error_estimate", None)
    # a claim on the range of a kind (the accuracy contract, a fixed-step estimate) is measured with
    # ``richardson.kind_scales``, whose scale is never below ABSOLUTE_FLOOR: that is its absolute part. Without
    # it a model at rest had no absolute tolerance at all, and its round-off (powers of 3e-52 W, fuzz seed 289)
    # was judged relative to a power scale made of that round-off
    from ..solvers.richardson import ABSOLUTE_FLOOR
    if label in CONTRACT_RUNS:
        from ..solvers.accuracy import DEFAULT_ACCURACY
        acc = float(options.get("accuracy", DEFAULT_ACCURACY))
        return acc, acc * ABSOLUTE_FLOOR
    if "tol" in options and est is not None:
        claim = max(float(options["tol"]), float(est))
        return claim, claim * ABSOLUTE_FLOOR
    rtol = float(options.get("rtol", 1e-6))
    atol = float(options.get("atol", rtol * 1e-2))
    return CLAIM_PER_RTOL * rtol, ABS_CLAIM * atol


def _bodies(model):
    """(name, mass, position name, speed name, acceleration name) of every mass in the model."""
    out = []
    for name, comp in model.components.items():
        if getattr(comp, "role", "") == "body":
            p, w, a, _ = comp.var_names()
            out.append((name, float(comp.mass), f"{name}.{p}", f"{name}.{w}", f"{name}.{a}"))
    return out


def _devices(model):
    return [(name, comp) for name, comp in model.components.items() if getattr(comp, "role", "") == "device"]


def _segments(t):
    """Index ranges of the smooth pieces of an output grid (an event instant appears twice)."""
    cuts = np.flatnonzero(np.diff(t) <= 0) + 1
    bounds = [0, *cuts.tolist(), len(t)]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b - a >= 1]


def integrate(t, y):
    """Cumulative trapezoid integral of ``y(t)`` on an output grid and the quadrature's own error estimate.

    Returns ``(I, err)``: ``I`` at every row, and ``err`` an estimate of ``max_t |I(t) - exact|`` by
    Richardson: on each smooth piece (an event instant appears twice in the grid) the cumulative rule
    at h is compared with the rule on every other point at the shared instants, ``|C_h - C_2h| / 3``,
    its largest value per piece summed over the pieces (the error at an instant inside a run can
    exceed the error of the whole, where oscillating errors cancel).

    A piece of one interval (two rows between events) gets ``h |y_b - y_a| / 2``, the bound for an integrand
    monotone on it.

    Richardson assumes an integrand smooth on the grid's scale. A kink between two rows (the power of a
    backlash at each contact, which no event marks) breaks that: the rule's error there is up to
    ``h^2 |jump of y'| / 8`` whatever the step, the same for the rule at 2h, and their difference says
    little. On fuzz seed 228 (a 0.2 kg mass rattling in an undamped backlash, power up to 1.3e5 W) the
    estimate was 3.9 J for an error of 42.7 J, and the books were open by it. So each row where the slope of
    ``y`` changes by more than twice its change at both neighbours (smooth curvature varies slowly between
    rows) counts as a kink and adds that bound (``_kink_bound``): 146 J there; nothing on a smooth integrand."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    inc = np.concatenate([[0.0], np.diff(t) * (y[1:] + y[:-1]) / 2])
    cum = np.cumsum(inc)
    err = 0.0
    for a, b in _segments(t):
        if b - a == 2:
            # one interval between events: no second grid to compare with. The rule's error is at most half the
            # difference of the rectangle rules, h |y_b - y_a| / 2, for an integrand monotone on the interval
            # (fuzz seed 60173: a Stribeck clutch stopping an inertia within the first output interval, 1 ms;
            # the trapezoid missed 7.6e-3 J of 0.15 J dissipated, and the books were open by it with an
            # estimate of 0)
            err += float(abs(t[a + 1] - t[a]) * abs(y[a + 1] - y[a])) / 2.0
            continue
        if b - a < 3:
            continue
        ts, ys = t[a:b], y[a:b]
        fine = cum[a:b:2] - cum[a]
        t2, y2 = ts[::2], ys[::2]
        coarse = np.concatenate([[0.0], np.cumsum(np.diff(t2) * (y2[1:] + y2[:-1]) / 2)])
        err += float(np.max(np.abs(fine - coarse))) / 3.0 + _kink_bound(ts, ys)
    return cum, err


def _kink_bound(t, y):
    """Bound of the trapezoid rule's error at the kinks of ``y`` on one smooth piece of the grid (``integrate``):
    ``sum h^2 |slope change| / 8`` over the rows whose slope change exceeds twice that of both neighbours."""
    h = np.diff(t)
    if len(h) < 2:
        return 0.0
    slope = np.diff(y) / np.where(h > 0, h, 1.0)
    jump = np.abs(np.diff(slope))                     # at rows 1 .. n-2
    pad = np.concatenate([[0.0], jump, [0.0]])
    kink = (jump > 2.0 * pad[:-2]) & (jump > 2.0 * pad[2:])
    step = np.maximum(h[:-1], h[1:])
    return float(np.sum(jump[kink] * step[kink] ** 2)) / 8.0


def energy_checks(res, model, run="", rel=1e-4, abs_speed=0.0, metrics=None) -> list[Finding]:
    """The power balance, the energy books and the sign of every loss, from the result's own signals.

    ``rel`` is the run's claimed relative error and ``abs_speed`` its absolute part (``claimed_error``);
    every power tolerance below also admits ``abs_speed`` times the largest device force of the run (a
    speed error at that level times the force: what a device held at rest shows as power when the whole
    model barely moves). ``metrics`` (a dict) receives the measured values relative to their scales.

    * Pointwise: ``sum_b m_b v_b a_b + sum_d P_d = 0`` within ``POWER_FACTOR * rel`` of the power scale
      (``P_d`` = ``<device>.power``, the power the device absorbs; a source absorbs minus its input; the
      power scale is the largest ``sum |terms|`` over the output instants).
    * Books: ``K(t) - K(0) + V(t) - V(0) + D(t) = W(t)`` with K the kinetic energy (``.kinetic``), V the
      stored energy (``.potential`` of the devices that have one), W the work of the sources
      ``-int P_src`` (with their work at impacts, ``Result.impulse_work``) and D the dissipation
      ``int P_other - (V(t) - V(0))``; within ``ENERGY_FACTOR * rel`` of the energy scale (the largest of ``int sum |P|``, K and |V|) plus ``QUAD_SAFETY`` times the
      quadrature error estimate (``integrate``).
    * Loss signs: every friction or loss element absorbs ``P_d >= -LOSS_FACTOR * rel * power scale`` at
      every output instant; an element with storage and loss has a non-decreasing D_d and an ideal
      element D_d = 0, both within the books' tolerance (with the element's own quadrature estimate).
    """
    metrics = {} if metrics is None else metrics
    t = res.t
    findings = []
    if len(t) < 3:
        return findings
    bodies = _bodies(model)
    kin = np.zeros_like(t)
    rate = np.zeros_like(t)
    rate_abs = np.zeros_like(t)
    for name, mass, _, w, a in bodies:
        if f"{name}.kinetic" not in res:
            continue
        kin = kin + res[f"{name}.kinetic"]
        term = mass * res[w] * res[a]
        rate = rate + term
        rate_abs = rate_abs + np.abs(term)
    powers = {}
    for name, dev in _devices(model):
        if f"{name}.power" in res:
            powers[name] = (dev, res[f"{name}.power"])
    total = rate + sum((p for _, p in powers.values()), np.zeros_like(t))
    p_abs = rate_abs + sum((np.abs(p) for _, p in powers.values()), np.zeros_like(t))
    # a model with no power anywhere (everything at rest, or only jumps of speed) still has books to close
    p_scale = float(p_abs.max(initial=0.0)) or 1e-300
    # every force or torque a device exerts, at its flanges too: a controller's actuator (``pi.flange.tau``)
    # and a lossy gear have no ``<name>.tau`` (fuzz seed 40201: a PI's 0.05 N m held at rest by stuck lossy
    # gears; the gear's round-off power of 2e-19 W was judged against a power scale of round-off alone)
    f_scale = 0.0
    devices = {name for name, _ in _devices(model)}
    for sig in res.names:
        head, _, last = sig.rpartition(".")
        if last in ("tau", "f") and (head in devices or head.rpartition(".")[0] in devices):
            f_scale = max(f_scale, float(np.abs(res[sig]).max(initial=0.0)))
    p_floor = abs_speed * f_scale
    k = int(np.argmax(np.abs(total)))
    metrics["power"] = abs(float(total[k])) / p_scale
    if abs(total[k]) > POWER_FACTOR * rel * p_scale + p_floor:
        findings.append(Finding("power-balance", f"sum m v a + sum P = {total[k]:.3g} W at t={t[k]:.6g} "
                                f"({metrics['power']:.2g} of the power scale {p_scale:.3g} W; tolerance "
                                f"{POWER_FACTOR * rel:.1g})", run))
    # energy books
    # the trapezoid over the rows with its own Richardson estimate, independent of the product's quadrature
    # (``Result.integral``, which a result's ``heat`` uses): tried, its estimate missed the clip kink
    # of a damped stop's contact (tests/validation/test_stops_and_loads: books 6e-8 J open, estimate 6e-12 J)
    # and its re-integrations of tight references tripled the CI subset's time; the models where the rows do
    # not resolve a stop (seeds 10288, 40477, 50103) stay findings of the checks, not of the product
    src = np.zeros_like(t)
    other = np.zeros_like(t)
    stored = np.zeros_like(t)
    impacts = np.zeros_like(t)
    per_dev = {}
    for name, (dev, p) in powers.items():
        if dev.is_source:
            src = src + p
            continue
        other = other + p
        pot = res[f"{name}.potential"] if f"{name}.potential" in res else None
        if pot is not None:
            stored = stored + pot
        cum, qe = integrate(t, p)
        jumps = res.impact_losses(name) if callable(getattr(res, "impact_losses", None)) else None
        if jumps is not None:
            cum = cum + jumps       # a hard stop's impacts: energy taken at an instant, not by a power
            impacts = impacts + jumps
        per_dev[name] = (dev, cum - (0.0 if pot is None else pot - pot[0]), qe, p)
    work, qe_w = integrate(t, -src)
    for name, (dev, _) in powers.items():
        # a motion source's work at impacts, at an instant (``Result.impulse_work``; fuzz seed 94074)
        jumps = res.impulse_work(name) if dev.is_source and callable(getattr(res, "impulse_work", None)) else None
        if jumps is not None:
            work = work + jumps
    absorbed, qe_o = integrate(t, other)
    absorbed = absorbed + impacts
    dissipated = absorbed - (stored - stored[0])
    books = (kin - kin[0]) + (stored - stored[0]) + dissipated - work
    e_scale = max(float(integrate(t, p_abs)[0][-1]), float(kin.max()), float(np.abs(stored).max(initial=0.0)))
    if e_scale == 0.0:
        return findings
    e_floor = p_floor * float(t[-1] - t[0])
    tol_e = ENERGY_FACTOR * rel * e_scale + QUAD_SAFETY * (qe_w + qe_o) + e_floor
    k = int(np.argmax(np.abs(books)))
    metrics["books"] = abs(float(books[k])) / e_scale
    metrics["quadrature"] = (qe_w + qe_o) / e_scale
    if abs(books[k]) > tol_e:
        findings.append(Finding("energy-books", f"kinetic + stored + dissipated - work in = {books[k]:.3g} J at "
                                f"t={t[k]:.6g} (work in {work[-1]:.4g} J, dissipated {dissipated[-1]:.4g} J; "
                                f"energy scale {e_scale:.3g} J, tolerance {tol_e:.3g} J of which quadrature "
                                f"{QUAD_SAFETY * (qe_w + qe_o):.3g} J)", run))
    worst_loss = 0.0
    for name, (dev, diss, qe, p) in per_dev.items():
        where = f"{type(dev).__name__} '{name}'"
        kind = _loss_kind(dev)
        tol_d = ENERGY_FACTOR * rel * e_scale + QUAD_SAFETY * qe + e_floor
        if kind == "loss":
            j = int(np.argmin(p))
            worst_loss = min(worst_loss, float(p[j]) / p_scale)
            if p[j] < -LOSS_FACTOR * rel * p_scale - p_floor:
                findings.append(Finding("loss-supplies-power", f"{where} absorbs {p[j]:.3g} W at t={t[j]:.6g} (it "
                                        f"can only dissipate; {p[j] / p_scale:.2g} of the power scale "
                                        f"{p_scale:.3g} W)", run, where))
        elif kind == "storing-loss":
            fall = np.maximum.accumulate(diss) - diss
            j = int(np.argmax(fall))
            if fall[j] > tol_d:
                findings.append(Finding("loss-supplies-power", f"{where}: its accumulated dissipation falls by "
                                        f"{fall[j]:.3g} J up to t={t[j]:.6g} (tolerance {tol_d:.3g} J)", run, where))
        elif kind == "lossless":
            j = int(np.argmax(np.abs(diss)))
            if abs(diss[j]) > tol_d:
                findings.append(Finding("lossless-dissipates", f"{where} (ideal) has absorbed {diss[j]:.3g} J net of "
                                        f"its stored energy at t={t[j]:.6g} (tolerance {tol_d:.3g} J)", run, where))
    metrics["loss"] = worst_loss
    return findings


def _loss_kind(dev):
    names = [k.__name__ for k in type(dev).__mro__]
    cls = type(dev).__name__
    if cls == "Shaft":
        if dev.stiffness is None:
            return "lossless"
        return "storing-loss" if dev.damping > 0 else "lossless"
    if cls in ("SpringDamper", "ElastoBacklash", "EndStop", "ElastoGap"):
        return "storing-loss"
    if cls == "RoadLoad":
        return "storing-loss"      # the grade force stores height energy
    if any(n in LOSS_CLASSES for n in names):
        return "loss"
    if any(n in LOSSLESS_CLASSES for n in names):
        return "lossless"
    return "other"


def finite_check(res, run="", integral_tol=None) -> list[Finding]:
    """The first signal of ``res`` with a NaN or inf, as a finding. ``integral_tol``: the relative error at which
    the signals that are time integrals (a device's ``heat``, ``Result.integral``) are computed for the check
    (None: the run's own, as ``res[name]`` reads them; the quadrature then follows the model's laws to the run's
    tolerance, re-integrating most output intervals of a run at rtol 1e-10). A hard stop's heat adds its impacts'
    losses (``Result.impact_losses``), as ``res[name]`` does."""
    rate_of = getattr(getattr(res, "_traj", None), "integral_rate", None)
    rates = {}
    # all integrals in one read: they share the quadrature's midpoint rows, its re-integrations and its work bound
    # (one ``res[name]`` per heat gave each its own: fuzz seed 60374 spent 32 s reading its heats after a 17.8 s
    # run, and the model's 420 s limit killed it as a hang)
    if rate_of is not None and getattr(res, "integrator", None) is not None:
        rates = {name: rate_of(name) for name in res.names}
        rates = {name: r for name, r in rates.items() if r is not None}
    integrals = res.integrals(sorted(set(rates.values())), tol=integral_tol) if rates else {}
    for name in res.names:
        y = res._with_impacts(name, integrals[rates[name]][0]) if name in rates else res[name]
        bad = ~np.isfinite(y)
        if bad.any():
            k = int(np.argmax(bad))
            return [Finding("nonfinite", f"{name} is {y[k]} at t={res.t[k]:.6g} ({int(bad.sum())} rows)", run,
                            name.split(".")[0])]
    return []


def motion_signals(model):
    """Names of the positions and speeds of every mass, by kind (``phi``, ``w``, ``s``, ``v``)."""
    kinds: dict[str, list[str]] = {}
    for _, _, p, w, _ in _bodies(model):
        kinds.setdefault(p.rsplit(".", 1)[1], []).append(p)
        kinds.setdefault(w.rsplit(".", 1)[1], []).append(w)
    return kinds


def range_claim(outcome) -> bool:
    """True when the run's claim is on the range of a kind (``claimed_error``): the accuracy contract's runs
    and fixed-step runs with an error estimate; False for an adaptive run's stand-in claim from its rtol."""
    return outcome.label in CONTRACT_RUNS or "tol" in outcome.options or "accuracy" in outcome.options


def agreement(outcomes, results, model, spec, pairs=None) -> list[Finding]:
    """Every pair of runs that returned must agree within the sum of their claims (``claimed_error``).

    The difference of two runs on the common output grid is measured per kind of signal (angles,
    speeds, positions, linear speeds of the masses) against two scales taken from the tightest run:

    * ``disagreement``: beyond ``(claim_i + claim_j) * max(range, largest |value|) + abs_i + abs_j``,
      what tolerance-proportional step control can promise at all; ``wrong-answer`` when beyond
      ``GROSS`` times that (one of the answers is plainly wrong, not merely less accurate than claimed);
    * ``range-accuracy``: within that but beyond the same bound on the *range* of the kind alone (the
      measure of the accuracy contract and of ``richardson``): a signal that varies little about a large
      value is less accurate than its variation needs. Only for a pair of runs that both claim accuracy on
      that measure (``range_claim``: a fixed-step run's estimate, the accuracy contract). An ``rtol`` run
      promises a local error relative to the values (``rtol |y| + atol``), which the ``disagreement`` scale
      checks: on a kind that varies little about a large value it is right and yet short of the range (CI
      seed 9005: J1.w varies by 1.25e-3 about 7.18 rad/s; ida at rtol 1e-8 is 7.7e-8 of the value off, 4.4e-4
      of the range; the default call, which promises the range, meets it). The range is what ``accuracy=``
      promises, and ``default_accuracy`` holds the default call to it.

    A ``disagreement`` that the runs at the other tolerance level show to be convergent
    (``_convergent``) is reported as ``convergent-accuracy`` instead.

    ``pairs`` (a dict) receives per pair the worst difference over its allowance on either scale.
    """
    pairs = {} if pairs is None else pairs
    from .metrics import sample
    from ..solvers.common import output_grid
    ok = [o for o in outcomes if o.status == "ok"]
    if len(ok) < 2:
        return []
    grid = output_grid(0.0, spec.t_end, spec.dt_out)
    kinds = motion_signals(model)
    tight = min(ok, key=lambda o: o.claim_rel)
    sampled = {o.label: {n: sample(results[o.label].t, results[o.label][n], grid) for ns in kinds.values()
                         for n in ns} for o in ok}
    ranges, mags = {}, {}
    for kind, names in kinds.items():
        ranges[kind] = max(float(np.ptp(sampled[tight.label][n])) for n in names)
        mags[kind] = max(ranges[kind], max(float(np.abs(sampled[tight.label][n]).max()) for n in names))
    findings = []
    gaps = {}           # per pair: the largest difference over max(range, |value|) of its kind
    for i, a in enumerate(ok):
        for b in ok[i + 1:]:
            gap = max(float(np.abs(sampled[a.label][n] - sampled[b.label][n]).max()) / max(mags[kind], 1e-300)
                      for kind, names in kinds.items() for n in names)
            gaps[a.label, b.label] = gaps[b.label, a.label] = gap
    for i, a in enumerate(ok):
        for b in ok[i + 1:]:
            worst = {"range": (0.0, ""), "mag": (0.0, "")}
            for kind, names in kinds.items():
                for scale_kind, scale in (("range", ranges[kind]), ("mag", mags[kind])):
                    allowed = (a.claim_rel + b.claim_rel) * scale + a.claim_abs + b.claim_abs
                    if allowed <= 0:
                        continue
                    for n in names:
                        d = np.abs(sampled[a.label][n] - sampled[b.label][n])
                        j = int(np.argmax(d))
                        ratio = float(d[j]) / allowed
                        if ratio > worst[scale_kind][0]:
                            info = (f"{n}: {a.label} and {b.label} differ by {d[j]:.3g} at t={grid[j]:.6g}, "
                                    f"{d[j] / max(ranges[kind], 1e-300):.3g} of the {kind} range {ranges[kind]:.3g} "
                                    f"({d[j] / max(mags[kind], 1e-300):.3g} of max(range, |{kind}|) = {mags[kind]:.3g}); "
                                    f"they claim {a.claim_rel:.0e} and {b.claim_rel:.0e} (+ {a.claim_abs + b.claim_abs:.0e})")
                            worst[scale_kind] = (ratio, info)
            pairs[f"{a.label}/{b.label}"] = (worst["mag"][0], worst["range"][0])
            if worst["mag"][0] > 1.0:
                info = worst["mag"][1]
                kind = "wrong-answer" if worst["mag"][0] > GROSS else "disagreement"
                if kind == "disagreement":
                    why = _convergent(a.label, b.label, gaps, results)
                    if why:
                        kind, info = "convergent-accuracy", f"{info}; {why}"
                findings.append(Finding(kind, info, f"{a.label}/{b.label}", info.split(":")[0]))
            elif worst["range"][0] > 1.0 and range_claim(a) and range_claim(b):
                info = worst["range"][1]
                findings.append(Finding("range-accuracy", info, f"{a.label}/{b.label}", info.split(":")[0]))
    return findings


#: the sensitivity probe explains a pair's difference when it moves the reference by at least this share of it
EXPLAINED_SHARE = 0.1


def _relative_gap(res_a, res_b, model, spec, scale_from) -> tuple[float, str]:
    """``(gap, signal)``: the largest difference of two runs on the output grid over max(range, largest
    |value|) of its kind in ``scale_from`` (the measure of ``agreement``'s ``disagreement``)."""
    from .metrics import sample
    from ..solvers.common import output_grid
    grid = output_grid(0.0, spec.t_end, spec.dt_out)
    worst = (0.0, "")
    for kind, names in motion_signals(model).items():
        ref = {n: sample(scale_from.t, scale_from[n], grid) for n in names}
        mag = max(max(float(np.ptp(y)), float(np.abs(y).max())) for y in ref.values())
        for n in names:
            d = float(np.abs(sample(res_a.t, res_a[n], grid) - sample(res_b.t, res_b[n], grid)).max())
            if d / max(mag, 1e-300) > worst[0]:
                worst = (d / max(mag, 1e-300), n)
    return worst


def perturb_masses(model, delta):
    """Scale the mass (J or m) of every body of ``model`` by ``1 + delta`` and ``1 - delta`` in turn (in the
    model's order): a perturbation of relative size ``delta`` that keeps every start consistent."""
    k = 0
    for comp in model.components.values():
        if getattr(comp, "role", "") == "body":
            setattr(comp, comp.mass_param, getattr(comp, comp.mass_param) * (1 + (delta if k % 2 == 0 else -delta)))
            k += 1
    return model


def conditioning(findings, outcomes, results, model, spec, runs=RUNS, time_limit_s=None, max_calls=None,
                 probe=None) -> list[Finding]:
    """Reclassify the ``wrong-answer`` and ``disagreement`` findings that the model's sensitivity explains
    as ``ill-conditioned`` (module docstring); the others are returned unchanged.

    For a pair at plain tolerances with larger rtol ``delta``: the tight reference (``REFERENCE_RUNS``, the
    first that returned) is run again on the model with every mass perturbed by ``delta``
    (``perturb_masses``); when that moves it by at least ``EXPLAINED_SHARE`` of the pair's difference (the
    measure of ``_relative_gap``), a perturbation of the size of the runs' tolerance grows to the size of
    their difference; when it moves it by ``GROSS`` times the pair's claims or more, the model's response
    to a perturbation of the size of the tolerance alone breaks the claims grossly, so they cannot hold on
    this model (a chaotic rattle saturates: seed 20152's DOP853 at rtol 1e-8 is 0.69 of the range off the
    references, and a 1e-8 perturbation moves them by 0.05, 500 times the claims). Either way the model is
    ill-conditioned at that tolerance, and the pair's difference is no evidence of a wrong answer. The global
    claim on such a model is the accuracy contract's (the default call, held to it by ``default_accuracy``). ``probe(delta) -> (gap, signal) or None`` replaces the
    re-run (tests)."""
    ok = {o.label: o for o in outcomes if o.status == "ok"}
    refs = [r for r in REFERENCE_RUNS if r in ok]
    judged = [f for f in findings if f.kind in ("wrong-answer", "disagreement") and "/" in f.run]
    if not judged or not refs:
        return findings
    ref = refs[0]
    cache = {}

    def measured(delta):
        if delta not in cache:
            if probe is not None:
                cache[delta] = probe(delta)
            else:
                cache[delta] = _probe(spec, model, ref, results[ref], runs, delta, time_limit_s, max_calls)
        return cache[delta]

    out = []
    for f in findings:
        if f not in judged:
            out.append(f)
            continue
        a, b = f.run.split("/")
        if a not in ok or b not in ok or range_claim(ok[a]) or range_claim(ok[b]):
            out.append(f)
            continue
        delta = max(float(ok[a].options.get("rtol", 1e-6)), float(ok[b].options.get("rtol", 1e-6)))
        gap = _relative_gap(results[a], results[b], model, spec, results[ref])[0]
        moved = measured(delta)
        claims = ok[a].claim_rel + ok[b].claim_rel
        if moved is None or not moved[0] >= min(EXPLAINED_SHARE * gap, GROSS * claims):
            out.append(f)
            continue
        out.append(Finding("ill-conditioned", f"{f.detail}; ill-conditioned: every mass perturbed by +-{delta:g} "
                           f"moves {ref} by {moved[0]:.3g} of max(range, |value|) on {moved[1]} ({moved[0] / delta:.3g} "
                           f"times the perturbation; the pair differs by {gap:.3g}): perturbations of the size of the "
                           f"tolerance grow to the size of the difference", f.run, f.where))
    return out


def _probe(spec, model, ref_label, ref_res, runs, delta, time_limit_s, max_calls):
    """The reference run again on a model with perturbed masses: ``(gap, signal)`` against the unperturbed
    reference, or None when it does not return."""
    from .guard import time_limit, work_budget
    import warnings
    solver, options = next((s, o) for label, s, o in runs if label == ref_label)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            other = perturb_masses(spec.build(), delta)
            with time_limit(time_limit_s), work_budget(other, max_calls or DEFAULT_MAX_CALLS):
                res = other.simulate(spec.t_end, dt_out=spec.dt_out, solver=solver, **dict(options))
    except Exception:      # noqa: BLE001 - a probe that does not return explains nothing
        return None
    return _relative_gap(res, ref_res, model, spec, ref_res)


def _mode_changes(res):
    """The mode changes of a run, as a multiset of (component, old, new): the path it took."""
    from collections import Counter
    return Counter((e.component, e.old_mode, e.new_mode) for e in res.events)


def _convergent(a, b, gaps, results) -> str:
    """Why the difference of runs ``a`` and ``b`` is convergent (see ``agreement``), or "".

    With a loose run in the pair, the pair of their tight companions (``COMPANIONS``; a tight run is its own)
    must differ at least ``CONVERGENCE`` times less; with two tight runs, the pair of their loose
    counterparts at least ``CONVERGENCE`` times more; a loose run and its own tight companion: the tight
    run and another solver's tight run at least ``CONVERGENCE`` times less. Every run must make the same
    mode changes as its companion: a run that took another path (a missed or extra event, seed 37) is never excused, however
    its difference scales.

    Why: the campaign's claim for an adaptive run is a stand-in, ``CLAIM_PER_RTOL * rtol`` of the range,
    not an estimate the run makes. A solver whose global error grows faster than its tolerance falls short of
    it while being right: on seed 86 IDA's error on a tyre's slip speed went as rtol^0.8 (7.4e-4, 2.1e-4,
    3.4e-5, 5.2e-6, 8.1e-7 of the range at rtol 1e-7 .. 1e-11 against rtol 1e-12, the largest at the
    road contact's break-aways; DOP853 at 1e-10 agrees with ida at 1e-12), so at 1e-8 it was 2.1 times
    the stand-in claim and at 1e-10 5.2 times. A wrong answer does not converge like that across both
    solvers with unchanged paths."""
    loose = {v: k for k, v in COMPANIONS.items()}
    tight_a, tight_b = COMPANIONS.get(a, a), COMPANIONS.get(b, b)
    if tight_a == b or tight_b == a:
        # one solver at two tolerances (the loose run's own error): its tight run must agree with another
        # solver's tight run CONVERGENCE times better
        tight = tight_a if tight_a == b else tight_b
        third = [r for r in COMPANIONS.values() if r != tight and (tight, r) in gaps]
        if not third:
            return ""
        other, closer = (tight, third[0]), True
        paths = [(a, b)]
    elif (tight_a, tight_b) != (a, b):
        other, closer = (tight_a, tight_b), True
        paths = [(a, tight_a), (b, tight_b)]
    else:
        other, closer = (loose.get(a), loose.get(b)), False
        paths = [(a, other[0]), (b, other[1])]
    if None in other or other[0] == other[1] or other not in gaps or (a, b) not in gaps:
        return ""
    for run, comp in paths:
        if run != comp and _mode_changes(results[run]) != _mode_changes(results[comp]):
            return ""
    here, there = gaps[a, b], gaps[other]
    if closer and not there * CONVERGENCE <= here:
        return ""
    if not closer and not there >= CONVERGENCE * here:
        return ""
    return (f"convergent: {other[0]} and {other[1]} differ by {there:.2g} of max(range, |value|) "
            f"({(here / max(there, 1e-300)) if closer else (there / max(here, 1e-300)):.3g} times "
            f"{'less' if closer else 'more'}), and each run makes its "
            f"companion's mode changes")


def contract_error(res, ref, model, spec):
    """``(error, signal, t)``: the global error of ``res`` against ``ref`` in the accuracy contract's measure
    (``solvers.accuracy``: max over the output instants and the state signals of the difference over the
    range of the reference's signals of that kind)."""
    from ..solvers.accuracy import compare_runs, result_state_labels
    from ..solvers.common import output_grid
    labels = result_state_labels(model.compile())
    est = compare_runs(res, ref, labels, output_grid(0.0, spec.t_end, spec.dt_out))
    return est.value, est.signal, est.t


def default_accuracy(outcomes, results, model, spec) -> list[Finding]:
    """The default call (``m.simulate(t_end, dt_out)``: solver auto, accuracy ``DEFAULT_ACCURACY``) keeps its
    promise: its error against the tight reference (``REFERENCE_RUNS``, the first that returned), in the
    contract's measure (``contract_error``), is at most the accuracy plus the reference's own error (the
    difference of the two references in the same measure when both returned, else ``CLAIM_PER_RTOL`` times
    its rtol). Beyond that: the finding ``default-accuracy`` (a broken promise of the default call)."""
    ok = {o.label: o for o in outcomes if o.status == "ok"}
    refs = [r for r in REFERENCE_RUNS if r in ok]
    findings = []
    for label in CONTRACT_RUNS:
        if label not in ok or not refs:
            continue
        ref = results[refs[0]]
        if len(refs) > 1:
            ref_err = contract_error(results[refs[1]], ref, model, spec)[0]
        else:
            ref_err = CLAIM_PER_RTOL * float(ok[refs[0]].options.get("rtol", 1e-6))
        err, signal, t = contract_error(results[label], ref, model, spec)
        ok[label].metrics["contract_error"] = err
        ok[label].metrics["reference_error"] = ref_err
        allowed = ok[label].claim_rel + ref_err
        if not err <= allowed:
            res = results[label]
            findings.append(Finding(
                "default-accuracy", f"{signal}: the default call ({res.stats.solver}, "
                f"{_settings_text(res)}) is {err:.3g} of the range of its kind off {refs[0]} at t={t:.6g}; it "
                f"promises {ok[label].claim_rel:g} (estimate {res.stats.error_estimate}; reference error "
                f"{ref_err:.2g})", f"{label}/{refs[0]}", signal.split(".")[0]))
    return findings


def _settings_text(res):
    st = res.stats.extra.get("settings") or {}
    return ", ".join(f"{k}={v:.3g}" for k, v in st.items()) or "default settings"


def _is_linear(model, t_end):
    from ..solvers.expm import nonlinear_components
    try:
        return not nonlinear_components(model.compile(), 0.0, float(t_end))
    except Exception:      # noqa: BLE001 - the runs themselves report what compile() raises
        return False


def evaluate(spec: ModelSpec, runs=RUNS, max_calls=DEFAULT_MAX_CALLS, time_limit_s=None,
             integral_tol=None) -> Verdict:
    """Build, run and check one generated model (see the module docstring for the verdicts); ``integral_tol``:
    as ``finite_check``'s (the CI subset reads the heats at 1e-6 to keep within its time)."""
    from ..errors import RegmechError, RegularityError
    from .guard import RunTimeout, WorkBudgetExceeded, time_limit, work_budget
    import warnings
    t0 = time.perf_counter()
    v = Verdict(spec.name, spec.seed, "pass", list(spec.families))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            model = spec.build()
            model.check(warn=False)
    except RegularityError as exc:
        v.findings.append(Finding("generator", f"RegularityError: {_first_line(exc)}"))
    except Exception as exc:      # noqa: BLE001 - the generator must build only valid models
        v.findings.append(Finding("generator", f"{type(exc).__name__}: {_first_line(exc)}"))
    if v.findings:
        v.status = "finding"
        v.wall_s = time.perf_counter() - t0
        return v
    v.n_components = len(model.components)
    spec.linear = _is_linear(model, spec.t_end)
    results = {}
    for label, solver, options in runs:
        o = RunOutcome(label, solver, dict(options), "ok")
        if solver == "expm":
            if not spec.linear:
                o.status = "skipped"
                v.runs.append(o)
                continue
            o.options.setdefault("h", spec.dt_out)
        ts = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                with time_limit(time_limit_s), work_budget(model, max_calls):
                    res = model.simulate(spec.t_end, dt_out=spec.dt_out, solver=solver, **o.options)
            results[label] = res
            o.claim_rel, o.claim_abs = claimed_error(label, solver, o.options, res)
        except (RunTimeout, WorkBudgetExceeded) as exc:
            o.status, o.error, o.message = "budget", type(exc).__name__, _first_line(exc)
            v.findings.append(Finding("budget", f"{type(exc).__name__}: {_first_line(exc)}", label))
        except RegmechError as exc:
            o.status, o.error, o.message = "refused", type(exc).__name__, _first_line(exc)
            v.refusals.append((label, o.error, o.message))
        except Exception as exc:   # noqa: BLE001 - that is the finding
            o.status, o.error, o.message = "crash", type(exc).__name__, _first_line(exc)
            tb = traceback.extract_tb(exc.__traceback__)
            at = f" (at {tb[-1].filename.rsplit('/', 2)[-1]}:{tb[-1].lineno} {tb[-1].name})" if tb else ""
            v.findings.append(Finding("crash", f"{type(exc).__name__} (not a regmech error): {o.message}{at}", label))
        o.wall_s = time.perf_counter() - ts
        v.runs.append(o)
        if o.status == "ok":
            try:
                bad = finite_check(res, label, integral_tol)
                v.findings += bad
                if not bad:
                    v.findings += energy_checks(res, model, label, rel=o.claim_rel,
                                                abs_speed=o.claim_abs, metrics=o.metrics)
            except Exception as exc:     # noqa: BLE001 - a result whose signals cannot be read
                v.findings.append(Finding("crash", f"reading the result: {type(exc).__name__}: {_first_line(exc)}",
                                          label))
    try:
        found = agreement([o for o in v.runs if o.status == "ok" and o.label not in CONTRACT_RUNS], results,
                          model, spec, v.pairs)
        v.findings += conditioning(found, v.runs, results, model, spec, runs, time_limit_s, max_calls)
        v.findings += default_accuracy(v.runs, results, model, spec)
    except Exception as exc:        # noqa: BLE001
        v.findings.append(Finding("crash", f"comparing the runs: {type(exc).__name__}: {_first_line(exc)}"))
    v.status = "finding" if v.findings else ("refused" if v.refusals else "pass")
    v.wall_s = time.perf_counter() - t0
    return v


__all__ = ["FAMILIES", "FAMILIES_NO_IMPACTS", "SIGNALS", "ModelSpec", "generate", "generate_seed", "evaluate", "Verdict", "Finding",
           "RunOutcome", "RUNS", "claimed_error", "energy_checks", "finite_check", "agreement", "integrate",
           "contract_error", "default_accuracy", "conditioning", "perturb_masses"]
