"""CSV files of result dataclasses: one row per record, empty cells for NaN."""
from __future__ import annotations

import csv
import math
import typing
from dataclasses import asdict, fields
from pathlib import Path
from typing import TypeVar

Record = TypeVar("Record")


def columns_of(kind: type) -> list[str]:
    return [f.name for f in fields(kind)]


def write_records(records: list, path: Path, columns: list[str]) -> None:
    from harness.output import written
    with written(Path(path)) as handle:
        writer = csv.DictWriter(handle, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for record in records:
            writer.writerow({k: ("" if isinstance(v, float) and math.isnan(v) else v)
                             for k, v in asdict(record).items()})


def read_records(path: Path, kind: type[Record]) -> list[Record]:
    """Rows back into `kind`; fields missing from the file keep their defaults."""
    types = typing.get_type_hints(kind)
    converters = {float: lambda text: float(text) if text else math.nan, int: int, str: str}
    with open(path, newline="") as handle:
        return [kind(**{f.name: converters[types[f.name]](row[f.name]) for f in fields(kind) if f.name in row})
                for row in csv.DictReader(handle)]
