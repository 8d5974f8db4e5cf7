"""Plain text for people: the aligned tables the ``sweep`` commands print (``sweep scenes``,
the accuracy study's tables), one printer so that every table lines up the same way."""
from __future__ import annotations

from collections.abc import Iterable, Sequence

__all__ = ["text_table"]


def text_table(header: Sequence[str], rows: Iterable[Sequence[str]], align: str,
               widths: Sequence[int] = (), gaps: str | Sequence[str] = "  ",
               rule: bool = False) -> str:
    """The lines of a table of text cells, joined by newlines (no final newline).

    ``align`` has one character per column, ``<`` (left) or ``>`` (right). Every column is as
    wide as its widest cell, its header or ``widths[k]`` (a minimum, in characters; missing or
    0: none), whichever is widest, so that a long cell moves its column's neighbours instead of
    running into them. ``gaps`` separate the columns: one string for all, or one per pair of
    neighbours (len(header) - 1). A left-aligned last column is not padded. ``rule`` puts a
    line of ``-`` as long as the header line under it.

    Raises ValueError when a row, ``align``, ``widths`` or ``gaps`` does not match the header.
    """
    n = len(header)
    body = [list(r) for r in rows]
    seps = [gaps] * (n - 1) if isinstance(gaps, str) else list(gaps)
    if len(align) != n or set(align) - {"<", ">"} or len(widths) > n or len(seps) != n - 1:
        raise ValueError(f"text_table: {n} columns, align {align!r}, widths {list(widths)}, "
                         f"{len(seps)} gaps")
    for r in body:
        if len(r) != n:
            raise ValueError(f"text_table: a row of {len(r)} cells for {n} columns: {r}")
    width = [max([len(header[k]), *(len(r[k]) for r in body),
                  widths[k] if k < len(widths) else 0]) for k in range(n)]

    def line(cells: Sequence[str]) -> str:
        out = []
        for k, cell in enumerate(cells):
            if align[k] == ">":
                out.append(cell.rjust(width[k]))
            else:
                out.append(cell if k == n - 1 else cell.ljust(width[k]))
            if k < n - 1:
                out.append(seps[k])
        return "".join(out)

    head = line(header)
    lines = [head, "-" * len(head)] if rule else [head]
    lines += [line(r) for r in body]
    return "\n".join(lines)
