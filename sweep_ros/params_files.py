"""The ``--params-file`` files of a sweep_node command line, checked before rclpy parses them
(rcl's own parser stops the process with a traceback): YAML that loads as plain data, the
``ros__parameters`` sections for this node's fully qualified name, and parameter lists of one
scalar type. Each problem is one line naming the file, the line and the fix.
"""
from __future__ import annotations

import os
import re
from collections.abc import Sequence

import yaml

from sweep_core.model.yaml_files import SAFE_LOADER, YAMLError, compose_yaml, yaml_fix, yaml_problem

PARAMS_KEY = "ros__parameters"
#: YAML tags of the scalar types a ROS parameter list may hold (one type per list)
_SCALAR_TYPES = {"tag:yaml.org,2002:bool": "bool", "tag:yaml.org,2002:int": "integer",
                 "tag:yaml.org,2002:float": "double", "tag:yaml.org,2002:str": "string"}


def _ros_sections(argv: Sequence[str]) -> list[list[str]]:
    """The arguments of each ``--ros-args ... [--]`` section of a command line."""
    sections: list[list[str]] = []
    current: list[str] | None = None
    for arg in argv:
        if arg == "--ros-args":
            current = []
            sections.append(current)
        elif arg == "--":
            current = None
        elif current is not None:
            current.append(arg)
    return sections


def params_files(argv: Sequence[str]) -> list[str | None]:
    """The paths given to ``--params-file`` inside ``--ros-args`` sections, in order (None for a
    ``--params-file`` with nothing after it)."""
    out: list[str | None] = []
    for args in _ros_sections(argv):
        for k, arg in enumerate(args):
            if arg == "--params-file":
                out.append(args[k + 1] if k + 1 < len(args) else None)
    return out


def node_fqn(argv: Sequence[str], node_name: str) -> str:
    """Fully qualified name of the node (``/ns/name``) after ``-r __node:=`` / ``__ns:=``."""
    name, ns = node_name, "/"
    for args in _ros_sections(argv):
        for k, arg in enumerate(args[:-1]):
            if arg in ("-r", "--remap"):
                rule = args[k + 1]
                if rule.startswith(("__node:=", "__name:=")):
                    name = rule.split(":=", 1)[1]
                elif rule.startswith("__ns:="):
                    ns = rule.split(":=", 1)[1]
    ns = "/" + ns.strip("/")
    return (ns.rstrip("/") + "/" + name) if name else ns


def _matches(pattern: str, fqn: str) -> bool:
    """Whether a params-file node key (``/**``, ``/*/name``, ``name``) applies to fqn."""
    parts = [p for p in pattern.strip("/").split("/") if p]
    regex = "".join("(?:/[^/]+)*" if p == "**" else
                    "/" + re.escape(p).replace(r"\*", "[^/]*") for p in parts)
    return re.fullmatch(regex or "/", fqn) is not None


def _line(node: yaml.Node) -> str:
    return f"line {node.start_mark.line + 1}"


def _check_values(node: yaml.MappingNode, where: str) -> str | None:
    """The first problem of a ros__parameters mapping (nested mappings are namespaces)."""
    for key, value in node.value:
        name = f"{where}.{key.value}" if where else str(key.value)
        if isinstance(value, yaml.MappingNode):
            problem = _check_values(value, name)
            if problem:
                return problem
        elif isinstance(value, yaml.SequenceNode):
            kinds = {_SCALAR_TYPES.get(item.tag, "other") if isinstance(item, yaml.ScalarNode)
                     else "list" for item in value.value}
            if len(kinds) > 1:
                return (f"{_line(value)}: parameter {name} is a list mixing "
                        f"{' and '.join(sorted(kinds))} items (fix: write every item of the list "
                        "with one type, e.g. 1.0, 2.0 for doubles)")
    return None


def _check_tree(node: yaml.Node, path: str, found: list[str]) -> str | None:
    """Walk node names and namespaces down to ros__parameters; collect node paths in found."""
    if not isinstance(node, yaml.MappingNode):
        return None
    for key, value in node.value:
        name = str(key.value)
        if name == PARAMS_KEY:
            if not isinstance(value, yaml.MappingNode):
                return (f"{_line(value)}: {PARAMS_KEY} of {path or '/'} is not a mapping of "
                        f"parameter names (fix: indent 'name: value' lines under {PARAMS_KEY}:)")
            found.append(path or "/")
            problem = _check_values(value, "")
            if problem:
                return problem
            continue
        if not isinstance(value, yaml.MappingNode):
            return (f"{_line(key)}: '{name}' has a value where a node name or {PARAMS_KEY} "
                    f"is expected (fix: put parameters under '<node name>:' then "
                    f"'{PARAMS_KEY}:', e.g. '/**:' for every node)")
        sub = name if name.startswith("/") else f"{path}/{name}"
        problem = _check_tree(value, sub, found)
        if problem:
            return problem
    return None


def check_params_file(path: str, fqn: str = "/sweep_node") -> str | None:
    """The problem of one parameters file for the node ``fqn`` as one line naming the file
    (and the line when there is one) and the fix, or None when rcl will accept it and some
    entry applies to the node."""
    head = f"params file {path}"
    try:
        with open(os.path.expanduser(path), encoding="utf-8") as f:
            text = f.read()
    except OSError as err:
        return (f"{head}: cannot read it ({err.strerror}) (fix: give the path of an existing "
                "YAML file after --params-file)")
    except UnicodeDecodeError as err:
        return f"{head}: is not UTF-8 text (byte {err.start}) (fix: give a YAML text file)"
    try:
        root = compose_yaml(text)  # within the nesting and alias limits, no key twice
        yaml.load(text, Loader=SAFE_LOADER)  # tags and values construct as plain data
    except YAMLError as err:
        return f"{head} {yaml_problem(err)} (fix: {yaml_fix(err)})"
    example = f"(fix: start the file with '/**:' or '{fqn.rsplit('/', 1)[-1]}:' and indent " \
              f"'{PARAMS_KEY}:' under it)"
    if root is None:
        return f"{head}: is empty {example}"
    if not isinstance(root, yaml.MappingNode):
        kind = "a list" if isinstance(root, yaml.SequenceNode) else "a single value"
        return f"{head} {_line(root)}: the top level is {kind}, not a mapping of node names " \
               f"{example}"
    found: list[str] = []
    problem = _check_tree(root, "", found)
    if problem:
        return f"{head} {problem}"
    if not any(_matches(p, fqn) for p in found):
        entries = f"its entries are for {found}" if found else f"it has no {PARAMS_KEY}"
        return f"{head}: no {PARAMS_KEY} applies to node {fqn} ({entries}) {example}"
    return None


def check_params_files(argv: Sequence[str], node_name: str = "sweep_node") -> list[str]:
    """Problems of the ``--params-file`` files of a command line (``sys.argv``), one line each.

    Call it before ``rclpy.init``: rcl refuses a broken file with a traceback that names
    neither line nor fix. Empty when every file is fine (or none is given)."""
    fqn = node_fqn(argv, node_name)
    problems = []
    for path in params_files(argv):
        if path is None:
            problems.append("--params-file: no file after it (fix: write --params-file FILE "
                            "inside --ros-args)")
            continue
        problem = check_params_file(path, fqn)
        if problem:
            problems.append(problem)
    return problems
