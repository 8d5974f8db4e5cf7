"""The cutoff of the built rows: when the answer moves further than the cutoff proves, the rows
of a wider cutoff are checked at the answer (with room for the exact projection) before the QP
is solved again with them."""
from __future__ import annotations

import importlib

import numpy as np
import pytest
from scenes import hex_jam
from test_certified import random_jam
from test_projection import jam_steps, reference

import sweep_core as sc

project_module = importlib.import_module("sweep_core.numerics.projection.project")
JAMS = [hex_jam(6, 6), random_jam(0), random_jam(1)]
IDS = ["hex36", "rand0", "rand1"]


def shrunk_cutoff(monkeypatch, factor: float) -> None:
    real = project_module.first_cutoff
    monkeypatch.setattr(project_module, "first_cutoff",
                        lambda q, pred, r1: factor * real(q, pred, r1))


@pytest.mark.parametrize("spec", JAMS, ids=IDS)
def test_a_short_cutoff_whose_wider_rows_hold_is_not_solved_again(spec, monkeypatch):
    """First cutoff 0.3 times the usual (about one step's motion): the answers move further
    than half of it, so the cutoff test alone cannot prove them. Where the wider rows hold at
    the answer it is kept, solved once (it was solved again before the wider rows were
    checked); where one breaks, the QP is solved again. Either way the answer is within its
    bound of the exact projection over every row."""
    shrunk_cutoff(monkeypatch, 0.3)
    kept = 0
    for scene, t1, q, pred, proj in jam_steps(spec, seed=3, steps=6, opts=sc.SolverOptions()):
        moved = float(np.sqrt(((proj.y - q) ** 2).sum(axis=1)).max())
        cut = 0.3 * project_module.first_cutoff(q, pred, scene.radii(t1))
        kept += 2.0 * (moved + proj.bound) > cut and proj.solves == 1
        want = reference(scene, t1, q, pred)
        assert float(np.sqrt(((proj.y - want) ** 2).sum())) <= proj.bound + 1e-12
    assert kept >= 3


def test_a_cutoff_that_misses_broken_rows_is_solved_again(monkeypatch):
    """First cutoff 1e-6 times the usual on a pressed lattice (neighbours a little apart): rows
    that the answer breaks are left out, the wider rows do not hold at it, and the QP is solved
    again with them; the answer is the exact projection over every row, within its bound."""
    shrunk_cutoff(monkeypatch, 1e-6)
    again = 0
    for scene, t1, q, pred, proj in jam_steps(hex_jam(6, 6), seed=3, steps=4,
                                              opts=sc.SolverOptions()):
        again += proj.solves >= 2
        want = reference(scene, t1, q, pred)
        assert float(np.sqrt(((proj.y - want) ** 2).sum())) <= proj.bound + 1e-12
        assert proj.bound <= 1e-6
    assert again >= 3
