"""docs/analyze_example.png, the figure of ``sweep analyze`` the README shows, made by the
commands whose summary the README quotes (docs/readme_examples.py: the bundled room with a
door, recorded every 5 steps, a counting line across the door):

    python docs/analyze_example.py
"""
from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

OUT = Path(__file__).resolve().parent / "analyze_example.png"


def main() -> int:
    with tempfile.TemporaryDirectory() as work:
        for args in (("run", "--record-every", "5", "--out", "run.mcap", "--quiet"),
                     ("analyze", "run.mcap", "--line", "10,4.4,10,5.6", "--quiet")):
            subprocess.run([sys.executable, "-m", "sweep_core.cli", *args], cwd=work,
                           check=True, capture_output=True, timeout=900)
        shutil.copyfile(Path(work) / "run.analysis.png", OUT)
    print(OUT)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
