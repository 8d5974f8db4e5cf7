"""The layout holds: nothing private is imported across modules, and no module grows past about
400 lines without saying why in its docstring. (The layers themselves are checked by
import-linter, ``lint-imports``, in the README's test command.)"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("sweep_core", "sweep_ros")
MODULES = sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))
#: a module longer than this must say why in its docstring ("Longer than ... because ...")
MAX_LINES = 420


def _first_party(name: str | None) -> bool:
    return bool(name) and name.split(".")[0] in PACKAGES


def private_imports(path: Path) -> list[str]:
    """``from first_party import _name`` and ``first_party_module._name`` uses in ``path``."""
    tree = ast.parse(path.read_text(), str(path))
    found = []
    aliases: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.level or _first_party(node.module)):
            for a in node.names:
                if a.name.startswith("_") and not a.name.startswith("__"):
                    found.append(f"line {node.lineno}: from {node.module} import {a.name}")
                else:
                    aliases.add(a.asname or a.name)
        elif isinstance(node, ast.Import):
            for a in node.names:
                if _first_party(a.name):
                    aliases.add(a.asname or a.name.split(".")[0])
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in aliases and node.attr.startswith("_")
                and not node.attr.startswith("__")):
            found.append(f"line {node.lineno}: {node.value.id}.{node.attr}")
    return found


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_private_name_crosses_a_module(path: Path) -> None:
    assert private_imports(path) == []


def test_the_private_import_check_can_fail(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("from sweep_core.numerics.projection.exact import _hidden\n"
                   "from sweep_core.numerics import projection\nprojection._solve()\n")
    assert len(private_imports(bad)) == 2


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(ROOT)))
def test_long_modules_say_why(path: Path) -> None:
    text = path.read_text()
    if text.count("\n") <= MAX_LINES:
        return
    doc = ast.get_docstring(ast.parse(text)) or ""
    assert "Longer than" in doc, f"{path.name}: {text.count(chr(10))} lines and no reason given"
