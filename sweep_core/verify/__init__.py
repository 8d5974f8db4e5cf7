"""``sweep verify``: the RiMEA tests that apply to a 2D simulator, and the validation against
experimental data, each over several seeds.

``TESTS`` is the registry (command-line name -> :class:`~sweep_core.verify.base.Test`); a test
lists its runs (cases: a bundled scene of ``sweep_core/scenes/rimea/`` with changes), judges
their traces and draws its figures. :func:`~sweep_core.verify.runner.verify` runs them (on a
Dask client, or in this process) and writes the report. docs/validation.md says what each
test measures, where its numbers come from, and the results of the full run.
"""
from __future__ import annotations

from sweep_core.verify import crowds, diagrams, gallery, rooms, single_file
from sweep_core.verify.base import Test

#: name -> test, in the order they run and print
TESTS: dict[str, Test] = {t.key: t for t in (
    rooms.TEST_1, diagrams.TEST_4, crowds.TEST_7, rooms.TEST_6, crowds.TEST_9, rooms.TEST_10, rooms.TEST_11,
    rooms.TEST_12, crowds.TEST_15, diagrams.TEST_BOTTLENECK, single_file.TEST_16,
    gallery.TEST_GALLERY)}
