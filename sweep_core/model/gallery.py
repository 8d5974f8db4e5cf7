"""The bundled scenes (``sweep_core/scenes/``): their index, and scene names resolved to files.

``scenes/gallery.yaml`` lists each bundled scene once: ``name`` (its file is ``NAME.yaml``),
``shows`` (one line: what it shows), ``model`` (``speed law``: its people walk with the
validated speed law ``flows.headway``; ``pure``: without it), ``why`` (one line: why that
model) and ``agents`` (its agent count, checked against the scene by the tests). Run times
are not listed: they depend on the machine and its load (``sweep bench`` measures them).

A scene argument (``sweep run NAME``, the node's ``scene``, an ensemble's scene) is a path
first: a name resolves to a bundled scene only when no such file exists.
"""
from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from sweep_core import checks
from sweep_core.errors import SceneError, show
from sweep_core.model.yaml_files import load_yaml

#: the index of the bundled scenes, beside them
INDEX = "gallery.yaml"
#: the models a bundled scene's people walk with: the speed law (``flows.headway``, validated
#: by ``sweep verify``) or the pure model (no speed law)
MODELS = ("speed law", "pure")


@dataclass(frozen=True)
class BundledScene:
    """One bundled scene: name, what it shows, agents, its file, and the model its people walk
    with (``MODELS``) and why."""

    name: str
    shows: str
    agents: int
    path: Path
    model: str = "pure"
    why: str = ""


def scenes_dir() -> Path:
    """The folder of the bundled scenes (inside the installed package)."""
    return Path(str(resources.files("sweep_core") / "scenes"))


def bundled_scenes() -> list[BundledScene]:
    """The bundled scenes, in the index's order."""
    folder = scenes_dir()
    out = []
    for k, item in enumerate(checks.mapping(_index(), INDEX, required={"scenes"})["scenes"]):
        field = f"{INDEX}: scenes[{k}]"
        keys = {"name", "shows", "agents", "model", "why"}
        checks.mapping(item, field, allowed=keys, required=keys)
        if item["model"] not in MODELS:
            raise SceneError(f"{field}.model", f"unknown model {show(item['model'])}",
                             f"use one of {', '.join(MODELS)}")
        out.append(BundledScene(str(item["name"]), str(item["shows"]),
                                checks.integer(item["agents"], f"{field}.agents", low=0),
                                folder / f"{item['name']}.yaml", str(item["model"]),
                                str(item["why"])))
    return out


def bundled_names() -> list[str]:
    """The names of the bundled scenes."""
    return [s.name for s in bundled_scenes()]


def resolve_scene_path(scene: str | Path) -> Path:
    """``scene`` as a path when such a file (or anything) exists there; else the bundled scene
    of that name (with or without ``.yaml``); else, for a path with a folder, ``scene``
    unchanged (loading it then fails naming the path).

    Raises:
        SceneError: a bare name that is neither a file nor a bundled scene (the error lists
            the bundled names).
    """
    path = Path(scene)
    text = str(scene)
    try:
        if path.exists():
            return path
    except OSError as err:  # a name longer than the file system takes (ENAMETOOLONG)
        raise SceneError("scene", f"{show(text)} ({len(text)} characters) cannot be looked up: "
                         f"{err.strerror}", "give the path of a scene YAML file, or a bundled "
                         "scene's name (sweep scenes lists them)") from None
    name = text[:-5] if text.endswith(".yaml") else text
    names = bundled_names()
    if name in names:  # a bundled name, e.g. bottleneck or rimea/rimea06_corner
        return scenes_dir() / f"{name}.yaml"
    if str(path.parent) != ".":
        return path
    raise SceneError("scene", f"no file {show(text)} here, and no bundled scene of that name",
                     f"give the path of a scene YAML file, or a bundled scene: "
                     f"{', '.join(names)} (sweep scenes describes them)")


def _index() -> dict:
    return load_yaml((scenes_dir() / INDEX).read_text()) or {}
