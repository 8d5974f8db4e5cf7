"""The README's quoted outputs are what the quoted commands print today (docs/readme_examples.py
regenerates them; here it only checks), and its two set-up commands are where CI finds them."""
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_readme_examples_match_a_fresh_run() -> None:
    done = subprocess.run([sys.executable, str(REPO / "docs" / "readme_examples.py"), "--check"],
                          cwd=REPO, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]


def test_readme_keeps_its_two_setup_commands() -> None:
    text = (REPO / "README.md").read_text()
    for marker in ("main-command", "test-command"):
        assert len(re.findall(f"<!-- {marker} -->", text)) == 1, marker
