"""The Foxglove layout and the RViz configuration in config/ load, and every topic they show is
one the node has (its topic table in docs/node.md; ``/map`` for a map_server's map)."""
import json
import re
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]


def node_topics() -> set[str]:
    """The topics of the node's topic table in docs/node.md, fully qualified."""
    text = (REPO / "docs" / "node.md").read_text()
    table = text.split("## Topics", 1)[1].split("\n\n", 2)[1]
    names = re.findall(r"^\| `([a-z_/<>]+)`", table, re.M)
    assert {"poses", "markers", "walls", "diagnostics", "navigation_field"} <= set(names)
    return {"/" + n for n in names if "<" not in n} | {"/map"}


def panels(tree) -> list[str]:
    if isinstance(tree, str):
        return [tree]
    return panels(tree["first"]) + panels(tree["second"])


def test_foxglove_layout_shows_the_node_topics() -> None:
    layout = json.loads((REPO / "config" / "foxglove_layout.json").read_text())
    used = panels(layout["layout"])
    assert sorted(used) == sorted(layout["configById"])
    three_d = next(v for k, v in layout["configById"].items() if k.startswith("3D!"))
    shown = {t for t, cfg in three_d["topics"].items() if cfg.get("visible")}
    assert {"/poses", "/markers", "/walls", "/navigation_field"} <= shown
    topics = node_topics()
    assert set(three_d["topics"]) <= topics
    for key, cfg in layout["configById"].items():
        if "topicToRender" in cfg:
            assert cfg["topicToRender"] == "/diagnostics", key
        if "topicPath" in cfg:
            assert cfg["topicPath"].split(".")[0] in topics, key
        for path in cfg.get("paths", []):
            assert path["value"].split(".")[0] in topics, key


def test_rviz_config_shows_the_node_topics() -> None:
    config = yaml.safe_load((REPO / "config" / "sweep.rviz").read_text())
    manager = config["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "map"
    displays = {d["Name"]: d for d in manager["Displays"]}
    topics = {d["Topic"]["Value"] for d in displays.values() if "Topic" in d}
    assert {"/poses", "/markers", "/walls", "/navigation_field"} <= topics <= node_topics()
    # the latched topics are read transient-local, or a late RViz sees nothing of them
    for d in displays.values():
        if "Topic" in d and d["Topic"]["Value"] in ("/walls", "/navigation_field", "/map"):
            assert d["Topic"]["Durability Policy"] == "Transient Local", d["Name"]
    tool_topics = {t["Topic"]["Value"] for t in manager["Tools"] if "Topic" in t}
    assert tool_topics <= node_topics() | {"/goal"}
