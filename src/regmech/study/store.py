"""The study's output file: rows written as they arrive, read back to resume.

CSV: the header, then one line per finished run, appended and flushed batch
by batch, so a crash loses at most the batch in flight. Floats are written
with ``repr`` (shortest exact form), so values read back are bit-identical.
When a run brings an output column that the header lacks (the first
successful run after failures, or an outputs function that returns other
names), the file is rewritten with the wider header: written to a temporary
file, then renamed over the old one, so the file on disk is always complete.

Parquet (path ending in ``.parquet``, needs pyarrow): a Parquet file is
unreadable until its footer is written, so every batch rewrites the whole
file the same atomic way (a study table is small: thousands of rows).

At the end the file is rewritten once more, sorted by run id.
"""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path

from ..errors import ParameterError
from .sampling import RESERVED

FINISHED = ("ok", "failed")


class ResultStore:
    """Rows of one study on disk (``path``) and in memory (``rows``: run id -> row)."""

    def __init__(self, path):
        self.path = Path(path)
        self.parquet = self.path.suffix.lower() == ".parquet"
        if self.parquet:
            try:
                import pyarrow  # noqa: F401
            except ImportError:
                raise ParameterError(f"sweep: out={str(self.path)!r} asks for Parquet, which needs pyarrow "
                                     f"(pip install pyarrow); or give a .csv path") from None
        self.rows: dict = {}
        self.columns: list[str] = []
        self._fh = None
        self._writer = None

    # -- resume ------------------------------------------------------------------------------
    def load(self) -> dict:
        """Rows already in the file: run id -> row with the values as stored (CSV: text)."""
        if not self.path.exists() or self.path.stat().st_size == 0:
            return {}
        if self.parquet:
            import pyarrow.parquet as pq
            table = pq.read_table(self.path)
            columns, records = list(table.column_names), table.to_pylist()
        else:
            with open(self.path, newline="") as fh:
                reader = csv.DictReader(fh)
                columns, records = list(reader.fieldnames or []), list(reader)
        if "run_id" not in columns or "status" not in columns:
            raise ParameterError(f"sweep: {self.path} exists but is not a study table (no run_id/status column); "
                                 f"choose another out path or delete the file")
        self.columns = columns
        stored = {}
        for rec in records:
            run_id = _parse(rec.get("run_id"))
            if not isinstance(run_id, int) or rec.get("status") not in FINISHED:
                continue             # a line cut short by a crash: that run is computed again
            # kept as stored (CSV: text) for matching parameters; parse_row() gives the values
            stored[run_id] = rec
            self.rows[run_id] = parse_row(rec)
        if not self.parquet:
            self.rewrite(sort=True)  # a clean file (no half line from a crash) before appending
        return stored

    # -- writing ---------------------------------------------------------------------------------
    def add(self, rows: list[dict]) -> None:
        """Record finished rows (in memory and on disk)."""
        new_cols = [k for r in rows for k in r if k not in self.columns]
        for r in rows:
            self.rows[r["run_id"]] = r
        if new_cols or self.parquet or not self.path.exists():
            self.columns += list(dict.fromkeys(new_cols))
            self.rewrite()
            return
        self._append(rows)

    def _append(self, rows: list[dict]) -> None:
        if self._fh is None:
            self._fh = open(self.path, "a", newline="")
            self._writer = csv.DictWriter(self._fh, fieldnames=self.columns)
        for r in rows:
            self._writer.writerow({k: _format(r.get(k)) for k in self.columns})
        self._fh.flush()

    def rewrite(self, sort: bool = False) -> None:
        """Write every row to a temporary file, then rename it over ``path`` (atomic)."""
        self.close()
        self.columns = _ordered(self.columns)
        rows = [self.rows[k] for k in sorted(self.rows)] if sort else list(self.rows.values())
        tmp = self.path.with_name(self.path.name + ".tmp")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.parquet:
            import pyarrow as pa
            import pyarrow.parquet as pq
            table = pa.Table.from_pylist([{k: r.get(k) for k in self.columns} for r in rows])
            pq.write_table(table, tmp)
        else:
            with open(tmp, "w", newline="") as fh:
                w = csv.DictWriter(fh, fieldnames=self.columns)
                w.writeheader()
                for r in rows:
                    w.writerow({k: _format(r.get(k)) for k in self.columns})
        os.replace(tmp, self.path)

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()
            self._fh = self._writer = None


def same_parameters(stored: dict, params: dict) -> bool:
    """A stored row belongs to this run when every parameter value matches (numbers numerically)."""
    for name, value in params.items():
        if name not in stored:
            return False
        a, b = stored[name], value
        if isinstance(b, (int, float)) and not isinstance(b, bool):
            a = _parse(a)
            if isinstance(a, bool) or not isinstance(a, (int, float)):
                return False
            if not (a == b or (math.isnan(a) and math.isnan(b))):
                return False
        elif str(a) != str(b):       # text, bools and anything else: as written
            return False
    return True


def parse_row(stored: dict) -> dict:
    """A stored row's values as Python values (numbers, None for empty cells, text)."""
    return {k: _parse(v) for k, v in stored.items()}


def _ordered(columns: list[str]) -> list[str]:
    # run_id first; status, error, wall_time last; parameters and outputs in arrival order between
    middle = [c for c in columns if c not in RESERVED]
    return ["run_id"] + middle + ["status", "error", "wall_time"]


def _format(v):
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    return v


def _parse(v):
    """A stored value -> Python: numbers as int/float, empty -> None, other text as is."""
    if not isinstance(v, str):
        return v
    if v == "":
        return None
    try:
        return int(v)
    except ValueError:
        pass
    try:
        return float(v)
    except ValueError:
        return v
