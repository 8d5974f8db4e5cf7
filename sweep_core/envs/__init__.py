"""Gymnasium environments around the engine (needs ``gymnasium``, the ``gym`` extra).

Importing this package registers ``sweep/CrowdNav-v0`` (:class:`CrowdNavEnv`)::

    import gymnasium
    import sweep_core.envs  # noqa: F401  (registers the environment)

    env = gymnasium.make("sweep/CrowdNav-v0", scene="my_scene.yaml")
    envs = gymnasium.make_vec("sweep/CrowdNav-v0", num_envs=32,
                              vectorization_mode="vector_entry_point")  # envs/vector.py
"""
from __future__ import annotations

import gymnasium

from sweep_core.envs.crowdnav import CrowdNavEnv

__all__ = ["CrowdNavEnv", "ENV_ID", "check_memory", "has_vector", "make_single", "make_vector"]

#: the registered id
ENV_ID = "sweep/CrowdNav-v0"

if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="sweep_core.envs.crowdnav:CrowdNavEnv",
                       vector_entry_point="sweep_core.envs.vector:make")


def make_single(**kwargs: object) -> gymnasium.Env:
    """``gymnasium.make(ENV_ID, **kwargs)`` (for the bench, which does not import gymnasium)."""
    return gymnasium.make(ENV_ID, **kwargs)


def has_vector() -> bool:
    """Whether ``ENV_ID`` has a vectorised entry point (``gymnasium.make_vec``'s
    ``vector_entry_point`` mode)."""
    return gymnasium.registry[ENV_ID].vector_entry_point is not None


def check_memory(num_envs: int, workers: int, options: dict[str, str]) -> int:
    """:func:`sweep_core.envs.vector.check_memory` of the default environment: the memory
    estimate (bytes) of ``make_vector(num_envs, workers=workers)``, or its SceneError naming
    the arguments as ``options`` maps them (for the bench, which does not import gymnasium)."""
    from sweep_core.envs.vector import check_memory as check

    return check(num_envs, workers, options)


def make_vector(num_envs: int, **kwargs: object) -> gymnasium.vector.VectorEnv:
    """``num_envs`` environments stepped in one call, through the vectorised entry point."""
    return gymnasium.make_vec(ENV_ID, num_envs=num_envs,
                              vectorization_mode="vector_entry_point", **kwargs)
