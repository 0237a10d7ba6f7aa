"""Ready-made output functions of a study: signal summaries and a scene's defaults.

``SignalSummary(["J1.w", "clutch1.tau"])`` reports, per signal, the final
value (``"J1.w.final"``) and the largest absolute value over the run
(``"J1.w.max_abs"``); ``final=``/``peak=`` pick one of the two per signal.
It is a class, not a closure, so it pickles to worker processes.
"""

from __future__ import annotations

import numpy as np


class SignalSummary:
    """Outputs function: final values and peaks ``max |x(t)|`` of named signals."""

    def __init__(self, names=(), *, final=(), peak=()):
        names = [names] if isinstance(names, str) else list(names)
        self.final = list(dict.fromkeys(names + list(final)))
        self.peak = list(dict.fromkeys(names + list(peak)))

    def columns(self) -> list[str]:
        return [f"{n}.final" for n in self.final] + [f"{n}.max_abs" for n in self.peak]

    def __call__(self, res) -> dict:
        out = {f"{n}.final": res.final(n) for n in self.final}
        out.update({f"{n}.max_abs": float(np.max(np.abs(res[n]))) for n in self.peak})
        return out

    def __repr__(self):
        return f"SignalSummary(final={self.final}, peak={self.peak})"


def scene_defaults(model) -> SignalSummary:
    """Default outputs of a scene: the final speed of every body (``<body>.w`` or ``.v``) and the
    peak torque or force (``<device>.tau`` or ``.f``) of every device that is not a source
    (a source's torque is an input of the study, not an outcome)."""
    final, peak = [], []
    for comp in model:
        if comp.role == "body":
            final.append(f"{comp.name}.{comp.var_names()[1]}")
        elif comp.role == "device" and not getattr(comp, "is_source", False):
            force = comp.rel_names.get(comp.domain, (None,) * 4)[3]
            if force:
                peak.append(f"{comp.name}.{force}")
    return SignalSummary(final=final, peak=peak)
