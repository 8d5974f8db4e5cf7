"""``gymnasium.make_vec("sweep/CrowdNav-v0", num_envs=K, vectorization_mode="vector_entry_point")``:
K independent crowds stepped by one call.

Each of the K environments is a :class:`~sweep_core.envs.crowdnav.CrowdNavEnv` of the same
scene and arguments, so environment i's episodes are those of the single environment reset
with the same seed, bit for bit: the same observations, rewards and infos. ``reset(seed=s)``
seeds environment i with s + i (Gymnasium's convention for vector environments), or with
``seed[i]`` for a list of K seeds. Autoreset is Gymnasium's next-step mode
(``metadata["autoreset_mode"]``): the step after environment i's episode ended resets it (its
action ignored) and returns its first observation, reward 0 and not done.
``reset(options={"reset_mask": mask})`` resets only the environments ``mask`` marks, as
Gymnasium's SyncVectorEnv does (:meth:`CrowdNavVectorEnv.reset`). A step (or reset) that
fails in one environment, after others have taken theirs, leaves the batch out of step: the
error is raised, and then every step and masked reset is refused until ``reset()`` starts
every environment again.

With ``workers`` W > 1 the K environments are split into W contiguous shares, each stepped
by its own process (:mod:`sweep_core.envs.workers`), so that W cores step the batch at once;
the episodes, observations, rewards and infos are the same bit for bit as with one.

Observations are the single observation's arrays stacked (``odom`` (K, 6), ``scan`` (K, B),
``goal`` (K, 2)); rewards, terminations and truncations (K,); infos as Gymnasium's vector
environments combine them (each key an array over the K environments, ``_key`` the mask of
those that have it; ``metrics`` at the end of an episode).
"""
from __future__ import annotations

import tracemalloc
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from sweep_core import checks
from sweep_core.envs.crowdnav import (
    ARGUMENTS,
    DEFAULT_SCENE,
    MEMORY_SHARE,
    NO_RENDER,
    CrowdNavEnv,
    available_memory,
    check_options,
    check_render_mode,
    refuse_unknown,
    seed_value,
)
from sweep_core.envs.memory import check_workers, memory_need, memory_refusal
from sweep_core.envs.workers import Workers, reset_all, stack, step_share
from sweep_core.errors import SceneError, show
from sweep_core.model.scene import Scene, load_scene
from sweep_core.numerics import kernels

#: the info values combined in one pass per key (:meth:`CrowdNavVectorEnv._combine`)
_SCALARS = (int, float, bool)

#: most environments of one vector environment, whatever the memory
MAX_ENVS = 100_000


#: steps of the traced environment over which its memory's growth per step is measured
GROWTH_STEPS = 16


def _memory_of(build: Any) -> tuple[float, float, int]:
    """(bytes one environment keeps, bytes its history grows by per step, scratch bytes), from
    which :func:`.memory.memory_need` gives what K environments take at the end of their longest
    episode (``max_steps``): one
    more environment (after a first has paid the one-time costs) built, reset and stepped
    with its Python and numpy allocations traced; what it keeps after one step, plus what
    its episode's history grows by per step (measured over :data:`GROWTH_STEPS` steps) times
    ``max_steps``, K times; and once its scratch (the traced peak above what it keeps),
    freed before the next is built. Measured against the peak resident memory of K = 96
    environments in test_estimates (the traced peak of a single first environment, the
    earlier estimate, counted imports and compiled kernels K times)."""
    tracing = tracemalloc.is_tracing()
    if not tracing:
        tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        env = build()
        env.reset(seed=0)
        action = np.zeros(env.action_space.shape)
        env.step(action)
        kept, peak = tracemalloc.get_traced_memory()
        steps = 0
        while steps < min(GROWTH_STEPS, env.max_steps - 1):
            steps += 1
            if any(env.step(action)[2:4]):  # its episode ended
                break
        grown = max(tracemalloc.get_traced_memory()[0] - kept, 0)
        return float(kept - before), grown / max(steps, 1), max(peak - kept, 0)
    finally:
        if not tracing:
            tracemalloc.stop()


def _check_memory(k: int, w: int, first: CrowdNavEnv, build: Any,
                  options: Mapping[str, str] | None = None) -> int:
    """The memory (bytes) K environments take at the end of ``first``'s longest episode,
    measured on one more (``build()``, :func:`_memory_of`; ``first`` has paid the one-time
    costs); refused (SceneError) when it, or it and W > 1 worker processes, need more than
    MEMORY_SHARE of the available memory."""
    measured = _memory_of(build)
    need = memory_need(k, first.max_steps, measured)
    have = available_memory()
    if need > MEMORY_SHARE * have:
        raise memory_refusal(k, first.max_steps, measured, have, options)
    if w > 1:
        check_workers(w, need, have, options)
    return need


def _first(scene: Any, kwargs: dict[str, Any]) -> tuple[Scene | dict, CrowdNavEnv]:
    """The scene (a path read once, to be shared) and a first environment of it, reset and
    stepped once (it pays the one-time costs: imports, kernels)."""
    if not isinstance(scene, (Scene, dict)):
        scene = load_scene(str(scene if scene is not None else DEFAULT_SCENE))
    first = CrowdNavEnv(scene=scene, **kwargs)
    first.reset(seed=0)
    first.step(np.zeros(first.action_space.shape))
    return scene, first


def check_memory(num_envs: int, workers: int = 1, options: Mapping[str, str] | None = None,
                 **kwargs: Any) -> int:
    """What :class:`CrowdNavVectorEnv` (``num_envs``, ``workers``, ``**kwargs``) checks of the
    memory, without building its environments or starting its workers: the estimate (bytes),
    or its SceneError, naming the arguments as ``options`` maps them (e.g. ``{"num_envs":
    "--num-envs"}``: a command's options), so that a command refuses them before other work."""
    scene, first = _first(kwargs.pop("scene", None), kwargs)
    try:
        return _check_memory(num_envs, workers, first,
                             lambda: CrowdNavEnv(scene=scene, **kwargs), options)
    finally:
        first.close()


class CrowdNavVectorEnv(VectorEnv):
    """K :class:`CrowdNavEnv` stepped together (module docstring).

    Args:
        num_envs: K, the number of environments (1 to :data:`MAX_ENVS`, and as many as half
            the available memory holds: the first environment's size times K, checked before
            the others are built).
        workers: W, the processes stepping the K environments (1: this one; 1 to K, and as
            many as half the available memory holds beside the environments).
        **kwargs: the arguments of :class:`CrowdNavEnv` (scene, robot, dt, max_steps, ...).
    """

    metadata: dict[str, Any] = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, workers: int = 1, **kwargs: Any) -> None:
        check_render_mode(kwargs.pop("render_mode", None))
        self.render_mode = None
        refuse_unknown({k: v for k, v in kwargs.items() if k not in ARGUMENTS},
                       ("num_envs", "workers", *ARGUMENTS))
        k = checks.integer(num_envs, "num_envs", low=1, fix="e.g. num_envs=32")
        if k > MAX_ENVS:
            raise SceneError("num_envs", f"{k} is more than the limit {MAX_ENVS}",
                             f"num_envs={MAX_ENVS} or fewer")
        w = checks.integer(workers, "workers", low=1, fix="e.g. workers=2, one per core")
        if w > k:
            raise SceneError("workers", f"{w} is more than the {k} environments",
                             f"workers={k} or fewer")
        scene, first = _first(kwargs.pop("scene", None), kwargs)
        self.memory_estimate = _check_memory(k, w, first,
                                             lambda: CrowdNavEnv(scene=scene, **kwargs))
        if w > 1:
            # every kernel loaded before the workers fork, so that they share the loaded code
            # instead of each loading what its first steps call, in those steps
            kernels.warm_up()
        # built afresh: the measured one's generator was seeded (reset(seed=None) draws anew)
        self.workers = Workers(k, w, scene, kwargs) if w > 1 else None
        self.envs = [] if w > 1 else [CrowdNavEnv(scene=scene, **kwargs) for _ in range(k)]
        self.num_envs = k
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(first.observation_space, k)
        self.action_space = batch_space(first.action_space, k)
        self.width = int(first.action_space.shape[0])
        self._done = np.zeros(k, dtype=np.bool_)
        #: the latest stacked observation (a masked reset keeps the unmarked rows)
        self._obs: dict[str, np.ndarray] | None = None
        #: a step failed in one environment after others had taken theirs: the batch is out
        #: of step until a reset of every environment
        self._failed = False

    # -- gymnasium ----------------------------------------------------------------------

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None
              ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Resets the environments: seed None (each draws its own), an int s (environment i
        gets s + i) or a list of K seeds (ints or None). ``options["reset_mask"]``, a bool
        array (K,) with at least one True, resets only the environments it marks (as
        Gymnasium's SyncVectorEnv does): the others keep their episode and their current
        observation, and the infos hold the reset ones only."""
        self._open("reset")
        seeds = self._seeds(seed)
        mask = self._mask(options)
        if mask is not None:
            self._refuse_failed("reset")
            options = {k: v for k, v in options.items() if k != "reset_mask"}  # type: ignore
        super().reset(seed=seeds[0])
        marked = [True] * self.num_envs if mask is None else mask.tolist()
        try:
            results = (self.workers.reset(seeds, options, marked) if self.workers is not None
                       else reset_all(self.envs, seeds, options, marked))
        except BaseException:
            self._failed = True  # some environments may have been reset, others not
            raise
        if mask is None:
            infos = self._combine([r[1] for r in results])
            self._failed = False
            self._done[:] = False
            self._obs = stack([r[0] for r in results])
        else:
            infos = {}
            rows = np.flatnonzero(mask)
            for i in rows:
                infos = self._add_info(infos, results[i][1], int(i))
            self._done[mask] = False
            # written in place: the arrays kept are never handed out (copies are returned)
            for key, value in self._obs.items():
                value[rows] = np.stack([results[i][0][key] for i in rows])
        return {key: value.copy() for key, value in self._obs.items()}, infos

    def _mask(self, options: dict[str, Any] | None) -> np.ndarray | None:
        """``options["reset_mask"]`` checked (the reset docstring), None without one."""
        check_options(options, ("reset_mask",))
        if not options or "reset_mask" not in options:
            return None
        mask, k = options["reset_mask"], self.num_envs
        fix = f"give a numpy bool array of shape ({k},), e.g. np.array([True] + [False] * {k - 1})"
        if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (k,):
            got = (f"dtype {mask.dtype} and shape {mask.shape}" if isinstance(mask, np.ndarray)
                   else f"{show(mask)} (a {type(mask).__name__})")
            raise SceneError('options["reset_mask"]', f"must be a numpy bool array of shape "
                             f"({k},), one entry per environment, got {got}", fix)
        if not mask.any():
            raise SceneError('options["reset_mask"]', "marks no environment (all False)",
                             "mark at least one environment True, or do not reset")
        if self._obs is None:
            raise SceneError('options["reset_mask"]', "resets some environments, but the "
                             "others have no observation yet", "call reset() without a "
                             "reset_mask first")
        return mask

    def step(self, actions: Any) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray,
                                          np.ndarray, dict[str, Any]]:
        self._open("step")
        self._refuse_failed("step")
        a = self._actions(actions)
        # next-step autoreset: an environment whose episode ended starts its next one
        try:
            stacked, rewards, terminated, truncated, each = (
                self.workers.step(self._done, a) if self.workers is not None
                else step_share(self.envs, self._done, a))
        except BaseException:
            self._failed = True
            raise
        infos = self._combine(each)
        self._done = terminated | truncated
        self._obs = stacked
        obs = {key: value.copy() for key, value in stacked.items()}
        return obs, rewards, terminated, truncated, infos

    def __reduce_ex__(self, protocol: Any) -> Any:
        """Pickled and copied as any object, but with workers refused (before any pipe is
        touched, so this one keeps working): their processes cannot be copied."""
        if getattr(self, "workers", None) is not None:
            w = len(self.workers.shares)
            raise SceneError("workers", f"a vector environment with workers={w} cannot be "
                             "copied or pickled (its worker processes cannot)",
                             "make a new one with the same arguments, or use workers=1")
        return super().__reduce_ex__(protocol)

    def render(self) -> None:
        """Refused in one line: the environments draw nothing (:data:`NO_RENDER`)."""
        raise SceneError("render", "the environments draw nothing (their only render mode "
                         "is None)", NO_RENDER)

    def close_extras(self, **kwargs: Any) -> None:
        if getattr(self, "workers", None) is not None:
            self.workers.close()
        for env in getattr(self, "envs", []):
            env.close()

    # -- checks and batching ------------------------------------------------------------

    def _seeds(self, seed: Any) -> list[int | None]:
        k, seed = self.num_envs, seed_value(seed)
        if seed is None:
            return [None] * k
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            s = checks.integer(seed, "seed", fix="give seed as an integer >= 0 (environment i "
                               "gets seed + i), a list of seeds or None")
            return [s + i for i in range(k)]
        if isinstance(seed, (list, tuple, np.ndarray)):
            if len(seed) != k:
                raise SceneError("seed", f"has {len(seed)} seeds for {k} environments: "
                                 f"{show(seed)}", f"give one seed per environment (a list of "
                                 f"{k}) or a single integer")
            return [None if s is None else checks.integer(seed_value(s), f"seed[{i}]",
                                                          fix=f"give seed[{i}] as an "
                                                          "integer >= 0")
                    for i, s in enumerate(seed)]
        raise SceneError("seed", f"must be an integer, a list of {k} seeds or None, got "
                         f"{show(seed)}", f"e.g. seed=0 or seed=[0, 1, ...] ({k} seeds)")

    def _refuse_failed(self, call: str) -> None:
        """Refuses ``call`` (a step, or a reset of some environments only) after a step that
        failed in one environment: the environments before it had stepped, and their results
        were not returned."""
        if self._failed:
            raise SceneError(call, "the last step failed in one environment after others had "
                             "taken theirs, so the environments are out of step",
                             "call reset() (without a reset_mask) to start every "
                             "environment's episode again")

    def _open(self, call: str) -> None:
        """Refuses ``call`` after close(), with workers or without."""
        if self.closed:
            raise SceneError(call, "the vector environment is closed", "make a new one")

    def _actions(self, actions: Any) -> np.ndarray:
        want = (self.num_envs, self.width)
        try:
            if np.iscomplexobj(actions):  # numpy would drop the imaginary parts, silently
                raise TypeError(actions)
            a = np.asarray(actions, dtype=np.float64)
        except (TypeError, ValueError):  # a string, a dict, complex numbers
            raise SceneError("actions", f"must be numbers of shape {want}, got "
                             f"{show(actions)}", "give an element of env.action_space") from None
        if a.shape != want:
            raise SceneError("actions", f"must have shape {want} (one row per environment), "
                             f"got shape {a.shape}", "give an element of env.action_space")
        bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
        if len(bad):
            i = int(bad[0])
            raise SceneError(f"actions[{i}]", f"must be {self.width} finite numbers, got "
                             f"{show(a[i])}", f"give environment {i} an element of "
                             "env.single_action_space")
        return a

    def _combine(self, infos: list[dict[str, Any]]) -> dict[str, Any]:
        """The K environments' infos (one each, in order) combined as Gymnasium's
        ``_add_info`` combines them, environment by environment: each key an array over the
        environments of its first value's type, ``_key`` the mask of those that have it. When
        every environment gives the same keys, each a Python int, float or bool of one type
        across the environments (every step but an episode's end, whose ``metrics`` is a
        dict), each key's array is built in one pass, with the same dtype, values and order
        of keys."""
        keys = list(infos[0])
        if all(list(info) == keys for info in infos):
            combined: dict[str, Any] = {}
            for key in keys:
                values = [info[key] for info in infos]
                kinds = set(map(type, values))
                kind = type(values[0])
                if len(kinds) > 1 or kind not in _SCALARS:
                    break
                combined[key] = np.array(values, dtype=kind)
                combined[f"_{key}"] = np.ones(self.num_envs, dtype=np.bool_)
            else:
                return combined
        combined = {}
        for i, info in enumerate(infos):
            combined = self._add_info(combined, info, i)
        return combined


def make(num_envs: int = 1, workers: int = 1, **kwargs: Any) -> CrowdNavVectorEnv:
    """The vector entry point of ``sweep/CrowdNav-v0``."""
    return CrowdNavVectorEnv(num_envs=num_envs, workers=workers, **kwargs)


__all__ = ["CrowdNavVectorEnv", "MAX_ENVS", "available_memory", "check_memory", "make"]
