"""Plots of modes and responses (matplotlib, optional).

Figures are built with ``matplotlib.figure.Figure`` and the Agg canvas, so
writing files never touches pyplot's global state or needs a display.
Each function returns the figure and writes it to ``path`` when given.
"""

from __future__ import annotations

import numpy as np

from .. import units as units_mod
from ..errors import RegmechError
from ..io import save_figure


def _figure(nrows=1, ncols=1, figsize=(9, 5), **kw):
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        raise RegmechError("plots need matplotlib: pip install 'regmech[plot]'") from None
    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False, **kw)
    return fig, axes


def _save(fig, path):
    if path is not None:
        save_figure(fig, path, "plot")
    return fig


def _shown(unit, units, name):
    """The display unit of output ``name`` (SI ``unit``) under ``units`` (a str, or a dict keyed by output
    name, variable or SI unit, as ``Result.display_unit``), and the factor to divide SI values by."""
    if units is None or unit is None or (isinstance(units, str) and units.strip().upper() == "SI"):
        return unit, 1.0
    if isinstance(units, str):
        want = units
    else:
        want = next((units[k] for k in (name, name.rpartition(".")[2], unit) if k in units), None)
    if want is None:
        return unit, 1.0
    return units_mod.normalise(want), units_mod.factor(unit, want, name)


def _quantity(unit) -> str:
    return units_mod.QUANTITIES.get(unit or "", "value")


def _elastic(natural_hz, lo, hi):
    """(mode number, f) of the elastic natural frequencies inside [lo, hi] Hz."""
    if natural_hz is None:
        return []
    return [(i + 1, float(f)) for i, f in enumerate(natural_hz) if f > 0 and lo <= f <= hi]


def _top_labels(ax, items, span):
    """Short labels at the top of ``ax`` at x positions (x, label); labels closer than 1.5 % of ``span``
    share one ("6,7") so that they never overlap."""
    import matplotlib.transforms as mtransforms
    trans = mtransforms.blended_transform_factory(ax.transData, ax.transAxes)
    clusters: list = []
    for x, lab in sorted(items):
        if clusters and x - clusters[-1][0] < 0.015 * span:
            clusters[-1][1].append(lab)
        else:
            clusters.append((x, [lab]))
    for x, labs in clusters:
        text = ",".join(labs) if len(labs) <= 3 else f"{labs[0]}-{labs[-1]}"
        ax.text(x, 1.01, text, transform=trans, fontsize=7.5, ha="center", va="bottom", color="0.15",
                fontweight="bold")


def _key(ax, lines, offset=-34):
    """Lines of text under ``ax`` (what the numbered marks are), in two columns when many."""
    if not lines:
        return
    half = (len(lines) + 1) // 2 if len(lines) > 5 else len(lines)
    for j, col in enumerate([lines[:half], lines[half:]] if half < len(lines) else [lines]):
        ax.annotate("\n".join(col), xy=(0.5 * j, 0.0), xycoords="axes fraction", xytext=(0, offset),
                    textcoords="offset points", fontsize=7.5, va="top", ha="left", family="monospace",
                    color="0.15")


#: at most this many natural frequencies (or resonance speeds) are marked in one plot; the rest are counted
MAX_MARKS = 12


def _mark_naturals(axes, marks, label_ax, key_ax, span):
    """Natural frequencies as dashed vertical lines through ``axes``, their mode numbers above
    ``label_ax``, the frequencies listed under ``key_ax`` (the lowest ``MAX_MARKS``; the others counted)."""
    if not marks:
        return
    rest = marks[MAX_MARKS:]
    marks = marks[:MAX_MARKS]
    for a in axes:
        for _, f in marks:
            a.axvline(f, color="0.35", lw=0.8, ls="--", zorder=0.5)
    _top_labels(label_ax, [(f, str(m)) for m, f in marks], span)
    lines = [f"mode {m:>2}: {f:.4g} Hz" for m, f in marks]
    if rest:
        lines.append(f"modes {rest[0][0]}-{rest[-1][0]} ({len(rest)}, {rest[0][1]:.4g} to {rest[-1][1]:.4g} Hz): "
                     f"not marked")
    _key(key_ax, lines)


def _log_values(amp):
    """|amplitude| for a log axis (zeros masked) and the legend note when some were zero."""
    bad = ~(amp > 0)
    if not bad.any():
        return amp, ""
    if bad.all():
        return np.full_like(amp, np.nan), " (zero at every frequency: not drawn on the log axis)"
    return np.where(bad, np.nan, amp), f" (zero at {bad.mean():.0%} of frequencies: gaps)"


def plot_mode_shapes(result, path=None, n_modes: int = 6, include_rigid: bool = False):
    """Mode shapes (max = 1) over the masses, one line per mode."""
    table = result.table(normalize=True)
    rows = [i for i in range(len(result.omega2)) if include_rigid or not result.rigid[i]][:n_modes]
    n = len(table.columns)
    fig, axes = _figure(figsize=(min(16.0, max(6.0, 0.6 * n + 3)), 5))
    ax = axes[0, 0]
    x = np.arange(n)
    for i in rows:
        ax.plot(x, table.data[i], marker="o" if n <= 40 else None,
                label=f"mode {i + 1}: {result.frequencies_hz[i]:.4g} Hz")
    ax.axhline(0.0, color="0.6", lw=0.8)
    step = int(np.ceil(n / 40))          # a long model: every step-th mass named, so that the names stay legible
    ax.set_xticks(x[::step])
    ax.set_xticklabels(table.columns[::step], rotation=45 if n > 6 else 0, ha="right" if n > 6 else "center",
                       fontsize=8 if n > 20 else None)
    lin = result.lin
    comps = lin.compiled.model.components
    kinds = {getattr(comps.get(n), "mass_param", None) for n in table.columns}
    unit = "rad" if kinds == {"J"} else "m" if kinds == {"m"} else "rad or m"
    ax.set_ylabel(f"displacement of each mass [{unit}], largest = 1")
    n_rigid = int(np.sum(result.rigid))
    skipped = len([i for i in range(len(result.omega2)) if include_rigid or not result.rigid[i]]) - len(rows)
    notes = []
    if n_rigid and not include_rigid:
        notes.append(f"{n_rigid} rigid-body mode(s) at 0 Hz not drawn")
    if skipped > 0:
        notes.append(f"{skipped} higher mode(s) not drawn")
    where = f"at t = {lin.t:g} s" if getattr(lin, "t", 0) else "at the start values"
    ax.set_title(f"{lin.compiled.model.name}: mode shapes {where}" + (f" ({'; '.join(notes)})" if notes else ""),
                 fontsize=10)
    if rows:
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    else:
        ax.text(0.5, 0.5, "no elastic mode: every mode is a rigid-body mode", transform=ax.transAxes,
                ha="center")
    ax.grid(True, alpha=0.3)
    return _save(fig, path)


def plot_frequency_response(resp, path=None, axes=None, units=None):
    """Amplitude (log; one axis per output unit) and phase of every output against frequency, with the
    natural frequencies marked; axis labels carry the units (output unit per input unit)."""
    ins = resp.inputs or {}
    in_units = getattr(resp, "input_units", {}) or {}
    out_units = getattr(resp, "units", {}) or {}
    unit_input = len(ins) == 1 and abs(abs(next(iter(ins.values()))) - 1.0) < 1e-12
    groups: dict = {}
    for name in resp.outputs:
        shown, f = _shown(out_units.get(name), units, name)
        groups.setdefault(shown, []).append((name, f))
    if axes is None:
        fig, ax = _figure(len(groups) + 1, 1, figsize=(10, 2.8 * len(groups) + 2.6), sharex=True)
        amp_axes, ax_p = [ax[i, 0] for i in range(len(groups))], ax[-1, 0]
    else:
        ax_a, ax_p = axes
        fig = ax_a.figure
        amp_axes = [ax_a] * len(groups)
    in_name = next(iter(ins), "input")
    in_unit = in_units.get(in_name)
    for a, (shown, members) in zip(amp_axes, groups.items()):
        for name, f in members:
            j = resp.outputs.index(name)
            amp, note = _log_values(np.abs(resp.values[:, j]) / f)
            a.semilogy(resp.freqs_hz, amp, label=name + note, color=f"C{j % 10}")
        if unit_input:
            per = f" per {in_unit}" if in_unit else f" per unit {in_name}"
            a.set_ylabel(f"{_quantity(out_units.get(members[0][0]))} amplitude\n[{shown or '?'}{per}]")
        else:
            a.set_ylabel(f"{_quantity(out_units.get(members[0][0]))} amplitude [{shown or '?'}]")
        a.grid(True, which="both", alpha=0.25)
        a.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    for j, name in enumerate(resp.outputs):
        amp = np.abs(resp.values[:, j])
        ph = np.degrees(np.unwrap(np.angle(resp.values[:, j])))
        ax_p.plot(resp.freqs_hz, np.where(amp > 0, ph, np.nan), label=name, color=f"C{j % 10}")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    ax_p.grid(True, alpha=0.25)
    lo, hi = float(np.min(resp.freqs_hz)), float(np.max(resp.freqs_hz))
    marks = _elastic(getattr(resp, "natural_hz", None), lo, hi)
    _mark_naturals(list(dict.fromkeys(amp_axes)) + [ax_p], marks, amp_axes[0], ax_p, hi - lo)
    if unit_input:
        src = f"per unit amplitude of {in_name}" + (f" (1 {in_unit})" if in_unit else "")
    else:
        src = "to " + ", ".join(f"{k} = {abs(v):g}" + (f" {in_units.get(k)}" if in_units.get(k) else "")
                                for k, v in ins.items())
    title = f"{getattr(resp, 'model_name', '') or 'harmonic response'}: steady-state response {src}"
    if marks:
        title += ";\ndashed: undamped natural frequencies, numbered by mode (listed below)"
    amp_axes[0].set_title(title, loc="left", fontsize=10, pad=14 if marks else 6)
    return _save(fig, path)


def plot_multi_harmonic(resp, path=None, units=None):
    """Amplitude of each harmonic's contribution and the superposed steady state."""
    fig, ax = _figure(2, 1, figsize=(10, 7))
    ax_b, ax_t = ax[0, 0], ax[1, 0]
    width = 0.8 / max(1, len(resp.outputs))
    idx = np.arange(len(resp.freqs_hz))
    out_units = getattr(resp, "units", {}) or {}
    shown = {n: _shown(out_units.get(n), units, n) for n in resp.outputs}
    for j, name in enumerate(resp.outputs):
        ax_b.bar(idx + j * width, np.abs(resp.values[:, j]) / shown[name][1], width,
                 label=f"{name} [{shown[name][0] or '?'}]")
    ax_b.set_xticks(idx + width * (len(resp.outputs) - 1) / 2)
    orders = getattr(resp, "orders", None)
    ax_b.set_xticklabels([f"order {o:g}\n{f:.3g} Hz" for o, f in zip(orders, resp.freqs_hz)] if orders is not None
                         else [f"{f:.3g} Hz" for f in resp.freqs_hz])
    labels = sorted({f"{_quantity(out_units.get(n))} [{shown[n][0] or '?'}]" for n in resp.outputs})
    ax_b.set_ylabel("amplitude: " + ", ".join(labels))
    ax_b.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    in_unit = getattr(resp, "input_unit", None)
    ax_b.set_title(f"steady state under harmonics of {resp.input_name}"
                   + (f" (amplitudes in {in_unit})" if in_unit else ""), loc="left", fontsize=10)
    t = resp._grid()
    y = resp.time_series(t)
    for j, name in enumerate(resp.outputs):
        ax_t.plot(t, y[:, j] / shown[name][1], label=name)
    ax_t.set_xlabel("time [s] (one period of the superposed harmonics)")
    ax_t.set_ylabel("steady state: " + ", ".join(labels))
    ax_t.grid(True, alpha=0.25)
    ax_t.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return _save(fig, path)


def plot_order_sweep(sweep, path=None, units=None):
    """Amplitude of each order and the superposed peak against speed, per output; the speeds where an
    order meets a natural frequency (60 f / order) marked."""
    n = len(sweep.outputs)
    fig, ax = _figure(n, 1, figsize=(10, 3.2 * n + 1.0), sharex=True)
    out_units = getattr(sweep, "units", {}) or {}
    rpm = sweep.speeds_hz * 60.0
    res_speeds = sorted(sweep.resonance_speeds() if hasattr(sweep, "resonance_speeds") else [], key=lambda c: c[3])
    more = len(res_speeds) - MAX_MARKS
    res_speeds = res_speeds[:MAX_MARKS]
    for j, name in enumerate(sweep.outputs):
        a = ax[j, 0]
        shown, f = _shown(out_units.get(name), units, name)
        for h, order in enumerate(sweep.orders):
            a.plot(rpm, sweep.amplitude[:, h, j] / f, label=f"order {order:g}")
        a.plot(rpm, sweep.peak[:, j] / f, "k--", label="peak of the sum of orders")
        a.set_ylabel(f"{name}\n{_quantity(out_units.get(name))} amplitude [{shown or '?'}]")
        a.grid(True, alpha=0.25)
        a.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        for order, mode, _, n_rpm in res_speeds:
            a.axvline(n_rpm, color="0.35", lw=0.8, ls=":", zorder=0.5)
    if res_speeds:
        _top_labels(ax[0, 0], [(c[3], str(i)) for i, c in enumerate(res_speeds, start=1)], rpm[-1] - rpm[0])
        _key(ax[-1, 0], [f"{i:>2}  {c[3]:7.0f} rpm  order {c[0]:g} meets mode {c[1]} ({c[2]:.4g} Hz)"
                         for i, c in enumerate(res_speeds, start=1)]
             + ([f"    {more} more above {res_speeds[-1][3]:.0f} rpm not marked"] if more > 0 else []))
    ax[-1, 0].set_xlabel("engine speed [rpm]")
    in_unit = getattr(sweep, "input_unit", None)
    title = f"{getattr(sweep, 'model_name', '')}: order response to {getattr(sweep, 'input_name', '') or 'the input'}" \
        + (f" (order amplitudes in {in_unit})" if in_unit else "")
    if res_speeds:
        title += ";\ndotted: an order meets a natural frequency (numbered, listed below)"
    ax[0, 0].set_title(title, loc="left", fontsize=10, pad=14 if res_speeds else 6)
    return _save(fig, path)


def plot_campbell(diagram, path=None, ax=None):
    """Campbell diagram (``CampbellDiagram.plot``)."""
    if ax is None:
        fig, axes = _figure(figsize=(10, 6))
        ax = axes[0, 0]
    else:
        fig = ax.figure
    n = diagram.speeds_rpm
    top_order = float(diagram.order_hz(float(np.max(diagram.orders)), n[-1]))
    low_order = float(diagram.order_hz(float(np.min(diagram.orders)), n[-1]))
    nat_max = float(np.max(diagram.natural_hz)) if diagram.natural_hz.size else 0.0
    # up to the highest mode an order reaches (modes far above every order are left out, said in the title),
    # and at least the whole ray of the lowest order
    ylim = 1.15 * max(min(nat_max, 1.5 * top_order), low_order)
    hidden = 0
    for j, m in enumerate(diagram.mode_numbers):
        f = diagram.natural_hz[:, j]
        if np.min(f) > ylim:
            hidden += 1
            continue
        ax.plot(n, f, color="tab:blue", lw=1.6)
        ax.text(n[-1], f[-1], f"  mode {m}: {f[-1]:.3g} Hz", fontsize=8, va="center", ha="left", color="tab:blue")
    top_exits = []
    for k in diagram.orders:
        f = diagram.order_hz(k, n)
        ax.plot(n, f, color="0.4", lw=1.0, ls="--")
        if f[-1] <= ylim:
            ax.text(n[-1], f[-1], f" order {k:g}", fontsize=8, color="0.25", ha="left", va="center")
        else:                                    # the ray leaves through the top: its order written there
            top_exits.append((60.0 * diagram.ratio * ylim / k, f"{k:g}"))
    if diagram.operating_rpm is not None:
        # the operating point: a vertical line and each order's excitation there
        op = diagram.operating_rpm
        ax.axvline(op, color="tab:green", lw=1.4)
        ax.text(op, ylim, f"operating point {op:.0f} rpm", fontsize=8, color="tab:green", rotation=90,
                ha="right", va="top")
        for k, fh in diagram.operating_point():
            if fh <= ylim:
                ax.plot(op, fh, "D", color="tab:green", ms=5)
    _top_labels(ax, top_exits, float(n[-1] - n[0]))
    shown = [c for c in diagram.crossings if c[2] <= ylim]
    for i, (order, m, fh, rpm) in enumerate(shown, start=1):
        ax.plot(rpm, fh, "o", mfc="none", mec="tab:red", ms=9, mew=1.6)
        ax.annotate(str(i), (rpm, fh), xytext=(5, -12), textcoords="offset points", fontsize=7.5, color="tab:red",
                    fontweight="bold")
    _key(ax, [f"{i:>2}  {rpm:7.0f} rpm  order {o:g} meets mode {m} ({fh:.4g} Hz)"
              for i, (o, m, fh, rpm) in enumerate(shown, start=1)])
    ax.set_xlim(float(n[0]), float(n[-1]))
    ax.set_ylim(0.0, ylim)
    ax.set_xlabel(f"{diagram.shaft} speed [rpm]")
    ax.set_ylabel("frequency [Hz]")
    ax.grid(True, alpha=0.25)
    title = f"{diagram.model_name + ': ' if diagram.model_name else ''}Campbell diagram: natural frequencies " \
            f"(solid), engine orders f = k n / {60 * diagram.ratio:.4g} (dashed,\nk at the top or the right end), " \
            f"resonances (circles, numbered, listed below)"
    if hidden:
        title += f"\n{hidden} higher mode(s) above {ylim:.3g} Hz not drawn"
    ax.set_title(title, loc="left", fontsize=10, pad=14)
    return _save(fig, path)
