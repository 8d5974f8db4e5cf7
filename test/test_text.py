"""The one text-table printer (``sweep_core.text.text_table``) and the tables printed with it:
columns stay aligned whatever their cells' lengths, and the accuracy study's tables keep
their layout."""
from __future__ import annotations

import math

import pytest

from sweep_core.bench.accuracy import Measurement, Slope
from sweep_core.bench.accuracy_report import format_features, format_slopes, format_table
from sweep_core.text import text_table


def test_columns_are_as_wide_as_their_widest_cell() -> None:
    out = text_table(("name", "n", "what"), [("a", "1", "first"), ("a much longer", "12345", "x")],
                     "<><", widths=(0, 3))
    assert out.split("\n") == [
        "name               n  what",
        "a                  1  first",
        "a much longer  12345  x"]
    # a left-aligned last column is not padded; a rule as long as the header
    out = text_table(("k", "v"), [("a", "1")], "<>", gaps=" | ", rule=True)
    assert out.split("\n") == ["k | v", "-----", "a | 1"]


def test_bad_shapes_are_refused() -> None:
    with pytest.raises(ValueError, match="a row of 1 cells for 2 columns"):
        text_table(("a", "b"), [("x",)], "<<")
    with pytest.raises(ValueError, match="align"):
        text_table(("a", "b"), [], "<")
    with pytest.raises(ValueError, match="gaps"):
        text_table(("a", "b", "c"), [], "<<<", gaps=(" ",))


def measurement(problem: str = "rbm_wall", tol: str = "certified:1e-12") -> Measurement:
    return Measurement(problem, "mean", "projected_euler", 0.08, tol, 1.234e-3, 2.1e-4, 0.0123,
                       1.0, 100)


def slope(problem: str = "rbm_wall", tol: str = "certified:1e-12",
          value: float = 0.98) -> Slope:
    return Slope(problem, "mean", "projected_euler", tol, value, 0.91, 1.05, 4, 6, "a note")


def test_the_accuracy_tables_keep_their_layout() -> None:
    """Ordinary cells are laid out as the study has always printed them."""
    assert format_table([measurement()]).split("\n") == [
        "problem     metric scheme           tol                      dt      error     +-95%"
        "  wall s/s   sub",
        "-" * 100,
        "rbm_wall    mean   projected_euler  certified:1e-12        0.08  1.234e-03  2.10e-04"
        "    0.0123  1.00"]
    assert format_slopes([slope(), slope(value=math.nan)]).split("\n") == [
        "problem     metric scheme           tol                slope  95% interval     note",
        "-" * 83,
        "rbm_wall    mean   projected_euler  certified:1e-12     0.98  [0.91, 1.05]     a note",
        "rbm_wall    mean   projected_euler  certified:1e-12        -                   a note"]
    assert format_features([{"scene": "bare", "ms_per_step": 1.2345, "ratio_to_none": 1.0,
                             "contacts": 12}]).split("\n") == [
        "free-flow crowd, 120 agents     ms/step  x none  contacts",
        "-" * 57,
        "bare                              1.234    1.00        12"]


def starts(line: str, cells: list[str]) -> list[int]:
    """Where each of cells begins in line, searched left to right."""
    out, at = [], 0
    for cell in cells:
        at = line.index(cell, at)
        out.append(at)
        at += len(cell)
    return out


def test_long_cells_move_the_columns_after_them() -> None:
    """A problem name or a tolerance longer than its column used to run into the next one
    (the columns after it shifted on that line only); now the column widens on every line."""
    long = measurement("a_very_long_problem", "certified:1.5e-12 (loose)")
    lines = format_table([measurement(), long]).split("\n")
    head = lines[0].split()
    left = starts(lines[0], head[:4])
    assert starts(lines[2], ["rbm_wall", "mean", "projected_euler", "certified:1e-12"]) == left
    assert starts(lines[3], ["a_very_long_problem", "mean", "projected_euler",
                             "certified:1.5e-12 (loose)"]) == left
    ends = [lines[0].index(h) + len(h) for h in ("dt", "error", "+-95%", "s/s", "sub")]
    for line in lines[2:]:
        cells = line.split()[-5:]
        assert [line.rindex(c) + len(c) for c in cells] == ends, line
    assert len(lines[1]) == len(lines[0]) == len(lines[2])

    lines = format_slopes([slope(), slope("a_very_long_problem",
                                          "certified:1.5e-12 (loose)")]).split("\n")
    note = lines[0].index("note")
    assert all(line.index("a note") == note for line in lines[2:])
    lines = format_features([
        {"scene": "bare", "ms_per_step": 1.0, "ratio_to_none": 1.0, "contacts": 1},
        {"scene": "radii (sine) + avoid + headway + groups", "ms_per_step": 2.0,
         "ratio_to_none": 2.0, "contacts": 2}]).split("\n")
    assert {len(line) for line in lines} == {len(lines[0])}
