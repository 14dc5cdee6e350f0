"""Benchmark of replaying recorded people (part of ``python -m runners.bench``, issue #38): what a 300-person
recording adds to a step.

A synthetic recording (fuzzynav ships none; the layout of ETH/UCY's: annotations every 0.4 s, people walking
straight at 130 cm/s for 30 s each, one entering every 2 s, so about 15 present at a time) of 300 people
crossing a 60 × 40 m plaza, replayed by the ``recorded`` model (:mod:`fuzzynav.pedestrians.recorded`) at dt = 1 s
for the recording's 600 s, with a robot standing in the plaza's middle. Timed per step, medians of repetitions:

- ``replay``: the crowd's step (the model's positions, velocities and presence of all 300);
- ``sensing``: the laser frame, the sonar and ground-truth perception of the present people, minus the same
  with nobody — the cost of the people the sensors could see (a person beyond the laser's range is culled
  before any beam is cast against it);

against a whole step of the ``mixed`` scenario (laser perception, no logging), the simulation's reference
workload. The Crowd is built directly, from the 300 people (``fuzzynav.params.limits.MAX_RECORDED_PEOPLE``, the
most a scenario's window may hold) and no scenario around them.
"""

from __future__ import annotations

import statistics
import time
from typing import Any

import numpy as np

N_PEOPLE = 300
SPAN_S = 600.0


def _people(n: int):
    from fuzzynav.pedestrians.recorded import RecordedConfig
    from fuzzynav.scenarios.scenario import DynamicObstacle

    rng = np.random.default_rng(38)
    out = []
    for i in range(n):
        start = 2.0 * i
        angle = rng.uniform(0, 2 * np.pi)
        direction = np.array([np.cos(angle), np.sin(angle)])
        centre = np.array([3000.0, 2000.0]) + rng.uniform(-1500, 1500, 2)
        t = start + 0.4 * np.arange(76)  # 30 s
        xy = centre + np.outer(130.0 * (t - start - 15.0), direction)
        out.append(DynamicObstacle(id=f"p{i}", radius=25.0, waypoints=tuple(map(tuple, xy.tolist())), speed=130.0,
                                   model="recorded", model_params=RecordedConfig(t_s=tuple(t.tolist()),
                                                                                 until_s=SPAN_S)))
    return out


def bench_recorded(reps: int = 3, steps: int = int(SPAN_S)) -> dict[str, Any]:
    """µs per step of the replay and of the sensing of 300 recorded people (module docstring), and their share of a
    ``mixed`` step."""
    from fuzzynav.kinematics import RobotState
    from fuzzynav.numerics.portable_random import NormalStream
    from fuzzynav.pedestrians.crowd import Crowd
    from fuzzynav.scenarios.world import World
    from fuzzynav.sensing import laser
    from fuzzynav.sensing.perception import PerceptionConfig, perceive
    from fuzzynav.sensing.sonar import Sonar
    from fuzzynav.sensing.tracking import TrackerState
    from runners.benchmarks.simulation import _scenario_and_config
    from runners.run import run_episode

    scenario, evaluator, cfg = _scenario_and_config("mixed")
    world = World((0, 0, 6000, 4000))
    robot = RobotState(3000.0, 2000.0, 0.0, 0.0)
    people = _people(N_PEOPLE)
    sonar = Sonar(cfg.sonar, 20.0)
    truth = PerceptionConfig(mode="ground_truth")

    def replay() -> tuple[float, list[tuple[np.ndarray, np.ndarray, np.ndarray]], float]:
        crowd = Crowd(people, world, 20.0)
        crowd.reset(0)
        frames, present = [], 0
        t = time.perf_counter()
        for _ in range(steps):
            pos, vel = crowd.step(robot, 1.0)
            frames.append((pos, vel, crowd.present))
            present += int(crowd.present.sum())
        return (time.perf_counter() - t) / steps, frames, present / steps

    def sense(frames, with_people: bool) -> float:
        noise = NormalStream(np.random.default_rng(0))
        state = TrackerState()
        t = time.perf_counter()
        for k, (pos, vel, present) in enumerate(frames):
            discs = np.column_stack([pos, np.full(len(pos), 25.0)])[present] if with_people else np.zeros((0, 3))
            speeds = np.hypot(vel[present, 0], vel[present, 1]) if with_people else None
            sonar.read(robot.x, robot.y, robot.heading, world.solid, discs, speeds)
            scan = laser.scan(cfg.laser, robot.x, robot.y, robot.heading, world.segments, world.circles, discs, noise)
            state, _ = perceive(truth, state, scan, float(k), pos, vel, np.full(len(pos), 25.0), noise,
                                present if with_people else np.zeros(len(pos), dtype=bool))
        return (time.perf_counter() - t) / len(frames)

    def mixed_step() -> float:
        t, n = time.perf_counter(), 0
        for seed in range(3):
            n += run_episode(scenario, evaluator, cfg, seed, None, "")["steps"]
        return (time.perf_counter() - t) / n

    replay()  # warm-up
    mixed_step()
    replays, extras, mixed = [], [], []
    for _ in range(reps):  # alternated, so that a slow spell of the machine hits all alike
        t_replay, frames, present = replay()
        replays.append(t_replay)
        extras.append(sense(frames, True) - sense(frames, False))
        mixed.append(mixed_step())
    in_range = statistics.mean(
        int(((np.hypot(pos[:, 0] - robot.x, pos[:, 1] - robot.y) - 25.0 <= cfg.laser.range_cm) & p).sum())
        for pos, _, p in frames)
    r, e, m = statistics.median(replays), statistics.median(extras), statistics.median(mixed)
    return {"people": N_PEOPLE, "steps": steps, "repetitions": reps, "present_per_step": present,
            "in_laser_range_per_step": in_range, "replay_us_per_step": r * 1e6,
            "sensing_extra_us_per_step": e * 1e6, "mixed_us_per_step": m * 1e6, "share_of_mixed_step": (r + e) / m}


def print_recorded(row: dict[str, Any]) -> None:
    print(f"\nRecorded people: {row['people']} people over {row['steps']} steps of 1 s "
          f"({row['present_per_step']:.1f} present, {row['in_laser_range_per_step']:.2f} in laser range per step)")
    print(f"  replay {row['replay_us_per_step']:.0f} µs/step, sensing them {row['sensing_extra_us_per_step']:.0f} "
          f"µs/step; a mixed step {row['mixed_us_per_step']:.0f} µs: +{100 * row['share_of_mixed_step']:.1f} %")
