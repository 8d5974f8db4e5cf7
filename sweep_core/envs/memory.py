"""What K environments of a vector environment (:mod:`sweep_core.envs.vector`) and its W
worker processes need of the memory, and the one-line refusals when they need more than
MEMORY_SHARE of what is available: :func:`memory_need` from the measure of one environment,
:func:`memory_refusal` (num_envs, or max_steps), :func:`check_workers` (workers). The
arguments are named as the caller says (:func:`option`): the vector environment's keywords,
or a command's options."""
from __future__ import annotations

from collections.abc import Mapping

from sweep_core.envs.crowdnav import MEMORY_SHARE
from sweep_core.envs.workers import WORKER_BYTES, start_method
from sweep_core.errors import SceneError


def memory_need(k: int, max_steps: int, measured: tuple[float, float, int]) -> int:
    """Bytes K environments take at the end of an episode of ``max_steps`` steps, from
    ``vector._memory_of``'s measure."""
    kept, per_step, scratch = measured
    return int(k * max(kept + per_step * max_steps, 1) + scratch)


def option(name: str, options: Mapping[str, str] | None) -> tuple[str, str | None]:
    """How a refusal names the argument ``name`` (num_envs, workers, max_steps) and sets it:
    the keyword (``num_envs``, ``num_envs=8``), or the command-line option ``options`` maps it
    to (``--num-envs``, ``--num-envs 8``); None for the setting when ``options`` has no
    option for it (the command cannot set it: no fix names it)."""
    if options is None:
        return name, f"{name}="
    if name not in options:
        return name, None
    return options[name], f"{options[name]} "


def memory_refusal(k: int, max_steps: int, measured: tuple[float, float, int],
                   have: int, options: Mapping[str, str] | None = None) -> SceneError:
    """The one-line refusal of K environments of ``max_steps`` steps needing more than
    MEMORY_SHARE of ``have`` bytes: naming num_envs when fewer environments fit, else
    max_steps (with its largest value that fits) when a shorter episode does (named as
    ``options`` says, :func:`option`)."""
    (envs_name, envs_set), (steps_name, steps_set) = (option("num_envs", options),
                                                      option("max_steps", options))
    envs_set = envs_set or f"{envs_name} "
    kept, per_step, scratch = measured
    need = memory_need(k, max_steps, measured)
    budget = MEMORY_SHARE * have
    one = (need - scratch) / k
    envs = int((budget - scratch) // one) if budget > scratch else 0
    steps = (int(((budget - scratch) / k - kept) // per_step)
             if per_step > 0 and budget > scratch + k * kept else 0)
    steps = min(int(0.9 * steps), max_steps - 1)  # a margin for the next measure's noise
    if steps_set is None:  # a command that cannot shorten the episodes
        steps = 0
    size = (f"{need / 1e9:.2g} GB ({one / 1e6:.2g} MB each, at max_steps={max_steps}), more "
            f"than half the {have / 1e9:.2g} GB available")
    if envs < 1 and steps >= 1:
        return SceneError(steps_name, f"{max_steps} steps is too long an episode: at its "
                          f"end the {k} environment{'s' if k > 1 else ''} need about {size}",
                          f"{steps_set}{steps} or fewer")
    fix = f"{envs_set}{max(1, envs)} or fewer"
    if steps >= 1:
        fix += f", or {steps_set}{steps} or fewer"
    return SceneError(envs_name, f"{k} environments need about {size}", fix)


def check_workers(w: int, envs_need: int, have: int,
                  options: Mapping[str, str] | None = None) -> None:
    """Refuses ``w`` worker processes (:data:`WORKER_BYTES` each) that, beside the ``envs_need``
    bytes of the environments, need more than MEMORY_SHARE of ``have`` bytes: before any is
    started, naming workers (as ``options`` says, :func:`option`) and the most that fit."""
    each = WORKER_BYTES[start_method()]
    budget = MEMORY_SHARE * have - envs_need
    if w * each <= budget:
        return
    most = int(budget // each)
    name, set_to = option("workers", options)
    set_to = set_to or f"{name} "
    raise SceneError(name, f"{w} worker processes need about {w * each / 1e9:.2g} GB "
                     f"({each / 1e6:.0f} MB each) beside the environments' "
                     f"{envs_need / 1e9:.2g} GB, more than half the {have / 1e9:.2g} GB "
                     "available", f"{set_to}{most} or fewer" if most >= 2 else f"{set_to}1")
