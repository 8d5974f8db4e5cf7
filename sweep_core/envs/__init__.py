"""Gymnasium environments around the engine (needs ``gymnasium``, the ``gym`` extra).

Importing this package registers ``sweep/CrowdNav-v0`` (:class:`CrowdNavEnv`)::

    import gymnasium
    import sweep_core.envs  # noqa: F401  (registers the environment)

    env = gymnasium.make("sweep/CrowdNav-v0", scene="my_scene.yaml")
"""
from __future__ import annotations

import gymnasium

from sweep_core.envs.crowdnav import CrowdNavEnv

__all__ = ["CrowdNavEnv", "ENV_ID"]

#: the registered id
ENV_ID = "sweep/CrowdNav-v0"

if ENV_ID not in gymnasium.registry:
    gymnasium.register(id=ENV_ID, entry_point="sweep_core.envs.crowdnav:CrowdNavEnv")
