"""ros2msg definition text of installed message types, for MCAP schema records.

The text is what rosbag2 stores: the type's own ``.msg`` file as installed, then every type it
depends on, each under a line of 80 ``=`` and ``MSG: pkg/Type``. Dependencies are appended depth
first, the direct dependencies of each definition in sorted order of their ``pkg/Type`` name,
each type once. The ``.msg`` files are looked up in the ``share/<pkg>/msg`` folders of the
ament prefixes (``AMENT_PREFIX_PATH``, through ament_index_python) and of this Python's prefix
(where the PyPI ROS wheels put them, and where an underlay that was not sourced keeps them).
"""
from __future__ import annotations

import sys
from functools import cache
from pathlib import Path

SEPARATOR = "=" * 80

#: built-in field types of the .msg format (no dependency)
PRIMITIVES = frozenset({
    "bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16", "int32",
    "uint32", "int64", "uint64", "string", "wstring",
})


class MsgDefError(LookupError):
    """A message type's definition cannot be found or parsed."""


def split_type(msgtype: str) -> tuple[str, str]:
    """``pkg/msg/Type`` or ``pkg/Type`` -> (pkg, Type)."""
    parts = msgtype.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        parts = [parts[0], parts[2]]
    if len(parts) != 2 or not all(parts):
        raise MsgDefError(f"{msgtype!r} is not a message type name (fix: write pkg/msg/Type)")
    return parts[0], parts[1]


def share_dirs() -> list[Path]:
    """Folders that may hold ``<pkg>/msg/<Type>.msg``, in search order, without duplicates."""
    prefixes: list[str] = []
    try:
        from ament_index_python.search_paths import get_search_paths
        prefixes.extend(get_search_paths())
    except (OSError, ImportError):
        pass
    prefixes.extend([sys.prefix, sys.base_prefix])
    out: list[Path] = []
    for p in prefixes:
        d = Path(p) / "share"
        if d.is_dir() and d not in out:
            out.append(d)
    return out


def find_msg_file(pkg: str, name: str) -> Path:
    """Path of the installed ``pkg/msg/name.msg``."""
    tried = []
    for share in share_dirs():
        path = share / pkg / "msg" / f"{name}.msg"
        if path.is_file():
            return path
        tried.append(str(path.parent))
    raise MsgDefError(f"{pkg}/msg/{name}.msg not found (looked in {tried or 'no share folder'}) "
                      f"(fix: install the {pkg} package or source its workspace)")


def _field_type(line: str) -> str | None:
    """The type token of a field or constant line, None for blank and comment lines."""
    code = line.split("#", 1)[0].strip()
    if not code:
        return None
    token = code.split()[0]
    token = token.split("[", 1)[0]        # arrays: T[], T[3], T[<=3]
    token = token.split("<=", 1)[0]       # bounded strings: string<=10
    return token


def dependencies(text: str, pkg: str) -> list[str]:
    """Sorted ``pkg/Type`` names of the non-primitive field types of a .msg text."""
    deps = set()
    for line in text.splitlines():
        token = _field_type(line)
        if token is None or token in PRIMITIVES:
            continue
        if token == "Header":
            deps.add("std_msgs/Header")
        elif "/" in token:
            dep_pkg, dep_name = split_type(token)
            deps.add(f"{dep_pkg}/{dep_name}")
        else:
            deps.add(f"{pkg}/{token}")
    return sorted(deps)


@cache
def _msg_text(pkg: str, name: str) -> str:
    return find_msg_file(pkg, name).read_text(encoding="utf-8")


@cache
def definition(msgtype: str) -> str:
    """Full ros2msg text of ``msgtype`` (``pkg/msg/Type``) with its dependencies appended."""
    pkg, name = split_type(msgtype)
    seen = {f"{pkg}/{name}"}

    def expand(dep_pkg: str, dep_name: str) -> str:
        text = _msg_text(dep_pkg, dep_name)
        out = text
        for dep in dependencies(text, dep_pkg):
            if dep in seen:
                continue
            seen.add(dep)
            sub_pkg, sub_name = dep.split("/")
            out += f"\n{SEPARATOR}\nMSG: {dep}\n" + expand(sub_pkg, sub_name)
        return out

    return expand(pkg, name)


def dependency_names(full_text: str) -> list[str]:
    """The ``MSG:`` names of a full definition, in order (for checks and tests)."""
    return [line[5:].strip() for line in full_text.splitlines() if line.startswith("MSG: ")]


def msgtype_of(msg_class: type) -> str:
    """``pkg/msg/Type`` of a generated rclpy message class."""
    module = msg_class.__module__.split(".")
    return f"{module[0]}/msg/{msg_class.__name__}"


__all__ = ["MsgDefError", "PRIMITIVES", "SEPARATOR", "definition", "dependencies",
           "dependency_names", "find_msg_file", "msgtype_of", "share_dirs", "split_type"]

