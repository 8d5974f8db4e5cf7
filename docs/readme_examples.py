"""The example outputs quoted in README.md, regenerated from the commands they quote.

Each example is a block of README.md between ``<!-- example: NAME -->`` and
``<!-- /example -->``; this script runs the seeded commands behind it and writes the block
(default) or, with ``--check``, exits 1 with a diff when the README differs from a fresh run.
The test suite runs ``--check`` (test/test_readme.py), so a change of the engine that changes
a quoted number fails CI until the README is regenerated:

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
BLOCK = re.compile(r"(<!-- example: (?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- /example -->)", re.S)

#: the lines of ``sweep analyze``'s summary the README quotes
ANALYZE_KEYS = ("status", "frames", "duration_s", "min_gap.min_m", "min_gap.between",
                "touching.mean", "reaction.pressure_mean_m_per_s", "speed.mean_m_per_s",
                "speed.p50_m_per_s", "flow.net", "flow.per_s", "arrivals.arrived",
                "density.max_per_m2")


def sweep(*args: str, cwd: Path) -> str:
    """Run ``sweep ARGS`` with this interpreter in cwd; its standard output."""
    done = subprocess.run([sys.executable, "-m", "sweep_core.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        raise SystemExit(f"sweep {' '.join(args)} failed ({done.returncode}):\n{done.stderr}")
    return done.stdout


def analyze(work: Path) -> str:
    """The bundled scene recorded every 5 steps, analysed with a line across the door."""
    sweep("run", "--record-every", "5", "--out", "run.mcap", cwd=work)
    out = sweep("analyze", "run.mcap", "--line", "10,4.4,10,5.6", "--no-plots", "--quiet",
                "--json", cwd=work)
    flat = _flatten(json.loads(out))
    missing = [k for k in ANALYZE_KEYS if k not in flat]
    if missing:
        raise SystemExit(f"sweep analyze --json has no {', '.join(missing)}")
    width = max(map(len, ANALYZE_KEYS)) + 2
    lines = [f"{k:<{width}}{_text(flat[k])}" for k in ANALYZE_KEYS]
    return "```\n" + "\n".join(lines) + "\n```\n"


def compare(work: Path) -> str:
    """dt = 0.01 against dt = 0.001 on the bundled scene for 1 s, on one Brownian path and on
    two."""
    sweep("run", "--dt", "0.001", "--seed", "3", "--t-end", "1", "--out", "fine.mcap", cwd=work)
    sweep("run", "--dt", "0.01", "--path-dt", "0.001", "--seed", "3", "--t-end", "1",
          "--out", "coarse.mcap", cwd=work)
    sweep("run", "--dt", "0.01", "--seed", "3", "--t-end", "1", "--out", "other.mcap", cwd=work)
    shared = json.loads(sweep("compare", "fine.mcap", "coarse.mcap", "--no-plots", "--json",
                              cwd=work))
    apart = json.loads(sweep("compare", "fine.mcap", "other.mcap", "--no-plots", "--json",
                             cwd=work))
    mm = 1e3 * float(shared["sup_m"])
    cm = 1e2 * float(apart["sup_m"])
    return (f"On the bundled scene over 1 s, the largest distance between the dt = 0.01 and "
            f"dt = 0.001 runs\nis {mm:.1f} mm on the shared path and {cm:.0f} cm without "
            f"`--path-dt` (two different paths).\n")


EXAMPLES: dict[str, Callable[[Path], str]] = {"analyze": analyze, "compare": compare}


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
    parser.add_argument("--check", action="store_true", help="exit 1 if README.md differs")
    args = parser.parse_args(argv)
    text = README.read_text()
    found = {m["name"] for m in BLOCK.finditer(text)}
    if found != set(EXAMPLES):
        print(f"README.md blocks {sorted(found)} != examples {sorted(EXAMPLES)}", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        bodies = {name: make(Path(tmp)) for name, make in EXAMPLES.items()}
    fresh = BLOCK.sub(lambda m: m[1] + bodies[m["name"]] + m[4], text)
    if fresh == text:
        print("README.md examples are up to date")
        return 0
    if args.check:
        sys.stdout.writelines(difflib.unified_diff(text.splitlines(True), fresh.splitlines(True),
                                                   "README.md", "fresh run"))
        print("README.md examples differ from a fresh run: python docs/readme_examples.py",
              file=sys.stderr)
        return 1
    README.write_text(fresh)
    print("README.md examples rewritten")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
