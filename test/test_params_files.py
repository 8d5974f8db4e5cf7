"""--params-file files are checked before rclpy parses them: a broken file is one line naming
the file, the line and the fix, instead of rcl's traceback."""
from __future__ import annotations

import pytest

from sweep_ros import params_files

GOOD = "/**:\n  ros__parameters:\n    dt: 0.02\n    seed: 3\n"

# (case, file text or None for no file, words of the one-line problem)
BROKEN = [
    ("syntax", "/**:\n  ros__parameters:\n    dt: [0.01\n    seed: 1\n",
     "line 4 column 9: did not find expected ',' or ']'"),
    ("bad indentation", "/**:\n  ros__parameters:\n    dt: 0.01\n   seed: 1\n", "line 4 column"),
    ("tab", "/**:\n\tros__parameters:\n", "line 2 column 1"),
    ("missing", None, "cannot read it (No such file or directory)"),
    ("top-level list", "- dt\n- seed\n", "line 1: the top level is a list"),
    ("top-level value", "dt\n", "line 1: the top level is a single value"),
    ("empty", "", "is empty"),
    ("no ros__parameters", "sweep_node:\n  dt: 0.01\n",
     "line 2: 'dt' has a value where a node name or ros__parameters is expected"),
    ("ros__parameters not a mapping", "/**:\n  ros__parameters: 5\n",
     "line 2: ros__parameters of /** is not a mapping"),
    ("value after ros__parameters", "/**:\n  ros__parameters:\n    dt: 0.1\n  foo: 1\n",
     "line 4: 'foo' has a value"),
    ("mixed list", "/**:\n  ros__parameters:\n    xs: [1, 2.0]\n",
     "line 3: parameter xs is a list mixing double and integer items"),
    ("another node", "other_node:\n  ros__parameters:\n    dt: 0.01\n",
     "no ros__parameters applies to node /sweep_node (its entries are for ['/other_node'])"),
    ("python tag", "/**:\n  ros__parameters:\n    dt: !!python/object:os.system x\n",
     "line 3 column 9: could not determine a constructor"),
    ("deep nesting", "/**:\n  ros__parameters:\n    dt: " + "[" * 100 + "]" * 100 + "\n",
     "line 3 column 70: nesting deeper than 64 levels"),
    ("key twice", "/**:\n  ros__parameters:\n    dt: 0.01\n    seed: 1\n    dt: 0.02\n",
     "line 5 column 5: key 'dt' is given twice in one mapping (first at line 3)"),
    ("alias bomb", "/**:\n  ros__parameters:\n    b0: &b0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n"
     + "".join(f"    b{k}: &b{k} [{', '.join([f'*b{k - 1}'] * 10)}]\n" for k in range(1, 7)),
     "aliases repeat more than 100000 nodes"),
]

#: what rcl itself does with each broken file (True: rclpy.init raises)
RCL_REFUSES = {"syntax", "bad indentation", "tab", "missing", "top-level list",
               "no ros__parameters", "ros__parameters not a mapping",
               "value after ros__parameters", "mixed list", "alias bomb"}


def write(tmp_path, name, text):
    path = tmp_path / f"{name.replace(' ', '_')}.yaml"
    if text is not None:
        path.write_text(text)
    return str(path)


def argv(*paths: str) -> list[str]:
    out = ["sweep_node", "--ros-args", "-p", "rate_hz:=10.0"]
    for p in paths:
        out += ["--params-file", p]
    return out


@pytest.mark.parametrize("case, text, words", BROKEN, ids=[b[0] for b in BROKEN])
def test_broken_params_file_is_one_line(tmp_path, case, text, words):
    path = write(tmp_path, case, text)
    problems = params_files.check_params_files(argv(path))
    assert len(problems) == 1, problems
    msg = problems[0]
    assert msg.startswith(f"params file {path}"), msg
    assert words in msg, msg
    assert "(fix: " in msg and msg.endswith(")") and "\n" not in msg, msg


def test_good_files_pass_and_every_file_is_checked(tmp_path):
    good = write(tmp_path, "good", GOOD)
    named = write(tmp_path, "named", "sweep_node:\n  ros__parameters:\n    dt: 0.02\n")
    nested = write(tmp_path, "nested", "/**:\n  ros__parameters:\n    solver:\n      a: 1\n")
    assert params_files.check_params_files(argv(good, named, nested)) == []
    assert params_files.check_params_files(["sweep_node"]) == []
    bad = write(tmp_path, "bad", "- 1\n")
    problems = params_files.check_params_files(argv(good, bad, str(tmp_path / "none.yaml")))
    assert [p.split(":")[0].split(" line")[0] for p in problems] == [
        f"params file {bad}", f"params file {tmp_path / 'none.yaml'}"]


def test_bundled_config_passes():
    from pathlib import Path
    config = Path(__file__).resolve().parents[1] / "config" / "sweep_node.yaml"
    assert params_files.check_params_files(argv(str(config))) == []


def test_node_name_and_namespace_remaps_are_followed(tmp_path):
    path = write(tmp_path, "ns", "crowd:\n  sim:\n    ros__parameters:\n      dt: 0.02\n")
    assert params_files.check_params_files(argv(path))  # not for /sweep_node
    assert params_files.check_params_files(argv(path) + ["-r", "__ns:=/crowd", "-r",
                                                          "__node:=sim"]) == []
    assert params_files.node_fqn(["x", "--ros-args", "--remap", "__ns:=/a/b"], "n") == "/a/b/n"
    wild = write(tmp_path, "wild", "/*/sim:\n  ros__parameters:\n    dt: 0.02\n")
    assert params_files.check_params_files(argv(wild) + ["-r", "__ns:=/crowd", "-r",
                                                          "__node:=sim"]) == []


def test_params_files_found_only_inside_ros_args():
    assert params_files.params_files(["x", "--params-file", "a.yaml"]) == []
    assert params_files.params_files(["x", "--ros-args", "--params-file", "a.yaml", "--", "y",
                                      "--ros-args", "--params-file", "b.yaml"]) == ["a.yaml", "b.yaml"]
    assert params_files.check_params_files(["x", "--ros-args", "--params-file"]) == [
        "--params-file: no file after it (fix: write --params-file FILE inside --ros-args)"]


@pytest.mark.parametrize("case, text, words", BROKEN, ids=[b[0] for b in BROKEN])
def test_rcl_agrees_on_what_it_refuses(tmp_path, case, text, words):
    """Every file rcl refuses (with a traceback from rclpy.init) is caught first."""
    import rclpy
    from rclpy.context import Context
    path = write(tmp_path, case, text)
    ctx = Context()
    try:
        rclpy.init(args=["sweep_node", "--ros-args", "--params-file", path], context=ctx)
    except Exception:  # noqa: BLE001 - rclpy's RCLError is not importable by a stable name
        refused = True
    else:
        refused = False
        ctx.try_shutdown()
    assert refused == (case in RCL_REFUSES)
    assert params_files.check_params_files(argv(path))
