"""JSON text <-> plain data: the form in which recordings carry their scene.

A recording's scene (metadata ``sweep_ros.scene``) is written as JSON; a scene file may be
JSON too (a text whose first character is ``{`` is read as JSON when it is JSON, else as YAML),
so a recorded scene saved to a file runs as it is. JSON is read by the standard library's C decoder,
about 40 times faster than YAML's loader and with a tenth of its memory per value (a wall
polyline of 300 000 points, 5.5 MB of text: 0.4 s against 19 s, and about 60 B a value against
600 B), so a recording that claims a large scene costs seconds to read, not minutes.

The text is held to the bounds a YAML scene is held to (:mod:`sweep_core.model.yaml_files`),
checked before and after decoding, never by recursion:

- at most :data:`~sweep_core.model.yaml_files.MAX_NODES` values, keys, lists and mappings,
  counted from the text before it is decoded (its commas, colons and opening brackets bound the
  count from above, so nothing larger is ever built);
- nesting at most :data:`~sweep_core.model.yaml_files.MAX_DEPTH` deep (measured on the text's
  brackets outside strings, before decoding);
- no key given twice in one mapping (JSON decoders otherwise keep the last silently).

``NaN``, ``Infinity`` and ``-Infinity`` are read as the floats YAML writes ``.nan``, ``.inf``
and ``-.inf``.
"""
from __future__ import annotations

import json
import re
from typing import Any

import numpy as np

from sweep_core.model import yaml_files


class JSONLimitError(ValueError):
    """The text is JSON but exceeds a bound (nodes, nesting) or repeats a key; ``problem``
    says which and ``fix`` what to write instead."""

    def __init__(self, problem: str, fix: str, cost: bool = False) -> None:
        super().__init__(problem)
        self.problem = problem
        self.fix = fix
        #: the bound exceeded is on what building the data would cost (its node count)
        self.cost = cost

    def __reduce__(self) -> tuple:
        """Pickled with its arguments (a worker process sends it to its parent)."""
        return (type(self), (self.problem, self.fix, self.cost), self.__dict__)


def looks_like_json(text: str) -> bool:
    """Whether ``text`` is meant as a JSON object: its first character other than white
    space is ``{`` (a YAML flow mapping starts so too; :func:`load_json` then tells them
    apart)."""
    return text.lstrip(" \t\r\n")[:1] == "{"


def node_bound(text: str) -> int:
    """An upper bound on the values, keys, lists and mappings a JSON text holds, from its
    punctuation alone: every value after the first in a list or mapping follows a comma,
    every key precedes a colon, and each list or mapping adds its first value (its own node
    is counted where it follows a comma or a colon, or as the document). Punctuation inside
    strings and empty lists or mappings only raise the bound."""
    return text.count(",") + text.count(":") + text.count("[") + text.count("{") + 1


def _pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
    out = dict(items)
    if len(out) != len(items):
        seen: set[str] = set()
        for key, _ in items:
            if key in seen:
                shown = key if len(key) <= 40 else key[:37] + "..."
                raise JSONLimitError(f"key {shown!r} is given twice in one mapping; JSON "
                                     "would keep only the last", "remove one of them")
            seen.add(key)
    return out


#: a JSON string (its escapes included): brackets inside it do not nest
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
#: every byte but the four brackets, deleted to measure nesting
_NOT_BRACKETS = bytes(sorted(set(range(256)) - set(b"[]{}")))


def nesting(text: str) -> int:
    """How deep lists and mappings nest in a JSON text (0: a scalar), from its brackets
    outside strings, without decoding it."""
    brackets = np.frombuffer(_STRING.sub('""', text).encode().translate(None, _NOT_BRACKETS),
                             dtype=np.uint8)
    if len(brackets) == 0:
        return 0
    opening = (brackets == ord("[")) | (brackets == ord("{"))
    return int(np.cumsum(np.where(opening, 1, -1), dtype=np.int64).max(initial=0))


def load_json(text: str, max_nodes: int | None = None, limit_name: str = "",
              fix: str = "") -> Any:
    """Decode one JSON document within the bounds above.

    Raises:
        JSONLimitError: more than ``max_nodes`` nodes (default, and at most, MAX_NODES;
            ``limit_name`` and ``fix`` name a lower bound and what to do; counted from the text
            before it is decoded), nesting deeper than MAX_DEPTH, or a key given twice.
        json.JSONDecodeError: the text is not JSON (line and column in the message).
    """
    if max_nodes is None or max_nodes > yaml_files.MAX_NODES:
        max_nodes, limit_name, fix = yaml_files.MAX_NODES, "", ""
    bound = node_bound(text)
    if bound > max_nodes:
        raise JSONLimitError(f"holds up to {bound} values, keys, lists and mappings (counted "
                             f"from its commas, colons and brackets), more than {max_nodes} "
                             f"({limit_name or 'the limit MAX_NODES'})",
                             fix or yaml_files.DEFAULT_NODES_FIX, cost=True)
    if nesting(text) > yaml_files.MAX_DEPTH:
        raise JSONLimitError(f"nests lists and mappings deeper than {yaml_files.MAX_DEPTH} "
                             "levels (the limit MAX_DEPTH)",
                             "write the data with fewer levels of brackets")
    try:
        return json.loads(text, object_pairs_hook=_pairs)
    except ValueError as err:  # a number of more digits than Python converts
        if isinstance(err, (json.JSONDecodeError, JSONLimitError)):
            raise
        raise JSONLimitError(f"holds a number Python does not read: "
                             f"{str(err).split(':')[0]}",
                             "write numbers with at most 4300 digits") from err


def dump_json(data: Any) -> str:
    """JSON text of plain data (dicts, lists, str, numbers, bools, None), keys in their
    order; floats written exactly (their shortest repr), infinities and NaN as ``Infinity``,
    ``-Infinity`` and ``NaN`` (which :func:`load_json` reads back)."""
    return json.dumps(data, ensure_ascii=False)
