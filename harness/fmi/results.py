"""A table of values over time, addressed by column name: what simulations return."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass
class TimeTable:
    columns: list[str]
    values: np.ndarray  # one row per communication point, the first column is time

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.values[:, self.columns.index(name)]
        except ValueError:
            raise KeyError(f"no column {name!r}; columns are {', '.join(self.columns)}") from None

    @property
    def time(self) -> np.ndarray:
        return self.values[:, 0]

    def write_csv(self, path: str | Path) -> None:
        """Through a temporary file renamed at the end (harness/output.py)."""
        from harness.output import csv_header, written
        with written(Path(path)) as sink:
            sink.write(csv_header(self.columns))
            np.savetxt(sink, self.values, delimiter=",", fmt="%.17g")


def rows_on_grid(times: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Indices of the last row at each grid time: a Model Exchange run under fmpy records a row before and
    after each event besides the output grid."""
    rows = [np.flatnonzero(np.abs(times - t) <= 1e-9 * max(1.0, abs(t))) for t in grid]
    missing = [t for t, found in zip(grid, rows) if not len(found)]
    if missing:
        raise ValueError(f"no row at t = {missing[0]:g}")
    return np.array([found[-1] for found in rows])
