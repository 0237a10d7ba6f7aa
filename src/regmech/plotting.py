"""Time plots of a result (``Result.plot``): one axis per unit, a mode strip per friction device.

What the figure holds, top to bottom:

* one axis per *display unit* of the signals asked for (speeds in rpm on
  one, torques in N m on the next, forces in N on another), each labelled
  with the quantity and the unit shown (``speed [rpm]``), its signals in a
  legend to the right;
* one thin strip per friction or loss device that has a ``mode`` signal
  (``clutch``, ``wheel.road_contact``): coloured bars with the mode's name
  (Free, Stuck, Forward, Backward, Held) written in every bar wide enough
  to hold it;
* the mode changes as thin vertical lines through every axis, and with
  ``events="annotate"`` each one labelled with the device and its
  transition (``clutch: Free -> Backward``; simultaneous identical changes
  of several devices share one label).

Without names the figure shows the speeds of the masses (in model order),
then the torques and forces of the devices and sources: not the flange
signals, which repeat the masses' motion and the devices' torques.

On a logarithmic axis (``logy=True``) values <= 0 cannot be drawn: a
signal that has them says so in its legend entry ("<= 0 throughout, not
drawn" or "gaps where <= 0") instead of vanishing.

The figure is made without pyplot when it is only written to a file, so a
script that saves many plots neither needs a display nor collects figures.
"""

from __future__ import annotations

import numpy as np

from . import units as units_mod
from .errors import ParameterError, RegmechError
from .io import save_figure
from .modes import MODE_NAMES

#: colour of each mode in the mode strips (Free light: nothing transmitted; Stuck dark: locked)
MODE_COLOURS = {-1: "#4c72b0", 0: "#c44e52", 1: "#55a868", 2: "#dddddd", 3: "#dd8452"}
#: at most this many signals per axis in the default selection (the rest are named in the axis' note)
MAX_DEFAULT_PER_AXIS = 8
#: at most this many event labels with events="annotate" (the rest are lines only, and said so)
MAX_EVENT_LABELS = 16


def _pyplot_free_figure(figsize):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig


def require_matplotlib(what: str = "plot()"):
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise RegmechError(f"{what} needs matplotlib: pip install 'regmech[plot]'") from None


# ------------------------------------------------------------------------------------ defaults
def component_order(res) -> list[str]:
    """Component names in model order (the order they were added: along the power path in the library
    scenes); for a result read from a file, which holds no model, the order of its signal names."""
    traj = getattr(res, "_traj", None)
    model = getattr(getattr(traj, "c", None), "model", None)
    if model is not None:
        return list(model.components)
    seen = {}
    for n in res.names:
        seen.setdefault(n.rpartition(".")[0], None)
    return list(seen)


def default_signals(res) -> list[str]:
    """The signals a reader wants first: every mass's speed (``J1.w``, ``body.v``), then the torque or
    force of every device and source (``clutch.tau``, ``road_load.f``), in model order.

    A mass is a component with a ``kinetic`` signal; a device's own torque is ``P.tau``/``P.f`` where
    ``P`` has no position signal (``P.phi``/``P.s`` would make it a flange or a mass)."""
    names = set(res.names)
    speeds, forces = [], []
    for p in component_order(res):
        if f"{p}.kinetic" in names:
            speeds += [f"{p}.{v}" for v in ("w", "v") if f"{p}.{v}" in names]
        elif f"{p}.phi" not in names and f"{p}.s" not in names:
            forces += [f"{p}.{v}" for v in ("tau", "f") if f"{p}.{v}" in names]
    return speeds + forces


def mode_devices(res) -> list[str]:
    """The devices with a ``mode`` signal (friction and loss elements), in model order."""
    names = set(res.names)
    return [p for p in component_order(res) if f"{p}.mode" in names]


def _segments(t, codes):
    """(start, end, code) of the stretches of constant mode."""
    codes = np.asarray(np.round(codes), int)
    if len(t) == 0:
        return []
    cut = np.nonzero(np.diff(codes))[0]
    starts = np.r_[0, cut + 1]
    ends = np.r_[cut + 1, len(t) - 1]
    out = []
    for a, b in zip(starts, ends):
        t0, t1 = float(t[a]), float(t[min(b, len(t) - 1)])
        if t1 > t0 or len(t) == 1:
            out.append((t0, t1, int(codes[a])))
    return out


def _event_groups(events):
    """Events at the same instant with the same transition, merged: (t, text)."""
    groups: dict = {}
    for ev in events:
        if ev.kind == "driving side":
            key = (round(ev.t, 12), "driving side", ev.old_mode, ev.new_mode)
            trans = f"driving side {'a->b' if ev.old_mode == 1 else 'b->a'}"
        else:
            key = (round(ev.t, 12), "mode", ev.old_mode, ev.new_mode)
            trans = f"{MODE_NAMES.get(ev.old_mode, ev.old_mode)} -> {MODE_NAMES.get(ev.new_mode, ev.new_mode)}"
        groups.setdefault(key, (ev.t, trans, []))[2].append(ev.component)
    return [(t, f"{', '.join(devs)}: {trans}") for t, trans, devs in groups.values()]


def _log_note(values) -> tuple[np.ndarray, str]:
    """Values for a log axis (<= 0 masked) and the note for the legend when some were masked."""
    bad = ~(values > 0)
    if not bad.any():
        return values, ""
    masked = np.where(bad, np.nan, values)
    if bad.all():
        return masked, " (<= 0 throughout: not drawn on the log axis)"
    share = bad.mean()
    return masked, f" (gaps where <= 0: {share:.0%} of points)" if share < 0.995 else \
        f" (<= 0 at all but {int((~bad).sum())} points: gaps on the log axis)"


# ------------------------------------------------------------------------------------ the plot
def plot_result(res, names=None, *, ax=None, path=None, title=None, events=True, units=None, modes=None,
                logy=False, figsize=None):
    """The time plot of ``Result.plot`` (its docstring is the reference). Returns the figure; with
    ``ax`` given, everything is drawn on that one axis and the axis is returned."""
    require_matplotlib()
    if events not in (True, False, "annotate", None):
        raise ParameterError(f"plot(events={events!r}): events is True (lines at the mode changes), "
                             f"'annotate' (lines labelled with device and transition) or False")
    chosen = names is None
    if chosen:
        names = default_signals(res) or [n for n in res.names if n.endswith((".w", ".v"))][:MAX_DEFAULT_PER_AXIS]
    elif isinstance(names, str):
        names = [names]
    names = list(names)
    for n in names:                      # unknown names: the result's own message, before any drawing
        res[n]
    if isinstance(units, str) and units.upper() == "SI":
        units = None
    # group the signals by the unit they are shown in, in order of first appearance
    groups: dict = {}
    for n in names:
        shown = res.display_unit(n, units)
        groups.setdefault(shown, []).append(n)
    hidden = {}
    if chosen:
        for u, ns in groups.items():
            if len(ns) > MAX_DEFAULT_PER_AXIS:
                hidden[u] = ns[MAX_DEFAULT_PER_AXIS:]
                groups[u] = ns[:MAX_DEFAULT_PER_AXIS]
    if modes is None:
        strips = mode_devices(res) if ax is None else []
        if len(strips) > 8:              # many devices: only those whose mode changed
            changed = {ev.component for ev in res.events if ev.kind == "mode"}
            strips = [d for d in strips if d in changed][:8]
    elif modes is False:
        strips = []
    else:
        strips = [modes] if isinstance(modes, str) else list(modes)
        for d in strips:
            res[f"{d}.mode"]
    if ax is not None:
        _draw_signals(res, ax, names, units, logy)
        ax.set_ylabel(_axis_label(res, names, units))
        _draw_events(res, [ax], events, top=ax)
        ax.set_xlabel("time [s]")
        ax.set_title(title or res.model_name)
        if path is not None:
            save_figure(ax.figure, path, "res.plot")
        return ax

    n_ax, n_strip = len(groups), len(strips)
    heights = [3.0] * n_ax + [0.42] * n_strip
    size = figsize or (10.0, sum(heights) + 0.9)
    if path is not None:
        fig = _pyplot_free_figure(size)
    else:
        import matplotlib.pyplot as plt
        fig = plt.figure(figsize=size)
    axes = fig.subplots(n_ax + n_strip, 1, sharex=True, squeeze=False,
                        gridspec_kw={"height_ratios": heights, "hspace": 0.12})[:, 0]
    for a, (u, ns) in zip(axes, groups.items()):
        _draw_signals(res, a, ns, units, logy, more=hidden.get(u))
        a.set_ylabel(_axis_label(res, ns, units))
    for a, dev in zip(axes[n_ax:], strips):
        _draw_mode_strip(res, a, dev)
    if n_strip:
        _mode_legend(res, axes[-1], strips)
    _draw_events(res, list(axes[:n_ax]) + list(axes[n_ax:]), events, top=axes[0], bottom=axes[-1])
    axes[-1].set_xlabel("time [s]")
    axes[-1].set_xlim(float(res.t[0]), float(res.t[-1]) if len(res.t) else 1.0)
    head = title or res.model_name
    # above the event labels when there are any (they sit just over the top axis)
    axes[0].set_title(head, loc="left", fontsize=11, pad=14 if events == "annotate" and res.events else 6)
    fig.align_ylabels(axes)
    if path is not None:
        save_figure(fig, path, "res.plot")
    return fig


def _axis_label(res, names, units) -> str:
    """``speed [rpm]``: the quantity and the unit shown; several, joined, when one axis holds more."""
    found = []
    for n in names:
        si, shown = res.unit(n), res.display_unit(n, units)
        what = units_mod.QUANTITIES.get(si or "", "value")
        text = f"{what} [{shown}]" if shown and shown != "1" else (what if shown else "value (unit unknown)")
        if text not in found:
            found.append(text)
    return ", ".join(found)


def _draw_signals(res, ax, names, units, logy, more=None):
    for n in names:
        unit = res.display_unit(n, units)
        y = res.get(n, unit=unit) if unit != res.unit(n) else res[n]
        note = ""
        if logy:
            y, note = _log_note(np.asarray(y, float))
        ax.plot(res.t, y, label=n + note, lw=1.3)
    if logy:
        ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if more:                             # the default selection left signals out: say which, in the legend
        from matplotlib.lines import Line2D
        handles.append(Line2D([], [], ls="none"))
        labels.append(f"+{len(more)} more, e.g. {', '.join(more[:2])}\n(pass names=[...] to choose)")
    ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False,
              borderaxespad=0.0)


def _draw_mode_strip(res, ax, dev):
    t = res.t
    span = float(t[-1] - t[0]) if len(t) > 1 else 1.0
    for t0, t1, code in _segments(t, res[f"{dev}.mode"]):
        ax.axvspan(t0, t1, color=MODE_COLOURS.get(code, "#999999"), lw=0)
        if (t1 - t0) > 0.07 * span:
            ax.text((t0 + t1) / 2, 0.5, MODE_NAMES.get(code, str(code)), ha="center", va="center", fontsize=7.5,
                    color="white" if code in (-1, 0) else "black")
    ax.set_ylim(0, 1)
    ax.set_yticks([])
    ax.set_ylabel(dev, rotation=0, ha="right", va="center", fontsize=8)


def _mode_legend(res, ax, strips):
    from matplotlib.patches import Patch
    codes = sorted({int(c) for d in strips for c in np.unique(np.round(res[f"{d}.mode"]))})
    handles = [Patch(color=MODE_COLOURS.get(c, "#999999"), label=MODE_NAMES.get(c, str(c))) for c in codes]
    ax.legend(handles=handles, title="mode", loc="lower left", bbox_to_anchor=(1.01, 0.0), fontsize=8,
              title_fontsize=8, frameon=False, borderaxespad=0.0)


def _draw_events(res, axes, events, top, bottom=None):
    """Mode changes as vertical lines; with ``"annotate"`` numbered at the top of ``top`` and listed (number,
    time, device, transition) under ``bottom``: numbers do not collide where labels would."""
    if not events or not res.events:
        return
    groups = sorted(_event_groups(res.events), key=lambda g: g[0])
    for a in axes:
        for t, _ in groups:
            a.axvline(t, color="0.45", lw=0.6, ls=":", zorder=0.5)
    if events != "annotate":
        return
    import matplotlib.transforms as mtransforms
    shown = groups[:MAX_EVENT_LABELS]
    span = float(res.t[-1] - res.t[0]) if len(res.t) > 1 else 1.0
    trans = mtransforms.blended_transform_factory(top.transData, top.transAxes)
    # numbers whose labels would touch share one label ("3,4"): a character of the 7.5 pt bold label is
    # about 5 pt wide, the axes' width in points converts that to time
    fig = top.figure
    width_pt = max(top.get_position().width * fig.get_figwidth() * 72.0, 1.0)
    char_t = 5.0 / width_pt * span
    clusters: list = [(t, [k]) for k, (t, _) in enumerate(shown, start=1)]
    merged = True
    while merged and len(clusters) > 1:     # at most one merge less per pass: bounded by the number of labels
        merged = False
        for i in range(len(clusters) - 1):
            (t1, k1), (t2, k2) = clusters[i], clusters[i + 1]
            width = 0.5 * (len(",".join(map(str, k1))) + len(",".join(map(str, k2))) + 2) * char_t
            if t2 - t1 < max(0.015 * span, width):
                clusters[i:i + 2] = [(t1, k1 + k2)]
                merged = True
                break
    for t, ks in clusters:
        top.text(t, 1.01, ",".join(map(str, ks)), transform=trans, fontsize=7.5, ha="center", va="bottom",
                 color="0.15", fontweight="bold")
    lines = [f"{k:>2}  t = {t:.4f} s  {text}" for k, (t, text) in enumerate(shown, start=1)]
    if len(groups) > MAX_EVENT_LABELS:
        lines.append(f"    ... {len(groups) - MAX_EVENT_LABELS} more mode changes (res.events lists all)")
    where = bottom if bottom is not None else top
    # two columns when the list is long and its longest line fits in half the axes' width (a monospace
    # character of 7.5 pt is 4.5 pt wide); one otherwise, so that long device names never run into the next column
    col_pt = 0.5 * max(where.get_position().width * fig.get_figwidth() * 72.0, 1.0)
    fits = max(len(line) for line in lines) * 4.6 < col_pt - 6.0
    half = (len(lines) + 1) // 2 if (len(lines) > 6 and fits) else len(lines)
    cols = [lines[:half], lines[half:]] if half < len(lines) else [lines]
    for j, col in enumerate(cols):
        where.annotate("\n".join(col), xy=(0.5 * j, 0.0), xycoords="axes fraction", xytext=(0, -34),
                       textcoords="offset points", fontsize=7.5, va="top", ha="left", family="monospace",
                       color="0.15")
