"""The study table: one row per run (run id, parameters, outputs, status, error, wall time).

A pandas DataFrame when pandas is installed, else a ``SweepTable`` (a list of
row dicts with ``columns``, ``attrs`` and ``to_csv``). Both carry ``attrs``:
executor, workers, runs computed and skipped (found in ``out``), failures,
elapsed wall time [s], throughput [runs/s] and whether the study was
interrupted.
"""

from __future__ import annotations

import csv

from .sampling import RESERVED


class SweepTable(list):
    """Rows of a study as dicts (pandas is not installed)."""

    def __init__(self, rows, columns):
        super().__init__(rows)
        self.columns = list(columns)
        self.attrs: dict = {}

    def column(self, name) -> list:
        return [r.get(name) for r in self]

    def to_csv(self, path) -> None:
        from ..io import writing
        with writing(path, "sweep table to_csv"), open(path, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=self.columns)
            w.writeheader()
            for r in self:
                w.writerow({k: "" if r.get(k) is None else (repr(r[k]) if isinstance(r[k], float) else r[k])
                            for k in self.columns})

    def __repr__(self):
        return f"<SweepTable: {len(self)} runs, columns {self.columns}>"


def make_table(rows: list[dict], param_names: list[str], attrs: dict):
    """Rows sorted by run id, columns ``run_id, parameters, outputs, status, error, wall_time``."""
    rows = sorted(rows, key=lambda r: r["run_id"])
    outputs = list(dict.fromkeys(k for r in rows for k in r if k not in RESERVED and k not in param_names))
    columns = ["run_id"] + list(param_names) + outputs + ["status", "error", "wall_time"]
    try:
        import pandas as pd
    except ImportError:
        table = SweepTable([{k: r.get(k) for k in columns} for r in rows], columns)
    else:
        table = pd.DataFrame([{k: r.get(k) for k in columns} for r in rows], columns=columns)
    table.attrs.update(attrs)
    return table
