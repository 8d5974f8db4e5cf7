"""YAML text <-> Python data, the one place sweep parses and writes YAML (scenes, recorded
scenes, maps, the node's parameter files).

libyaml's ``CSafeLoader`` / ``CSafeDumper`` are used when PyYAML was built with libyaml (on a
scene of 1e5 agents, 4.9 MB, loading takes about a third of the pure-Python ``SafeLoader``'s
time and dumping a third of ``SafeDumper``'s), otherwise the pure-Python classes; both give the
same data and both mark errors with their line and column.

Before a document is composed, its event stream (which both parsers produce without recursion)
is checked against limits that keep hostile or careless text from exhausting the stack or the
memory (:func:`check_yaml`): nesting deeper than :data:`MAX_DEPTH`, more than
:data:`MAX_ALIASES` aliases, aliases that would repeat more than :data:`MAX_ALIAS_NODES` nodes
in all (a few hundred bytes of nested aliases can stand for billions of nodes), more than
:data:`MAX_NODES` nodes (the memory composing them takes), and a key
given twice in one mapping (YAML loaders otherwise keep the last silently) are refused with
their line and column.
"""
from __future__ import annotations

import re
from typing import Any

import yaml

#: the loader class used: libyaml's safe loader when available, else PyYAML's pure-Python one
SAFE_LOADER: type = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

#: a number in exponent notation as YAML 1.2 writes it (``1e5``, ``5e-2``, ``1.5E+3``, ``.5e1``)
#: but YAML 1.1, which PyYAML follows, reads as text unless it has a dot and a signed exponent
EXPONENT_FLOAT = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")


class SceneLoader(SAFE_LOADER):
    """:data:`SAFE_LOADER` that also reads numbers in exponent notation (:data:`EXPONENT_FLOAT`)
    as floats, so that ``sigma: 5e-2`` is the number 0.05, as a scientist means it and as
    YAML 1.2, JSON and rcl's parameter parser read it."""


SceneLoader.add_implicit_resolver("tag:yaml.org,2002:float", EXPONENT_FLOAT,
                                  list("-+0123456789."))

#: the dumper class used: libyaml's safe dumper when available, else PyYAML's pure-Python one
SAFE_DUMPER: type = getattr(yaml, "CSafeDumper", yaml.SafeDumper)

#: the errors load_yaml can raise
YAMLError = yaml.YAMLError

#: deepest nesting of sequences and mappings accepted (a scene uses 5, a parameters file 4)
MAX_DEPTH = 64
#: aliases (``*name``) accepted in one document
MAX_ALIASES = 1000
#: nodes that aliases may repeat in one document, counted as composed (an alias of a list of
#: 3 numbers repeats 4 nodes)
MAX_ALIAS_NODES = 100_000
#: nodes (scalars, keys and collections) in one document. Loading a node costs about
#: :data:`BYTES_PER_NODE` (measured increase of the peak resident memory over loading 3e5
#: nodes: 430 B a node for a list of numbers, 530 B for a list of points, 730 B for a list of
#: small mappings; 550 B for 9e5 nodes of points), so a file within the scene's size limit
#: could otherwise take tens of GB; this bounds it near 2.5 GB. A scene listing the positions,
#: radii and speeds of 1e5 agents has about 5e5 nodes
MAX_NODES = 1 << 22
#: nodes in a recorded scene given as YAML. sweep records scenes as JSON
#: (:mod:`sweep_core.model.json_text`), read up to MAX_NODES at a tenth of the memory; YAML in a
#: recording (written by hand or by another tool) is read up to this count, about 160 MB and
#: a few seconds
MAX_RECORDED_YAML_NODES = 1 << 18
#: what to do about a document of more than MAX_NODES nodes
DEFAULT_NODES_FIX = ("give long per-agent lists by a rule instead (a spawn region, a speed "
                     "distribution)")
#: memory (bytes) a loaded node takes, the estimate behind :data:`MAX_NODES`
#: (test/test_estimates.py checks it)
BYTES_PER_NODE = 600


class YAMLLimitError(yaml.MarkedYAMLError):
    """The text is valid YAML but exceeds one of the limits above (nesting, aliases, their
    expansion) or repeats a key; ``problem`` names the limit, ``problem_mark`` the place and
    ``fix`` what to write instead."""

    fix = ""
    #: the bound exceeded is on what composing the text would cost (its node count)
    cost = False


def _refuse(problem: str, mark: Any, fix: str, cost: bool = False) -> YAMLLimitError:
    err = YAMLLimitError(problem=problem, problem_mark=mark)
    err.fix = fix
    err.cost = cost
    return err


def yaml_fix(err: yaml.YAMLError) -> str:
    """The fix to print after :func:`yaml_problem`: the limit's own, or correcting the syntax."""
    return getattr(err, "fix", "") or "correct the YAML syntax at that line"


def check_yaml(text: str | bytes, max_nodes: int | None = None, limit_name: str = "",
               fix: str = "") -> None:
    """Walk the YAML events of ``text`` (no recursion, nothing composed) and refuse what
    :func:`load_yaml` must not compose.

    Raises:
        YAMLLimitError: nesting deeper than MAX_DEPTH, more than MAX_ALIASES aliases, aliases
            repeating more than MAX_ALIAS_NODES nodes, more than ``max_nodes`` nodes (default
            MAX_NODES; ``limit_name`` and ``fix`` name another bound and what to do), or a
            mapping key given twice.
        yaml.YAMLError: the text is not valid YAML.
    """
    # one frame per open collection: [nodes inside so far, anchor, children, keys seen or None]
    stack: list[list[Any]] = []
    sizes: dict[str, int] = {}  # anchor -> composed node count of what it names
    aliases = repeated = nodes = 0

    def done(size: int, anchor: str | None, event: Any) -> None:
        if anchor is not None:
            sizes[anchor] = size
        if not stack:
            return
        top = stack[-1]
        top[0] += size
        if top[3] is not None and top[2] % 2 == 0 and isinstance(event, yaml.ScalarEvent):
            key = event.value
            line = top[3].get(key)
            if line is not None:
                shown = key if len(key) <= 40 else key[:37] + "..."
                raise _refuse(f"key {shown!r} is given twice in one mapping (first at line "
                              f"{line}); YAML would keep only the last", event.start_mark,
                              "remove one of them")
            top[3][key] = event.start_mark.line + 1
        top[2] += 1

    if max_nodes is None:
        max_nodes, limit_name, fix = MAX_NODES, "", ""
    limit_name = limit_name or "the limit MAX_NODES"
    fix = fix or DEFAULT_NODES_FIX
    scalar = yaml.ScalarEvent
    node_events = {scalar, yaml.SequenceStartEvent, yaml.MappingStartEvent, yaml.AliasEvent}
    for event in yaml.parse(text, Loader=SAFE_LOADER):
        if type(event) in node_events:
            nodes += 1
            if nodes > max_nodes:
                raise _refuse(f"more than {max_nodes} values, keys, lists and mappings in "
                              f"one document ({limit_name})", event.start_mark, fix, cost=True)
        if type(event) is scalar and event.anchor is None and stack and stack[-1][3] is None:
            top = stack[-1]  # the common case, an item of a list: counted and nothing else
            top[0] += 1
            top[2] += 1
        elif isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
            if len(stack) >= MAX_DEPTH:
                raise _refuse(f"nesting deeper than {MAX_DEPTH} levels of lists and mappings "
                              f"(the limit MAX_DEPTH)", event.start_mark,
                              "write the data with fewer levels of brackets and indentation")
            keys: dict[str, int] | None = {} if isinstance(event, yaml.MappingStartEvent) \
                else None
            stack.append([1, event.anchor, 0, keys])
        elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            size, anchor, _, _ = stack.pop()
            done(size, anchor, event)
        elif isinstance(event, yaml.ScalarEvent):
            done(1, event.anchor, event)
        elif isinstance(event, yaml.AliasEvent):
            aliases += 1
            size = sizes.get(event.anchor, 1)  # an unknown anchor: the loader names it
            repeated += size
            if aliases > MAX_ALIASES:
                raise _refuse(f"more than {MAX_ALIASES} aliases (the limit MAX_ALIASES)",
                              event.start_mark, "write the repeated values out")
            if repeated > MAX_ALIAS_NODES:
                raise _refuse(f"aliases repeat more than {MAX_ALIAS_NODES} nodes (the limit "
                              f"MAX_ALIAS_NODES; *{event.anchor} alone repeats {size})",
                              event.start_mark, "use fewer, smaller aliases")
            done(size, None, event)
        elif isinstance(event, yaml.DocumentStartEvent):
            sizes.clear()
            aliases = repeated = nodes = 0


def load_yaml(text: str | bytes, **limits: Any) -> Any:
    """Parse one YAML document with :class:`SceneLoader` (plain data only: no Python tags;
    ``1e5`` is a number), after :func:`check_yaml` (``limits``: its node limit's keywords).

    Raises:
        yaml.YAMLError: the text is not valid YAML, or exceeds a limit (YAMLLimitError);
            :func:`yaml_problem` describes it.
    """
    check_yaml(text, **limits)
    return yaml.load(text, Loader=SceneLoader)


def compose_yaml(text: str | bytes) -> Any:
    """The node tree (``yaml.Node``, with line marks) of one document, after
    :func:`check_yaml`; raises as :func:`load_yaml`."""
    check_yaml(text)
    return yaml.compose(text, Loader=SceneLoader)


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
