"""The quoted outputs of the README and the docs are what the quoted commands print today
(docs/readme_examples.py regenerates them; here it only checks), the README's two set-up
commands are where CI finds them, and the test command builds the documentation strictly."""
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


def test_readme_test_command_builds_the_docs_strictly() -> None:
    text = (REPO / "README.md").read_text()
    command = text.split("<!-- test-command -->", 1)[1].split("```", 2)[1]
    assert re.search(r"mkdocs build --strict\b", command)
    assert "python -m pytest" in command.split("mkdocs build", 1)[1]
    # --quiet (-q) drops the warnings that --strict counts: the build would pass with them
    mkdocs = command.split("mkdocs build", 1)[1].split("&&", 1)[0]
    assert not re.search(r"(^|\s)(--quiet|-q)(\s|$)", mkdocs), mkdocs


def test_the_site_lists_every_page_and_builds_nowhere_in_the_tree() -> None:
    """Every page of docs/ is in mkdocs.yml's nav (a page left out is a page nobody finds), and
    site/ is ignored by git (the build is never committed)."""
    nav = (REPO / "mkdocs.yml").read_text().split("\nnav:", 1)[1]
    pages = {p.name for p in (REPO / "docs").glob("*.md")}
    listed = set(re.findall(r"([\w-]+\.md)", nav))
    assert pages <= listed, sorted(pages - listed)
    assert "site/" in (REPO / ".gitignore").read_text().split()


def test_the_compare_example_shows_the_commands_its_numbers_come_from() -> None:
    """docs/recordings.md quotes numbers docs/readme_examples.py gets from its runs: the page
    shows those runs and comparisons, and says how long they are."""
    sys.path.insert(0, str(REPO / "docs"))
    try:
        import readme_examples
    finally:
        sys.path.remove(str(REPO / "docs"))
    text = (REPO / "docs" / "recordings.md").read_text()
    shown = re.findall(r"^    (sweep (?:run corridor_groups|compare fine\.mcap) .*)$", text, re.M)
    wanted = [" ".join(("sweep",) + args) for args in
              readme_examples.COMPARE_RUNS + readme_examples.COMPARE_PAIRS]
    assert shown == wanted
    t_end = {args[args.index("--t-end") + 1] for args in readme_examples.COMPARE_RUNS}
    assert t_end == {"1"} and "On corridor_groups over 1 s" in text
