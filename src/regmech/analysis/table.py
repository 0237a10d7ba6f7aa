"""A small labelled table (rows x columns of floats) that prints well and
turns into a pandas DataFrame when pandas is installed."""

from __future__ import annotations

import numpy as np

from ..errors import RegmechError


class Table:
    """``data[i, j]`` for row label ``index[i]`` and column label ``columns[j]``.

    ``table["J1"]`` is a column, ``table.row(label)`` a row; ``str(table)``
    a fixed-width text table; ``table.to_dataframe()`` a pandas DataFrame.
    """

    def __init__(self, data, index, columns, title: str = "", index_name: str = "", notes=()):
        self.data = np.asarray(data, float).reshape(len(index), len(columns))
        self.index = list(index)
        self.columns = list(columns)
        self.title = title
        self.index_name = index_name
        #: sentences printed under the table (what a row label or value means)
        self.notes = list(notes)

    @property
    def shape(self):
        return self.data.shape

    def __getitem__(self, column) -> np.ndarray:
        try:
            return self.data[:, self.columns.index(column)]
        except ValueError:
            raise KeyError(f"no column {column!r} in table '{self.title}'; columns are {self.columns}") from None

    def row(self, label) -> np.ndarray:
        try:
            return self.data[self.index.index(label)]
        except ValueError:
            raise KeyError(f"no row {label!r} in table '{self.title}'") from None

    def as_dict(self) -> dict:
        """``{row label: {column label: value}}``."""
        return {r: dict(zip(self.columns, map(float, self.data[i]))) for i, r in enumerate(self.index)}

    def to_dataframe(self):
        try:
            import pandas as pd
        except ImportError:
            raise RegmechError("Table.to_dataframe() needs pandas: pip install 'regmech[pandas]'") from None
        df = pd.DataFrame(self.data, index=self.index, columns=self.columns)
        df.index.name = self.index_name or None
        return df

    def to_csv(self, path) -> None:
        import csv

        from ..io import writing
        with writing(path, "Table.to_csv"), open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow([self.index_name or ""] + [str(c) for c in self.columns])
            for label, row in zip(self.index, self.data):
                w.writerow([label] + [repr(float(v)) for v in row])

    def __str__(self) -> str:
        cells = [[f"{v:.6g}" for v in row] for row in self.data]
        labels = [str(r) for r in self.index]
        heads = [str(c) for c in self.columns]
        w0 = max([len(self.index_name)] + [len(s) for s in labels]) if labels else len(self.index_name)
        widths = [max([len(h)] + [len(row[j]) for row in cells]) for j, h in enumerate(heads)]
        lines = [self.title] if self.title else []
        lines.append("  ".join([self.index_name.ljust(w0)] + [h.rjust(w) for h, w in zip(heads, widths)]))
        for label, row in zip(labels, cells):
            lines.append("  ".join([label.ljust(w0)] + [c.rjust(w) for c, w in zip(row, widths)]))
        lines += [f"  {n}" for n in self.notes]
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"Table({self.title!r}, {len(self.index)} x {len(self.columns)})"
