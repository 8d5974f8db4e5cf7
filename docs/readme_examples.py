"""The example outputs quoted in README.md and docs/*.md, regenerated from the commands they
quote.

Each example is a block between ``<!-- example: NAME -->`` and ``<!-- /example -->``, once in
README.md or one page of docs/; this script runs the seeded commands behind it and writes the
block (default) or, with ``--check``, exits 1 with a diff when a file differs from a fresh run.
The test suite runs ``--check`` (test/test_readme.py), so a change of the engine that changes
a quoted number fails CI until the files are regenerated:

    python docs/readme_examples.py            # rewrite the blocks
    python docs/readme_examples.py --check    # verify them
"""
from __future__ import annotations

import argparse
import difflib
import json
import re
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
#: the files whose example blocks are generated
FILES = (README, *sorted((REPO / "docs").glob("*.md")))
BLOCK = re.compile(r"(<!-- example: (?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- /example -->)", re.S)

#: the lines of ``sweep analyze``'s summary the README quotes
ANALYZE_KEYS = ("status", "frames", "duration_s", "min_gap.min_m", "min_gap.between",
                "touching.mean", "reaction.pressure_mean_m_per_s", "speed.window_s",
                "speed.mean_m_per_s", "speed.p50_m_per_s", "flow.net", "flow.per_s",
                "flow.steady_per_s", "flow.reference.flow_per_s",
                "flow.reference.departure_pct", "arrivals.arrived", "density.max_per_m2")
#: the shorter summary of the README's tour (the same run)
TOUR_KEYS = ("status", "min_gap.min_m", "touching.mean", "speed.mean_m_per_s", "flow.net",
             "flow.per_s", "flow.reference.departure_pct", "arrivals.arrived",
             "density.max_per_m2")


def sweep(*args: str, cwd: Path) -> str:
    """Run ``sweep ARGS`` with this interpreter in cwd; its standard output."""
    done = subprocess.run([sys.executable, "-m", "sweep_core.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        raise SystemExit(f"sweep {' '.join(args)} failed ({done.returncode}):\n{done.stderr}")
    return done.stdout


def _door_analysis(work: Path) -> dict:
    """``sweep analyze --json`` of the bundled scene recorded every 5 steps, with a line across
    the door, flattened (run once per work folder)."""
    saved = work / "door_analysis.json"
    if not saved.exists():
        sweep("run", "--record-every", "5", "--out", "run.mcap", cwd=work)
        saved.write_text(sweep("analyze", "run.mcap", "--line", "10,4.4,10,5.6", "--no-plots",
                               "--quiet", "--json", cwd=work))
    return _flatten(json.loads(saved.read_text()))


def _summary(flat: dict, keys: tuple[str, ...]) -> str:
    missing = [k for k in keys if k not in flat]
    if missing:
        raise SystemExit(f"sweep analyze --json has no {', '.join(missing)}")
    width = max(map(len, keys)) + 2
    lines = [f"{k:<{width}}{_text(flat[k])}" for k in keys]
    return "```\n" + "\n".join(lines) + "\n```\n"


def analyze(work: Path) -> str:
    """The bundled scene recorded every 5 steps, analysed with a line across the door."""
    return _summary(_door_analysis(work), ANALYZE_KEYS)


def tour(work: Path) -> str:
    """The same analysis, the lines the README's tour quotes."""
    return _summary(_door_analysis(work), TOUR_KEYS)


#: the runs of the compare example (docs/recordings.md shows these commands): dt = 0.001, and
#: dt = 0.01 on its Brownian path and on another
COMPARE_RUNS = (
    ("run", "corridor_groups", "--dt", "0.001", "--seed", "3", "--t-end", "1", "--out",
     "fine.mcap"),
    ("run", "corridor_groups", "--dt", "0.01", "--path-dt", "0.001", "--seed", "3", "--t-end",
     "1", "--out", "coarse.mcap"),
    ("run", "corridor_groups", "--dt", "0.01", "--seed", "3", "--t-end", "1", "--out",
     "other.mcap"),
)
#: the comparisons of the compare example: one path, two paths
COMPARE_PAIRS = (("compare", "fine.mcap", "coarse.mcap"), ("compare", "fine.mcap", "other.mcap"))


def compare(work: Path) -> str:
    """dt = 0.01 against dt = 0.001 on the bundled corridor_groups for 1 s, on one Brownian path
    and on two (a fine path needs a fixed crowd: the default scene's sink is refused)."""
    for args in COMPARE_RUNS:
        sweep(*args, cwd=work)
    shared, apart = (json.loads(sweep(*args, "--no-plots", "--json", cwd=work))
                     for args in COMPARE_PAIRS)
    mm = 1e3 * float(shared["sup_m"])
    cm = 1e2 * float(apart["sup_m"])
    return (f"On corridor_groups over 1 s, the largest distance between the dt = 0.01 and "
            f"dt = 0.001 runs\nis {mm:.1f} mm on the shared path and {cm:.0f} cm without "
            f"`--path-dt` (two different paths).\n")


EXAMPLES: dict[str, Callable[[Path], str]] = {"analyze": analyze, "compare": compare,
                                              "tour": tour}


def _flatten(tree: dict, prefix: str = "") -> dict:
    flat: dict = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            flat.update(_flatten(value, name + "."))
        else:
            flat[name] = value
    return flat


def _text(value: object) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list):
        return ", ".join(_text(v) for v in value)
    return "-" if value is None else str(value)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if a file differs")
    args = parser.parse_args(argv)
    texts = {path: path.read_text() for path in FILES}
    found = [m["name"] for text in texts.values() for m in BLOCK.finditer(text)]
    if sorted(found) != sorted(EXAMPLES):
        print(f"example blocks {sorted(found)} != examples {sorted(EXAMPLES)} (each once in "
              "README.md and docs/*.md)", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        bodies = {name: make(Path(tmp)) for name, make in EXAMPLES.items()}
    stale = 0
    for path, text in texts.items():
        fresh = BLOCK.sub(lambda m: m[1] + bodies[m["name"]] + m[4], text)
        if fresh == text:
            continue
        stale += 1
        name = str(path.relative_to(REPO))
        if args.check:
            sys.stdout.writelines(difflib.unified_diff(text.splitlines(True),
                                                       fresh.splitlines(True), name, "fresh run"))
        else:
            path.write_text(fresh)
            print(f"{name}: examples rewritten")
    if not stale:
        print("examples are up to date")
        return 0
    if args.check:
        print("examples differ from a fresh run: python docs/readme_examples.py", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
