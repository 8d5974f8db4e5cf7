"""YAML text <-> Python data, the one place sweep parses and writes YAML (scenes, recorded
scenes, the node's parameter files).

libyaml's ``CSafeLoader`` / ``CSafeDumper`` are used when PyYAML was built with libyaml (on a
scene of 1e5 agents, 4.9 MB, loading takes about a third of the pure-Python ``SafeLoader``'s
time and dumping a third of ``SafeDumper``'s), otherwise the pure-Python classes; both give the
same data and both mark errors with their line and column.
"""
from __future__ import annotations

from typing import Any

import yaml

#: the loader class used: libyaml's safe loader when available, else PyYAML's pure-Python one
SAFE_LOADER: type = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

#: the dumper class used: libyaml's safe dumper when available, else PyYAML's pure-Python one
SAFE_DUMPER: type = getattr(yaml, "CSafeDumper", yaml.SafeDumper)

#: the errors load_yaml can raise
YAMLError = yaml.YAMLError


def load_yaml(text: str | bytes) -> Any:
    """Parse one YAML document with :data:`SAFE_LOADER` (plain data only: no Python tags).

    Raises:
        yaml.YAMLError: the text is not valid YAML; :func:`yaml_problem` describes it.
    """
    return yaml.load(text, Loader=SAFE_LOADER)


def dump_yaml(data: Any) -> str:
    """YAML text of plain data (dicts, lists, str, numbers, bools, None), keys in their order."""
    return yaml.dump(data, Dumper=SAFE_DUMPER, sort_keys=False)


def _where(mark: Any) -> str:
    return f"line {mark.line + 1} column {mark.column + 1}"


def yaml_problem(err: yaml.YAMLError) -> str:
    """One line describing a YAML error: ``line L column C: problem (while ... at line l)``.

    Lines and columns count from 1, as editors do."""
    problem = getattr(err, "problem", None)
    mark = getattr(err, "problem_mark", None)
    if not problem:
        return " ".join(str(err).split())
    out = f"{_where(mark)}: {problem}" if mark is not None else str(problem)
    context = getattr(err, "context", None)
    context_mark = getattr(err, "context_mark", None)
    if context:
        at = ""
        if context_mark is not None and (mark is None or context_mark.line != mark.line
                                         or context_mark.column != mark.column):
            at = f" started at {_where(context_mark)}"
        out += f" ({context}{at})"
    return " ".join(out.split())
