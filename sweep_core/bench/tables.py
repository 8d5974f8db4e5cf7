"""CSV output shared by the bench studies."""
from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

from sweep_core.io.outputs import replacing


def write_csv(path: Path, rows: list[dict], columns: Sequence[str] | None = None) -> None:
    """The rows as a CSV with a header: ``columns``, or the keys of the first row, written whole
    or not at all (:func:`~sweep_core.io.outputs.replacing`). Nothing is written for no rows
    without columns."""
    if columns is None and not rows:
        return
    with replacing(path, other="--csv OTHER.csv") as tmp, Path(tmp).open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(columns or rows[0]))
        w.writeheader()
        w.writerows(rows)


def table_row(row: dict, columns: Sequence[str], widths: Sequence[int]) -> str:
    """One printed row of a study's table: each column right-aligned in its width, floats
    with three decimals."""
    return " ".join(f"{row[c]:>{w}.3f}" if isinstance(row[c], float) else f"{row[c]:>{w}}"
                    for c, w in zip(columns, widths))
