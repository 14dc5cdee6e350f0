"""Wall-clock timers on the stages of a simulation step, for the benchmarks (:mod:`runners.bench`,
:mod:`runners.benchmarks.crowd`, :mod:`runners.benchmarks.baseline`'s child): the library itself is not instrumented,
the
timed functions are wrapped for the measurement and restored afterwards."""

from __future__ import annotations

import time

from fuzzynav import episode as episode_mod
from fuzzynav.pedestrians.crowd import Crowd
from fuzzynav.planning import layer as nav_mod
from fuzzynav.policies.fuzzy import FuzzyPolicy
from fuzzynav.sensing import laser as laser_mod
from fuzzynav.sensing.sonar import Sonar
from runners.logs.mcap_log import EpisodeLogWriter


class Timers:
    """Wrap functions with accumulating timers (bench only: the library is not instrumented)."""

    def __init__(self) -> None:
        self.total: dict[str, float] = {}
        self._undo: list = []

    def wrap(self, owner, attr: str, stage: str) -> None:
        original = getattr(owner, attr)

        def timed(*args, **kwargs):
            t = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                self.total[stage] = self.total.get(stage, 0.0) + time.perf_counter() - t

        setattr(owner, attr, timed)
        self._undo.append((owner, attr, original))

    def us_per_step(self, seconds: float, steps: int) -> dict[str, float]:
        """µs per step of each stage, and ``rest`` (the run's ``seconds`` not in any stage), largest first."""
        stages = {k: v for k, v in self.total.items() if not k.startswith("_")}
        stages["rest"] = max(seconds - sum(stages.values()), 0.0)
        return {k: v / steps * 1e6 for k, v in sorted(stages.items(), key=lambda kv: -kv[1])}

    def restore(self) -> None:
        for owner, attr, original in reversed(self._undo):
            setattr(owner, attr, original)
        self._undo.clear()


def stage_timers(obstacles: bool = False) -> Timers:
    """Timers on the stages of a step (call :meth:`Timers.restore` afterwards): sensors (sonar and laser), tracking
    (perception), TPT, planner, controller, logging and, with ``obstacles``, the obstacle models' motion
    (:meth:`fuzzynav.pedestrians.crowd.Crowd.step`); what is left of a run's time is ``rest``."""
    timers = Timers()
    timers.wrap(Sonar, "read", "sensors")
    timers.wrap(laser_mod, "scan", "sensors")
    timers.wrap(episode_mod, "perceive", "tracking")
    timers.wrap(nav_mod, "build_tpt", "tpt")
    timers.wrap(nav_mod, "find_new_path", "planner")
    timers.wrap(nav_mod.PlanningLayer, "_still_valid", "planner")
    timers.wrap(FuzzyPolicy, "fuzzy", "controller")
    timers.wrap(EpisodeLogWriter, "step", "logging")
    if obstacles:
        timers.wrap(Crowd, "step", "obstacles")
    return timers
