"""Runs verification tests over seeds (on Dask, or in this process), prints one line per
test and writes the report folder: ``summary.csv`` (one row per test), ``report.md`` (the
lines and the figures) and the figures."""
from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from sweep_core.errors import SweepError
from sweep_core.io.outputs import write_text
from sweep_core.model.scene import Scene
from sweep_core.verify.base import Case, Test, Trace, Verdict, ran, simulate


def line(test: Test, verdict: Verdict, seeds: Sequence[int] = ()) -> str:
    """The printed line of a test: name, what is measured, criterion, value, notes, and for
    a FAIL the failing seeds with the conditions that failed."""
    text = (f"{test.key:<9} {verdict.status:<4}  {test.title}: {test.measures} | criterion "
            f"{test.criterion} | {verdict.spread()}")
    text += f" | {verdict.notes}" if verdict.notes else ""
    failed = verdict.failures(seeds or range(len(verdict.values)))
    return text + (f" | FAILED {failed}" if failed else "")


def judge(test: Test, mine: dict[str, list[Trace]], seeds: Sequence[int],
          quick: bool) -> Verdict:
    """A test's verdict from its traces: its judge's, then each seed with a run error fails
    with that error quoted (every case's, by name); a judge that raises fails every seed
    with its error."""
    try:
        verdict = test.judge(mine, quick)
    except Exception as err:  # noqa: BLE001 - a measurement that fails is a FAIL line
        why = f"the measurement failed: {type(err).__name__}: {str(err)[:200]}"
        verdict = Verdict([math.nan] * len(seeds), [False] * len(seeds),
                          reasons=[why] * len(seeds))
    for k in range(len(seeds)):
        for trs in mine.values():
            ok, why = ran(trs[k])
            if not ok and why not in (verdict.reasons[k:k + 1] or [""])[0]:
                verdict.fail(k, why)
    return verdict


def run_traces(tasks: Sequence[tuple[Case, int]], folder: str | None, client: Any,
               progress: Callable[[str], None] | None = None) -> list[Trace]:
    """The traces of (case, seed) tasks: on the Dask ``client`` when given, else here;
    ``progress`` is told "k of n runs done" as runs finish (at most about 20 times)."""
    tell = progress or (lambda _text: None)
    n = len(tasks)
    step = max(1, n // 20)
    if client is None:
        out = []
        for k, (case, seed) in enumerate(tasks, 1):
            out.append(simulate(case, seed, folder))
            if k % step == 0 or k == n:
                tell(f"{k} of {n} runs done")
        return out
    from distributed import as_completed

    futures = [client.submit(simulate, case, seed, folder, pure=False) for case, seed in tasks]
    index = {f.key: k for k, f in enumerate(futures)}
    results: list[Trace | None] = [None] * n
    for k, fut in enumerate(as_completed(futures), 1):
        results[index[fut.key]] = fut.result()
        if k % step == 0 or k == n:
            tell(f"{k} of {n} runs done")
    return [r for r in results if r is not None]


def verify(tests: Sequence[Test], seeds: Sequence[int], quick: bool, out: Path | None,
           folder: str | None = None, client: Any = None,
           say: Callable[[str], None] = print,
           progress: Callable[[str], None] | None = None) -> list[tuple[Test, Verdict]]:
    """Runs every case of every test with every seed, judges, prints a line per test and (when
    ``out`` is given) writes the report folder; ``progress`` hears how many runs are done.
    Returns (test, verdict) pairs."""
    if folder is not None and not Path(folder).is_dir():
        raise SweepError(f"--scenes: {folder!r} is not a folder (fix: give a folder of scene "
                         "YAML files named as the bundled ones, e.g. rimea06_corner.yaml)")
    tasks = [(case, seed) for t in tests for case in t.cases(quick) for seed in seeds]
    if folder is not None:  # a replaced scene is checked here, its error said in one line
        for name in sorted({case.scene for case, _ in tasks if case.inline is None}):
            path = Path(folder) / f"{name}.yaml"
            if path.exists() or path.is_symlink():  # a FIFO or folder of that name: refused
                Scene.from_yaml(path)
    traces = run_traces(tasks, folder, client, progress)
    by_test: dict[str, dict[str, list[Trace]]] = {}
    k = 0
    for t in tests:
        mine: dict[str, list[Trace]] = {}
        for case in t.cases(quick):
            for _ in seeds:
                mine.setdefault(case.label, []).append(traces[k])
                k += 1
        by_test[t.key] = mine
    results = []
    figures: dict[str, list[Path]] = {}
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    for t in tests:
        mine = by_test[t.key]
        errors = any(tr.error for trs in mine.values() for tr in trs)
        verdict = judge(t, mine, seeds, quick)
        results.append((t, verdict))
        say(line(t, verdict, seeds))
        if out is not None and t.plot is not None and not errors:
            figures[t.key] = t.plot(mine, verdict, out)
    if out is not None:
        write_report(results, figures, seeds, quick, out)
    return results


def write_report(results: list[tuple[Test, Verdict]], figures: dict[str, list[Path]],
                 seeds: Sequence[int], quick: bool, out: Path) -> None:
    """``summary.csv`` and ``report.md`` in ``out``."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["test", "status", "measures", "criterion", "mean", "min", "max", "values",
                "notes", "failed"])
    for t, v in results:
        vals = [x for x in v.values if math.isfinite(x)]
        w.writerow([t.key, v.status, t.measures, t.criterion,
                    f"{sum(vals) / len(vals):.6g}" if vals else "",
                    f"{min(vals):.6g}" if vals else "", f"{max(vals):.6g}" if vals else "",
                    " ".join(f"{x:.6g}" for x in v.values), v.notes, v.failures(seeds)])
    write_text(out / "summary.csv", buf.getvalue())
    md = [f"# sweep verify{' --quick' if quick else ''}", "",
          f"Seeds: {', '.join(str(s) for s in seeds)}.", "", "```"]
    md += [line(t, v, seeds) for t, v in results] + ["```", ""]
    for t, _ in results:
        md += [f"## {t.title}", "", f"Source: {t.source}.", ""]
        for path in figures.get(t.key, []):
            md.append(f"![{path.stem}]({os.path.basename(path)})")
        md.append("")
    write_text(out / "report.md", "\n".join(md))
