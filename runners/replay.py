"""Replay a logged episode.

    python -m runners.replay LOG.mcap                       # decision timeline + LOG.png
    python -m runners.replay LOG.mcap --animate             # also LOG.gif (one frame per step)
    python -m runners.replay LOG.mcap --steps 5,12,20       # snapshots at these steps in the PNG
    python -m runners.replay LOG.mcap --verify              # re-decide every step; exit 1 at the first change
    python -m runners.replay LOG.mcap --controller listing planner.h_wait=4    # counterfactual replay

``--verify`` rebuilds the navigator from the configuration recorded in the log and feeds it the recorded
inputs of each step (robot state, sonar, tracks, static laser returns), carrying its own plan from step to
step; it reports the first step whose decision (mode, Δθ, v, and the planner's tc/tS/tG) differs from the
recorded one. With ``--controller`` (a name in conf/controller/ or a YAML file) and/or ``key=value``
overrides of the recorded config (e.g. ``planner.h_wait=4``), the same recorded inputs go through the
changed navigator and every step where its decision diverges is printed (open loop: the recorded inputs do
not react to the new decisions).
"""

from __future__ import annotations

import argparse
import copy
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from analysis.episode_log import EpisodeLog, load_episode
from analysis.logs import LogError
from fuzzynav.fuzzy_fast import FastEvaluator
from fuzzynav.fuzzy_spec import ControllerSpec, ControllerSpecError
from fuzzynav.kinematics import RobotState
from fuzzynav.navigator import ActivePlan, Decision, Navigator, Observation
from fuzzynav.tracking import Track
from runners.run import episode_config

CONF = Path(__file__).resolve().parents[1] / "conf"
ALL_TOPICS = ("/scene", "/robot/state", "/obstacles/truth", "/planner/decision", "/tpt", "/episode", "/tracks",
              "/sonar", "/laser")
TOLERANCE = 1e-2  # degrees and cm/s: the log rounds to 1e-4


@dataclass(frozen=True)
class Divergence:
    step: int
    field: str
    recorded: Any
    replayed: Any


def timeline(log: EpisodeLog) -> list[str]:
    """One line per step: mode, inputs, outputs, predicted collisions, plans."""
    lines = [f"{'step':>4} {'mode':<7} {'L':>6} {'F':>6} {'R':>6} {'angle':>6} {'dθ':>7} {'v':>5}  events"]
    for d in log.decisions:
        k = d["step"]
        events = []
        t = log.tpts.get(k)
        if t:
            rows = [i for i, row in enumerate(t["collide"]) if i > 0 and any(row)]
            if rows:
                events.append(f"TPT collisions at +{rows}")
        if d.get("planning"):
            p = d["planning"]
            events.append(f"plan {p['strategy']} tc={p['tc']} tS={p['tS']} tG={p['tG']} waitTime={p['wait_time']}"
                          f" hWait={p['h_wait']} ({p['reason']})")
        st = log.states[k] if k < len(log.states) else None
        if st and (st["contact_static"] or st["contact_dynamic"]):
            events.append("CONTACT " + ("static " if st["contact_static"] else "") + " ".join(st["contact_dynamic"]))
        lines.append(f"{k:>4} {d['mode']:<7} {d['left_cm']:6.1f} {d['front_cm']:6.1f} {d['right_cm']:6.1f} "
                     f"{d['angle_deg']:6.1f} {d['dtheta_deg']:7.2f} {d['v_cm_s']:5.1f}  {'; '.join(events)}")
    lines.append(f"outcome: {log.outcome} after {log.steps} steps")
    return lines


def _set(config: dict[str, Any], dotted: str, value: Any) -> None:
    node = config
    keys = dotted.split(".")
    for key in keys[:-1]:
        node = node.setdefault(key, {})
    if keys[-1] not in node:
        raise KeyError(dotted)
    node[keys[-1]] = value


def navigator_for(config: dict[str, Any], robot_radius: float) -> Navigator:
    """The navigator a run with this (recorded) configuration used."""
    ep = episode_config(config)
    evaluator = FastEvaluator(ControllerSpec.from_dict(config["controller"]))
    return Navigator(evaluator, ep.planner, ep.navigator, ep.robot, robot_radius, ep.dt, ep.sonar.front)


def _observation(log: EpisodeLog, k: int, goal: tuple[float, float]) -> Observation:
    s = log.states[k]
    state = RobotState(s["x_cm"], s["y_cm"], s["heading_deg"], s["v_cm_s"])
    son = log.sonar[k]
    tr = log.tracks[k]
    tracks = tuple(Track(t["id"], t["x_cm"], t["y_cm"], t["vx_cm_s"], t["vy_cm_s"], t["radius_cm"])
                   for t in tr["tracks"])
    laser = log.laser[k]
    ranges = np.array(laser["ranges"]) * 100.0
    returned = np.array(laser["intensities"]) > 0
    moving = np.zeros(len(ranges), dtype=bool)
    moving[tr.get("moving_beams", [])] = True
    n = len(ranges)
    angles = math.radians(s["heading_deg"]) + np.arange(n) * (2 * math.pi / n)
    keep = returned & ~moving
    pts = np.stack([s["x_cm"] + ranges[keep] * np.cos(angles[keep]),
                    s["y_cm"] + ranges[keep] * np.sin(angles[keep])], axis=1)
    return Observation(state, goal, (son["left_cm"], son["front_cm"], son["right_cm"]), tracks, pts)


def _compare(k: int, recorded: dict[str, Any], d: Decision) -> Divergence | None:
    if recorded["mode"] != d.mode:
        return Divergence(k, "mode", recorded["mode"], d.mode)
    for name, value in (("dtheta_deg", d.dtheta_deg), ("v_cm_s", d.v_cm_s)):
        if abs(recorded[name] - value) > TOLERANCE:
            return Divergence(k, name, recorded[name], round(value, 4))
    if recorded["new_plan"] != d.new_plan:
        return Divergence(k, "new_plan", recorded["new_plan"], d.new_plan)
    if d.new_plan and d.plan is not None and recorded.get("planning"):
        p = recorded["planning"]
        for name in ("strategy", "tc", "tS", "tG"):
            if p[name] != getattr(d.plan, name):
                return Divergence(k, f"planning.{name}", p[name], getattr(d.plan, name))
    return None


def replay(log: EpisodeLog, config: dict[str, Any], stop_at_first: bool) -> list[Divergence]:
    """Feed the recorded inputs of every step to a navigator built from ``config``."""
    navigator = navigator_for(config, log.robot_radius)
    goal = log.goal
    active: ActivePlan | None = None
    out = []
    for k, recorded in enumerate(log.decisions):
        decision, active = navigator.decide(_observation(log, k, goal), active)  # type: ignore[arg-type]
        diff = _compare(k, recorded, decision)
        if diff is not None:
            out.append(diff)
            if stop_at_first:
                break
    return out


def _controller(name: str) -> dict[str, Any]:
    path = Path(name)
    if not path.exists():
        path = CONF / "controller" / f"{name}.yaml"
    if not path.exists():
        raise FileNotFoundError(f"controller {name!r}: no such file (looked in {CONF / 'controller'})")
    return yaml.safe_load(path.read_text())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("log", help="an episode log (.mcap)")
    parser.add_argument("overrides", nargs="*", help="key=value changes of the recorded config (counterfactual)")
    parser.add_argument("--verify", action="store_true", help="re-decide every step; exit 1 at the first change")
    parser.add_argument("--controller", help="counterfactual controller: a name in conf/controller/ or a YAML file")
    parser.add_argument("--animate", action="store_true", help="also write an animated GIF")
    parser.add_argument("--steps", help="comma-separated steps to draw snapshots at")
    parser.add_argument("--out", help="output path stem for the PNG/GIF (default: beside the log)")
    parser.add_argument("--quiet", action="store_true", help="no timeline")
    args = parser.parse_intermixed_args(argv)
    path = Path(args.log)
    if not path.exists():
        print(f"error: {path}: no such file", file=sys.stderr)
        return 2
    try:
        log = load_episode(path, ALL_TOPICS)
    except LogError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if not log.decisions:
        print(f"error: {path}: no /planner/decision messages to replay", file=sys.stderr)
        return 2
    if args.verify and not log.complete:
        print(f"error: {path}: truncated log (no MCAP summary; {log.steps} steps readable): an unfinished episode "
              "cannot be verified", file=sys.stderr)
        return 2
    counterfactual = bool(args.controller or args.overrides)
    config = copy.deepcopy(log.config)
    try:
        if args.controller:
            config["controller"] = _controller(args.controller)
        for item in args.overrides:
            key, _, value = item.partition("=")
            _set(config, key, yaml.safe_load(value))
    except KeyError as err:
        print(f"error: override {err.args[0]}: no such key in the recorded config", file=sys.stderr)
        return 2
    except (FileNotFoundError, yaml.YAMLError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.verify or counterfactual:
        try:
            diffs = replay(log, config, stop_at_first=args.verify and not counterfactual)
        except (ControllerSpecError, ValueError, KeyError) as err:
            print(f"error: {path}: cannot rebuild the navigator from the recorded config: {err}", file=sys.stderr)
            return 2
        if counterfactual:
            print(f"counterfactual replay of {len(log.decisions)} recorded steps: {len(diffs)} decisions differ")
            for d in diffs:
                print(f"  step {d.step}: {d.field} recorded {d.recorded!r}, now {d.replayed!r}")
            return 0
        if diffs:
            d = diffs[0]
            print(f"{path}: decision differs at step {d.step}: {d.field} recorded {d.recorded!r}, "
                  f"replayed {d.replayed!r}")
            return 1
        print(f"{path}: all {len(log.decisions)} decisions reproduced")
        return 0
    if not args.quiet:
        print("\n".join(timeline(log)))
    from analysis.render import render_gif, render_png

    stem = Path(args.out) if args.out else path.with_suffix("")
    steps = [int(s) for s in args.steps.split(",")] if args.steps else None
    png = render_png(log, stem.with_suffix(".png"), steps)
    print(f"wrote {png}")
    if args.animate:
        print(f"wrote {render_gif(log, stem.with_suffix('.gif'))}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
