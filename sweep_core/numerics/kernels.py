"""The compiled kernels, compiled (or loaded from numba's cache) before the first step.

numba compiles a kernel at its first call and keeps the machine code on disk (``cache=True``:
``__pycache__`` beside the module, or numba's user cache directory where the package is
read-only; ``NUMBA_CACHE_DIR`` moves it), one entry per CPU model, which every entry point
(``sweep run``, ``sweep_node``, ``sweep analyze``, an ensemble's workers) shares. Compiling
them all takes 10 to 40 s on two cores, once per machine; loading them from the cache takes a
fraction of a second. :func:`warm_up` makes that moment a known one, before anything is timed
or published: it calls every kernel through the code paths a simulation takes (both
neighbour searches, segment walls and obstacles, a geodesic field, the certified rounds and
the face step, the bridge scheme), on a small bundled jam, and reports what it compiled.
"""
from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from types import ModuleType

import numpy as np
import scipy.sparse as sp
from numba.core.registry import CPUDispatcher

from sweep_core.model import elementary, fields, neighbours, wall_kernels
from sweep_core.model.scene import Scene
from sweep_core.numerics import (
    constraints,
    csm,
    entry,
    exit_choice,
    headway,
    noise,
    schemes,
    ziggurat,
)
from sweep_core.numerics.projection import certified, clear, dual, pairwise, small, summaries
from sweep_core.numerics.projection.clusters import solve_active
from sweep_core.numerics.robots import (
    clear_step,
    contacts,
    control,
    episode,
    guard,
    overlaps,
    small_step,
    social_kernels,
    window,
)
from sweep_core.numerics.robots import scan as robot_scan
from sweep_core.numerics.simulator import Simulator

#: the modules that hold compiled kernels
MODULES: tuple[ModuleType, ...] = (neighbours, wall_kernels, dual, schemes, robot_scan,
                                   noise, constraints, guard, social_kernels, window, contacts,
                                   control, clear, overlaps, clear_step, small, summaries,
                                   small_step, episode, ziggurat)

#: the message shown while kernels compile
COMPILING = "compiling kernels, first run on this machine (cached for later runs)"


@dataclass(frozen=True)
class WarmUp:
    """What :func:`warm_up` did: ``seconds`` (s) it took, ``compiled`` kernel signatures it
    compiled (0: all came from the cache)."""

    seconds: float
    compiled: int


def kernels_in(modules: Iterable[ModuleType]) -> list[CPUDispatcher]:
    """The compiled kernels defined in ``modules`` (a kernel a module imports from another is
    the other's), each once, in the modules' order."""
    seen: dict[int, CPUDispatcher] = {}
    for module in modules:
        for value in list(vars(module).values()):
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == module.__name__:
                seen[id(value)] = value
    return list(seen.values())


#: the kernels the last scan found, and the state of ``sys.modules`` it saw (see dispatchers)
_found: tuple[tuple[int, str], list[CPUDispatcher]] | None = None


def dispatchers() -> list[CPUDispatcher]:
    """Every compiled kernel of the engine: those of :data:`MODULES` and of any other
    ``sweep_core`` module imported so far.

    The modules are scanned once, and again only after an import (``sys.modules`` has another
    length or another newest entry): every kernel is decorated at its module's top level, so
    no import, no new kernel. (A module reloaded in place is not scanned again.)"""
    global _found
    modules = sys.modules
    try:
        key: tuple[int, str] | None = (len(modules), next(reversed(modules)))
    except RuntimeError:  # another thread imported meanwhile: scan
        key = None
    found = _found
    if found is None or found[0] != key:
        named = {m.__name__: m for m in MODULES}
        named.update((name, m) for name, m in list(modules.items())
                     if name.startswith("sweep_core.") and m is not None)
        found = (key or (-1, ""), kernels_in(named.values()))
        _found = found
    return list(found[1])


def compiled_count() -> int:
    """Kernel signatures compiled in this process so far (not loaded from the cache), read
    from the kernels' own counters at each call (cheap: the node asks once a second)."""
    return sum(sum(d.stats.cache_misses.values()) for d in dispatchers())


def uncached() -> list[str]:
    """The kernels (module.name) with no entry in numba's on-disk cache for this CPU and this
    source: all of them when that cannot be told (the cache is then taken to be cold)."""
    out = []
    for d in dispatchers():
        try:  # numba's cache index (not a public API): entries keyed by (signature, the
            # CPU's magic tuple: triple, name, features, ...); empty when the source changed
            entries = d._cache._cache_file._load_index()  # type: ignore[attr-defined]
            here = d.targetctx.codegen().magic_tuple()  # type: ignore[attr-defined]
            ok = any(isinstance(k, tuple) and len(k) > 1 and k[1] == here for k in entries)
        except Exception:  # numba's cache layout changed, or an unreadable index
            ok = False
        if not ok:
            out.append(f"{d.py_func.__module__}.{d.py_func.__name__}")
    return out


def cached() -> bool:
    """Whether every kernel has an entry in numba's on-disk cache."""
    return not uncached()


def _room(robot: bool = True) -> Scene:
    """Two people walking into each other beside a prescribed robot (or none), in a room of a
    segment wall, a half-plane and a circle obstacle, nothing moving (the small scenes'
    compiled paths: the robots' step, or the scheme's projection)."""
    kin = {"type": "holonomic", "max_speed": 1.0}
    robots = [{"name": "robot", "radius": 0.3, "pose": [0.2, -0.5, 0.0], "kinematics": kin,
               "weight": "inf"}] if robot else []
    return Scene.from_dict({
        "agents": {"positions": [[0.0, 0.0], [0.4, 0.0]], "radius": 0.2},
        "drift": {"kind": "goal", "goal": [0.2, 0.0], "speed": 1.0},
        "walls": [{"kind": "segment", "a": [-2.0, -1.0], "b": [2.0, -1.0]},
                  {"kind": "halfplane", "normal": [0.0, -1.0], "offset": -2.0}],
        "obstacles": [{"kind": "circle", "center": [0.25, 0.8], "radius": 0.2}],
        "robots": robots})


def _jam() -> Scene:
    """40 disks of two radii pressed into a 1.2 m door in a room of segment walls, with a
    circle and a polygon obstacle, a geodesic drift and noise."""
    pos = [[0.6 + 0.5 * (k % 8) + 0.25 * ((k // 8) % 2), 0.6 + 0.45 * (k // 8)]
           for k in range(40)]
    return Scene.from_dict({
        "name": "warm_up",
        "agents": {"positions": pos, "radius": [0.2 + 0.02 * (k % 3) for k in range(40)]},
        "walls": [{"kind": "polyline", "points": [[5.4, 2.4], [5.4, 3.2], [0, 3.2],
                                                  [0, 0], [5.4, 0], [5.4, 1.2]]},
                  {"kind": "halfplane", "normal": [0.0, 1.0], "offset": -1.0}],
        "obstacles": [{"kind": "circle", "center": [4.7, 2.7], "radius": 0.2},
                      {"kind": "polygon", "points": [[4.6, 0.3], [5.0, 0.3], [4.8, 0.6]]}],
        "drift": {"kind": "geodesic", "goal": [7.0, 1.8], "speed": 1.5},
        "noise": {"sigma": 0.1},
    })


def _exercise() -> None:
    """Every kernel, through the paths a simulation takes."""
    scene = _jam()
    for scheme in ("projected_euler", "bridge"):
        Simulator(scene, dt=0.02, seed=0, scheme=scheme).step(12)
    # neighbour searches on a crowd spread wide enough for the sorted cell lists
    rng = np.random.default_rng(0)
    far = rng.uniform(0.0, 400.0, (64, 2))
    neighbours.pairs_within(far, 1.0)
    neighbours.segments_within(far, far[:3], far[3:6], 1.0)
    neighbours.segments_within(far[:4], far[:3], far[3:6], 1.0)
    # the headway law's kernels (flows.headway)
    headway.headway(far[:8] * 0.01, np.full(8, 0.2), np.ones((8, 2)), 1.0)
    csm.csm(far[:8] * 0.01, np.full(8, 0.2), np.ones((8, 2)), 0.8, 2.0, 0.1)
    csm.csm(far[:8] * 0.01, np.full(8, 0.2), np.ones((8, 2)), 0.8, 2.0, 0.1, 0.7, 0.9, 0.9, 0.5)
    # the speed law's rules as Python calls them one by one (gaps_ahead, the analysis)
    q8, r8, u8 = far[:8] * 0.01, np.full(8, 0.2), np.ones((8, 2))
    pi, pj = neighbours.pairs_within(q8, 1.0)
    e8 = csm.directions(q8, r8, u8, pi, pj, 2.0, 0.1, np.zeros((0, 2)))
    s8, lead = csm.nearest_ahead(q8, r8, e8, pi, pj, 0.7, 0.9, 0.9)
    v8 = csm.speeds(u8, e8, s8, 0.8, np.zeros(8))
    csm.leader_push(v8, e8, lead, 0.5)
    exit_choice.assign(far[:8, :2].copy(), np.ones(2))
    # a source's room check (its grid over the disks present)
    entry.EntryGrid(np.zeros(2), np.ones(2), 0.5, far[:4] * 0.01, np.full(4, 0.2)).clear(
        far[:2] * 0.001, 0.2)
    # kernels a small jam may not reach (the factored face step's products, the bridge's
    # logarithm of a wall contact), called with the types their callers pass
    v = np.ones(3)
    dual.dot(v, v)
    dual.maximum(1.0, 2.0)  # inlined where the kernels call it; its own entry cached too
    dual.minimum(1.0, 2.0)  # (the same)
    # the certified rounds' helpers (called from compiled code; their own entries cached too)
    pairwise.numpy_sum(np.ones(300))
    pairwise.block_sum(v, 0, 3)
    certified.same_face(v, np.ones(3, dtype=np.bool_))
    certified.rounding_floor(np.ones((2, 2)), v)  # a cluster held from the rounds
    schemes.log_each(v)
    one = np.zeros(1, dtype=np.int64)
    dual.slacks(np.zeros((2, 2)), one, one - 1, np.ones((1, 2)), np.zeros(1))
    # the robots' gaps after a step (no robot in the jam)
    overlaps.robot_gaps(np.ones((1, 2)), np.ones(1), np.zeros((2, 2)), np.full(2, 0.2),
                        np.ones((1, 2)), np.zeros(1), np.zeros((1, 2)), np.ones((1, 2)),
                        np.zeros((0, 2)), np.zeros(0), np.empty(4))
    # the inline value helpers (compiled into the kernels above; their own entries cached too)
    wall_kernels.segment_foot(0.5, 1.0, 0.0, 0.0, 1.0, 0.0)
    wall_kernels.halfplane_value(0.5, 1.0, 0.0, 1.0, 0.0, 0.2)
    wall_kernels.disk_gap(0.5, 1.0, 0.0, 0.0, 0.2, 0.2)
    wall_kernels.unit(0.5, 1.0, 1.2)
    overlaps.keep_smallest(0.5, overlaps.PERSON, 0, 1, np.inf, -1, -1, -1)
    # a goal drift (the jam's is geodesic)
    two = np.array([[0.0, 0.0], [1.0, 0.0]])
    fields.towards_goal(1.0, 2.0, 1.0, 0.5, two, np.empty((2, 2)))
    # a small scene's prediction checked against its rows without building them (the jam's
    # polygon sends its steps to the rows)
    clear.clear_count(two, two, np.full(2, 0.2), 0.1, np.ones((1, 2)), np.zeros(1), two,
                      two + 1.0, two + 3.0, np.ones(2))
    # a small scene's projection in one call (the jam's polygon sends its steps to project's
    # own path), and a robot's step with contacts in one call: two people pressed together
    # beside a robot, steps warm-started from the one before
    Simulator(_room(), dt=0.02, seed=0).step(3)
    Simulator(_room(robot=False), dt=0.02, seed=0).step(3)
    # a simple robot step in one call (the jam has no robot; its polygon would send it back)
    clear_step.clear_robot_step(two, two, np.full(2, 0.2), np.array([[3.0, 0.0]]),
                                np.array([[3.1, 0.0]]), np.full(1, 0.3), np.ones(1, np.bool_),
                                np.ones((1, 2)), np.full(1, -5.0), two + 5.0, two + 6.0,
                                two + 9.0, np.ones(2), np.ones(2, np.bool_), 1 << 16, True,
                                np.empty(8, np.intp), np.empty(8, np.intp), np.empty(8),
                                np.empty(10), np.empty(4, np.intp), np.empty(4, np.intp),
                                np.empty(8, np.intp), np.empty(8, np.intp),
                                np.empty(8, np.bool_), np.empty(12))
    # ... and the end of a general robot step
    clear_step.clear_end(two, two, np.full(2, 0.2), np.array([[3.0, 0.0]]),
                         np.array([[3.1, 0.0]]), np.full(1, 0.3), np.ones((1, 2)),
                         np.full(1, -5.0), two + 5.0, two + 6.0, two + 9.0, np.ones(2),
                         np.ones(2, np.bool_), 1 << 16, True, np.empty(8, np.intp),
                         np.empty(8, np.intp), np.empty(8), np.empty(10), np.empty(4, np.intp),
                         np.empty(4, np.intp), np.empty(8, np.intp), np.empty(8, np.intp),
                         np.empty(8, np.bool_), np.empty(12))
    # the crossing test of a path that reaches a wall segment (no step of the jam does)
    wall_kernels.paths_meet_exactly(np.zeros((1, 2)), np.ones((1, 2)), np.array([[0.0, 1.0]]),
                                    np.array([[1.0, 0.0]]))
    # the exact path of small clusters: two agents pressed together against a wall
    rows = sp.csr_matrix(np.array([[1.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0]]))
    solve_active(np.array([0.1, -0.2, -0.1, 0.0]), rows, np.array([0.05, 0.0]))
    # a robot's scan (the ray cast against disks, segments and half-planes)
    robot_scan.ray_cast(0.0, 0.0, np.ones(2), np.zeros(2), np.ones((1, 2)), np.ones(1),
                        np.ones((1, 2)), 2 * np.ones((1, 2)), np.ones((1, 2)), np.ones(1), 5.0)
    # its noise and REP 117 marks
    ranges = np.array([1.0, np.inf])
    robot_scan.finish_ranges(ranges, np.ones(robot_scan.finite_count(ranges)), 0.01, 0.05, 5.0)
    # a scan's noise drawn in its compiled call (numpy's PCG64 stream and ziggurat), and the
    # whole scan in one call
    noise.key_normals(noise.seed_words(0), 0, 1, 2)
    ziggurat.standard_normals(noise.pcg64_start(np.zeros(3, dtype=np.uint64)), np.empty(2))
    pcg = np.ones(4, dtype=np.uint64)  # the helpers compiled into them (own entries too)
    ziggurat.next_double(pcg), ziggurat.next_uint64(pcg), ziggurat.standard_normal(pcg)
    ziggurat.lcg_step(pcg)
    ziggurat.mul_high(np.uint64(3), np.uint64(5))
    robot_scan.scan_ranges(0.0, np.zeros(2), 0.0, 0.0, np.ones((1, 2)), np.ones(1),
                           np.ones((1, 2)), 2 * np.ones((1, 2)), np.ones((1, 2)), np.ones(1),
                           0.05, 5.0, 0.01, noise.seed_words(0), 0, 1)
    # the environment's observation of them (NaN and infinite ranges bounded)
    robot_scan.bounded_ranges(ranges, 5.0, np.empty(2))
    # the sampling planner's forecast of the people it sees
    window.hazards(np.ones((2, 2)), np.zeros(2), 0.3, np.ones((1, 2)), np.full(1, 0.2),
                   np.zeros((1, 2)), 1.5, 1.0, 0.6, 0.3, 0.1, 0.25, 1.0, 0.1, 1.0, np.empty(2))
    # the elementary functions as Python calls them (scalars and arrays)
    for f in (elementary.sin, elementary.cos, elementary.exp, elementary.log):
        f(0.5)
    elementary.sincos(0.5)
    elementary.atan2(0.5, 1.0)
    elementary.sin_of(v), elementary.cos_of(v), elementary.exp_of(v), elementary.atan2_of(v, v)
    elementary.z_rotations(v, np.empty((3, 4)))  # the markers' orientations
    # the planners' safety layer, with and without people's noise (its root's start helper
    # compiled into it; its own entry cached too)
    for people_noise in (0.0, 0.05):
        guard.nearest_safe(np.array([1.0, 0.0]), (0.0, 0.0, 0.0), 0.3, np.ones((1, 2)),
                           np.ones(1) * 0.2, 1.0, 0.05, 0.5, people_noise=people_noise)
    guard.start(1.0, 1.0, 1.0, 1.0)
    # and its walls (a segment and a circle obstacle ahead)
    guard.Walls(np.zeros(2), 0.3, np.ones((1, 2)), 2 * np.ones((1, 2)), np.ones((1, 2)),
                np.ones(1), 1.0, 0.1).speeds(np.array([[1.0, 0.0]]))
    # the social-force planner's people term
    grad = np.ones((1, 2))
    social_kernels.people_terms(np.ones((1, 2)), np.zeros((1, 2)), np.empty(1), grad,
                                np.empty((1, 2)))
    social_kernels.pushes(grad, np.ones(1), np.ones(1), np.zeros(2))
    social_kernels.track(np.ones((1, 2)), np.ones((1, 2)), np.zeros((1, 2)), 0.1, 0.2, 0.25,
                         np.zeros((1, 2)))
    social_kernels.near_segments(0.0, 0.0, np.zeros((1, 2)), np.ones((1, 2)), 1.0,
                                 np.empty(1, dtype=np.bool_))
    robot_scan.beam_directions(0.0, robot_scan.ScanSpec(0.1, 1.0, -1.0, 1.0, 0.5, 10.0, 0.0))
    rel, d = np.empty((1, 2)), np.empty(1)
    social_kernels.wall_offsets(0.0, 0.0, np.zeros((1, 2)), np.ones((1, 2)), rel, d)
    social_kernels.scaled_sum(np.ones(1), rel, d)
    # the people a controller sees (of a scene without robots, none is observed)
    control.within_reach(np.ones((1, 2)), np.ones(1), 0.0, 0.0, 8.0, np.empty(1, dtype=np.bool_))
    # a robot's contacts from the projection's rows (a prescribed disk's, a free robot's)
    one8 = np.full(1, 2, dtype=np.int8)
    ids, imp = np.empty(1, dtype=np.int64), np.empty((1, 2))
    contacts.circle_contacts(one8, one, one, np.ones((1, 2)), np.ones(1), 2, 0, 0.1, ids, imp)
    contacts.pair_contacts(one, one + 1, np.ones((1, 2)), np.ones(1), 1, 1, 0.1, ids, imp)
    social_kernels.nearest_pass(0.0, 0.0, 0.0, 0.0, 0.3, np.ones((1, 2)), np.ones(1),
                                np.zeros((1, 2)), np.empty(3))
    # the environment's record of a step (the people's pass, the goal field's distance, the
    # observation), with people and without
    grid = (np.arange(3.0), np.arange(2.0), np.ones((2, 3, 1)))
    for n in (1, 0):
        episode.record(0.5, 0.5, 0.1, 1.0, 0.0, 0.2, 0.1, 0.3, np.ones((n, 2)), np.ones(n),
                       np.zeros((n, 2)), *grid, 2.0, 1.0, n, np.ones((n, 2)), ranges, 5.0,
                       np.empty(episode.OUT), np.empty(6), np.empty(2), np.empty(2))
    # perf7: a scan's directions, ray cast and hit count in one call
    robot_scan.cast_beams(0.0, np.zeros(2), 0.0, 0.0, np.ones((1, 2)), np.ones(1),
                          np.ones((1, 2)), 2 * np.ones((1, 2)), np.ones((1, 2)), np.ones(1), 5.0)


def warm_up(notify: Callable[[str], None] | None = None) -> WarmUp:
    """Compiles every kernel of the engine, or loads it from the cache.

    ``notify`` (e.g. ``print`` to stderr, a logger) hears :data:`COMPILING` at once when the
    cache holds no entry for this CPU and source (first run on a machine, a cache made on
    another CPU, a changed source), then one line with the time; nothing when the cache was
    warm, however long loading takes.
    """
    start = time.perf_counter()
    before = compiled_count()
    said = False
    if notify is not None and not cached():
        said = True
        notify(COMPILING)
    _exercise()
    done = WarmUp(time.perf_counter() - start, compiled_count() - before)
    if notify is not None and (said or done.compiled):
        notify(f"kernels ready: {done.compiled} compiled in {done.seconds:.1f} s"
               if done.compiled else f"kernels loaded from the cache in {done.seconds:.1f} s")
    return done

