"""Plots of modes and responses (matplotlib, optional).

Figures are built with ``matplotlib.figure.Figure`` and the Agg canvas, so
writing files never touches pyplot's global state or needs a display.
Each function returns the figure and writes it to ``path`` when given.
"""

from __future__ import annotations

import numpy as np

from ..errors import RegmechError


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
        fig.savefig(path, dpi=120, bbox_inches="tight")
    return fig


def plot_mode_shapes(result, path=None, n_modes: int = 6, include_rigid: bool = False):
    """Mode shapes (max = 1) over the masses, one line per mode."""
    table = result.table(normalize=True)
    rows = [i for i in range(len(result.omega2)) if include_rigid or not result.rigid[i]][:n_modes]
    fig, axes = _figure(figsize=(max(6.0, 0.6 * len(table.columns) + 3), 5))
    ax = axes[0, 0]
    x = np.arange(len(table.columns))
    for i in rows:
        ax.plot(x, table.data[i], marker="o", label=f"mode {i + 1}: {result.frequencies_hz[i]:.4g} Hz")
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xticks(x)
    ax.set_xticklabels(table.columns, rotation=45 if len(x) > 6 else 0, ha="right" if len(x) > 6 else "center")
    ax.set_ylabel("relative displacement (max = 1)")
    ax.set_title(f"{result.lin.compiled.model.name}: mode shapes")
    if rows:
        ax.legend(fontsize=8)
    return _save(fig, path)


def plot_frequency_response(resp, path=None, axes=None):
    """Amplitude (log) and phase of every output against frequency."""
    if axes is None:
        fig, ax = _figure(2, 1, figsize=(9, 6), sharex=True)
        ax_a, ax_p = ax[0, 0], ax[1, 0]
    else:
        ax_a, ax_p = axes
        fig = ax_a.figure
    for j, name in enumerate(resp.outputs):
        amp = np.abs(resp.values[:, j])
        ax_a.semilogy(resp.freqs_hz, np.where(amp > 0, amp, np.nan), label=name)
        ax_p.plot(resp.freqs_hz, np.degrees(np.unwrap(np.angle(resp.values[:, j]))), label=name)
    src = ", ".join(resp.inputs) if resp.inputs else "input"
    ax_a.set_ylabel(f"amplitude per unit {src}")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    ax_a.set_title("harmonic response")
    ax_a.legend(fontsize=8)
    return _save(fig, path)


def plot_multi_harmonic(resp, path=None):
    """Amplitude of each harmonic's contribution and the superposed steady state."""
    fig, ax = _figure(2, 1, figsize=(9, 7))
    ax_b, ax_t = ax[0, 0], ax[1, 0]
    width = 0.8 / max(1, len(resp.outputs))
    idx = np.arange(len(resp.freqs_hz))
    for j, name in enumerate(resp.outputs):
        ax_b.bar(idx + j * width, np.abs(resp.values[:, j]), width, label=name)
    ax_b.set_xticks(idx + width * (len(resp.outputs) - 1) / 2)
    ax_b.set_xticklabels([f"{f:.3g} Hz" for f in resp.freqs_hz])
    ax_b.set_ylabel("amplitude")
    ax_b.legend(fontsize=8)
    t = resp._grid()
    y = resp.time_series(t)
    for j, name in enumerate(resp.outputs):
        ax_t.plot(t, y[:, j], label=name)
    ax_t.set_xlabel("t [s] (one period)")
    ax_t.set_ylabel("steady state")
    return _save(fig, path)


def plot_order_sweep(sweep, path=None):
    """Amplitude of each order and the superposed peak against speed, per output."""
    fig, ax = _figure(len(sweep.outputs), 1, figsize=(9, 3.2 * len(sweep.outputs)), sharex=True)
    for j, name in enumerate(sweep.outputs):
        a = ax[j, 0]
        for h, order in enumerate(sweep.orders):
            a.plot(sweep.speeds_hz * 60.0, sweep.amplitude[:, h, j], label=f"order {order:g}")
        a.plot(sweep.speeds_hz * 60.0, sweep.peak[:, j], "k--", label="peak (all orders)")
        a.set_ylabel(name)
        a.legend(fontsize=8)
    ax[-1, 0].set_xlabel("speed [rpm]")
    return _save(fig, path)
