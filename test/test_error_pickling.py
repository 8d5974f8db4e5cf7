"""Every exception class sweep_core and sweep_ros define survives pickling: the same type,
message and attributes after ``pickle.loads(pickle.dumps(err))``, so a worker process (a
``sweep bench social --workers 2`` pool, an ensemble's Dask worker) that raises one hands its
parent that error, not a broken pool."""
from __future__ import annotations

import importlib
import pickle
import pkgutil
import signal
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import pytest
import yaml

import sweep_core
import sweep_ros
from sweep_core.errors import SceneError

#: packages a sweep_ros module may need that a machine without ROS lacks
ROS_PACKAGES = ("rclpy", "builtin_interfaces", "std_msgs", "std_srvs", "geometry_msgs",
                "sensor_msgs", "nav_msgs", "visualization_msgs", "diagnostic_msgs",
                "rosgraph_msgs", "tf2_msgs", "ament_index_python", "rosidl_runtime_py")


def _yaml_limit() -> BaseException:
    from sweep_core.model.yaml_files import YAMLLimitError

    err = YAMLLimitError(problem="nesting deeper than 64 levels",
                         problem_mark=yaml.Mark("scene.yaml", 120, 7, 3, None, None))
    err.fix = "flatten the document"
    err.cost = True
    return err


#: "module.Class": how to build a representative instance (its module is imported first)
EXAMPLES: dict[str, Callable[[Any], BaseException]] = {
    "sweep_core.errors.SweepError": lambda m: m.SweepError("something failed"),
    "sweep_core.errors.SceneError": lambda m: m.SceneError(
        "agents.radius", "-0.2 is negative", "give a radius > 0 m"),
    "sweep_core.errors.CostError": lambda m: m.CostError(
        "sources[0].count", "1e9 agents", "emit at most 1e6"),
    "sweep_core.errors.InfeasibleError": lambda m: m.InfeasibleError(
        2.5, [3, 4], "residual 1e-3", "use a smaller dt"),
    "sweep_core.errors.RecordingError": lambda m: m.RecordingError("run.mcap: truncated"),
    "sweep_core.errors.WorkerError": lambda m: m.WorkerError(
        "worker 1 of the vector environment has ended (exit code -9): close it and make a new "
        "one"),
    "sweep_core.errors.OutputError": lambda m: m.OutputError(
        "out.mcap", "it is a folder", "name a file"),
    "sweep_core.model.json_text.JSONLimitError": lambda m: m.JSONLimitError(
        "more than 1e6 nodes", "give the list by a rule", True),
    "sweep_core.model.yaml_files.YAMLLimitError": lambda m: _yaml_limit(),
    "sweep_core.io.live.LiveError": lambda m: m.LiveError("port 8765 is in use (fix: --port 0)"),
    "sweep_core.io.recording.chunks.ChunkError": lambda m: m.ChunkError("chunk 3: bad CRC"),
    "sweep_core.cli.run.Interrupted": lambda m: m.Interrupted(int(signal.SIGTERM)),
    "sweep_core.verify.base._Done": lambda m: m._Done(),
    "sweep_ros.errors.StartError": lambda m: m.StartError(["dt: -1 is negative", "scene: none"]),
    "sweep_ros.messages.CommandError": lambda m: m.CommandError("crowd/cmd_vel", "NaN speed"),
    "sweep_ros.msgdefs.MsgDefError": lambda m: m.MsgDefError("'x' is not a message type name"),
    "sweep_ros.client.ClientError": lambda m: m.ClientError("no node found"),
    "sweep_ros.client.Unanswered": lambda m: m.Unanswered("the node refused"),
}


def _import(name: str) -> Any:
    """The module ``name``, or a skip when it needs a ROS package this machine lacks."""
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as err:
        if (err.name or "").split(".")[0] in ROS_PACKAGES:
            pytest.skip(f"{name} needs {err.name}, not installed here")
        raise


def _plain(value: Any) -> Any:
    """value with every object replaced by its type and attributes (for ==)."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if hasattr(value, "__dict__") and not isinstance(value, type):
        return (type(value), _plain(vars(value)))
    return value


def test_every_exception_class_has_an_example() -> None:
    """Every exception class defined in a module of sweep_core or sweep_ros is in EXAMPLES
    (a new one is then checked below)."""
    found = set()
    for pkg in (sweep_core, sweep_ros):
        for info in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            if info.name.endswith("__main__"):
                continue  # runs the command line
            try:
                module = importlib.import_module(info.name)
            except ModuleNotFoundError as err:
                if (err.name or "").split(".")[0] in ROS_PACKAGES:
                    continue  # its classes are skipped below too
                raise
            for value in vars(module).values():
                if (isinstance(value, type) and issubclass(value, BaseException)
                        and value.__module__ == info.name):
                    found.add(f"{info.name}.{value.__qualname__}")
    assert found - set(EXAMPLES) == set(), "add representative arguments for these"
    assert set(EXAMPLES) - found == set(), "these are not defined (or not found) any more"


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_the_error_survives_pickling(name: str) -> None:
    module = _import(name.rsplit(".", 1)[0])
    err = EXAMPLES[name](module)
    assert f"{type(err).__module__}.{type(err).__qualname__}" == name
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is type(err)
    assert str(back) == str(err)
    assert back.args == err.args
    assert _plain(vars(back)) == _plain(vars(err))


def _refuse_in_worker(field: str) -> None:
    raise SceneError(field, "is not a scene key", "remove it")


def test_a_pool_worker_hands_its_scene_error_to_the_parent() -> None:
    """A SceneError raised in a ProcessPoolExecutor's worker comes back to the parent as that
    SceneError (its one-line message), not as a broken pool."""
    with ProcessPoolExecutor(1) as pool:
        future = pool.submit(_refuse_in_worker, "agents.colour")
        with pytest.raises(SceneError) as caught:
            future.result(timeout=600)
    assert (caught.value.field, caught.value.problem, caught.value.fix) == (
        "agents.colour", "is not a scene key", "remove it")
    assert str(caught.value) == "agents.colour: is not a scene key (fix: remove it)"


def test_an_infeasible_error_built_from_one_is_its_copy() -> None:
    """``type(err)(err)``, how Gymnasium's AsyncVectorEnv raises a worker's error again, gives
    the same error (time, agents, detail, the fix as given), not a TypeError."""
    from sweep_core.errors import InfeasibleError

    for err in (InfeasibleError(1.25, [3, 4], "rows broken by 2e-3 m"),
                InfeasibleError(0.5, [], "a robot overlaps", fix="stop the robot")):
        again = InfeasibleError(err)
        assert (again.t, again.agents, again.detail, again.fix, str(again)) == (
            err.t, err.agents, err.detail, err.fix, str(err))
    with pytest.raises(TypeError):
        InfeasibleError(1.0)  # type: ignore[call-arg]


@pytest.mark.parametrize("name", ["sweep_core.errors.SceneError", "sweep_core.errors.CostError",
                                  "sweep_core.errors.InfeasibleError",
                                  "sweep_core.errors.OutputError"])
def test_an_error_built_from_one_of_its_kind_is_its_copy(name: str) -> None:
    """``type(err)(err)``, how Gymnasium's AsyncVectorEnv raises a worker's error again, gives
    the same error (type, message, attributes), not a TypeError; a call with neither the
    arguments nor such an error is a TypeError."""
    module = _import(name.rsplit(".", 1)[0])
    err = EXAMPLES[name](module)
    again = type(err)(err)
    assert type(again) is type(err) and str(again) == str(err) and again.args == err.args
    assert _plain(vars(again)) == _plain(vars(err))
    with pytest.raises(TypeError):
        type(err)("only the first argument")
