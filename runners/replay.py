"""Replay a logged episode.

    python -m runners.replay LOG.mcap                       # decision timeline + LOG.png
    python -m runners.replay LOG.mcap --animate             # also LOG.gif (one frame per step)
    python -m runners.replay LOG.mcap --steps 5,12,20       # snapshots at these steps in the PNG
    python -m runners.replay LOG.mcap --verify              # re-decide every step; exit 1 at the first change
    python -m runners.replay LOG.mcap --controller listing planner.h_wait=4    # counterfactual replay

``--verify`` rebuilds the planning layer (the policy and wait/detour) from the configuration recorded in the log
and feeds it the recorded inputs of each step (robot state, sonar, tracks, static laser returns), carrying its own
plan from step to step; it reports the first step whose decision (mode, Δθ, v, and the planner's tc/tS/tG)
differs from the recorded one. With ``--controller`` (a name in conf/controller/ or a YAML file) and/or ``key=value``
overrides of the recorded config (e.g. ``planner.h_wait=4``), the same recorded inputs go through the
changed planning layer and every step where its decision diverges is printed (open loop: the recorded inputs do
not react to the new decisions); ``--verify`` cannot be combined with them. Only what the planning layer decides
with can be overridden (keys in controller, planner, navigator, robot, and dt), each key once: the scenario,
the seed, perception and the sensors shaped the recorded inputs, which stay as they were.
"""

from __future__ import annotations

import argparse
import copy
import os
import stat
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from analysis.cli_args import OneLineParser
from analysis.episode_log import EpisodeLog, load_episode
from analysis.logs import LogError, file_kind
from fuzzynav.conf import CONF_DIR as CONF
from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.controller.fuzzy_spec import ControllerSpec, ControllerSpecError
from fuzzynav.kinematics import RobotState
from fuzzynav.params.names import AGENT
from fuzzynav.planning.layer import ActivePlan, Decision, Observation, PlanningLayer, build_planning_layer
from fuzzynav.sensing.laser import LaserConfig, beam_directions
from fuzzynav.sensing.tracking import Track
from runners.configuration.data_files import SAFE_LOADER
from runners.run import ConfigFileError, episode_config

ALL_TOPICS = ("/scene", "/robot/state", "/obstacles/truth", "/planner/decision", "/tpt", "/episode", "/tracks",
              "/sonar", "/laser")
TOLERANCE = 1e-2  # degrees and cm/s (and a policy's own numbers): the log rounds to 1e-4
MAX_SNAPSHOTS = 100  # --steps: snapshots drawn in one PNG
MAX_CONTROLLER_BYTES = 1 << 20  # --controller: a controller file is a few KB
NAVIGATOR_SOURCES = {"controller": "controller", "planner": "planner", "policy": "navigator", "params": "navigator",
                     "limits": "robot", "dt": "dt", "front_sector_deg": "sensors.sonar.front"}
"""Per argument of :func:`build_planning_layer` (but ``robot_radius``, which the log's /robot/state gives), the part
of the run config :func:`navigator_for` builds it from (a test keeps this in step with both). Nothing else
reaches a replayed decision, so an override of any other key is refused."""
RECORDED_INPUT_SOURCES = ("sensors.sonar.front",)  # the sector the recorded front readings were taken over: the
# navigator compares the goal with that reading, so another sector would misread the recorded input
OVERRIDABLE = tuple(dict.fromkeys(source for source in NAVIGATOR_SOURCES.values()
                                  if source not in RECORDED_INPUT_SOURCES))
"""The keys (and the keys inside them) a counterfactual replay may change."""


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


class ReplayError(Exception):
    """A replay argument or input that cannot be used; the message is the one line printed."""


def _set(config: dict[str, Any], dotted: str, value: Any) -> None:
    """Set an existing key of the recorded config (dotted path); :class:`ReplayError` if there is none."""
    node: Any = config
    keys = dotted.split(".")
    for key in keys[:-1]:
        node = node.get(key) if isinstance(node, dict) else None
    if not isinstance(node, dict) or keys[-1] not in node:
        raise ReplayError(f"override {dotted}: no such key in the recorded config")
    if isinstance(node[keys[-1]], dict):  # ``planner=`` replaced the recorded section by its defaults
        raise ReplayError(f"override {dotted}: a section of the recorded config; give its keys one by one "
                          f"({dotted}.<key>=value)")
    node[keys[-1]] = value


def parse_steps(text: str) -> list[int]:
    """``--steps 5,12,20``: step numbers (non-negative integers), at most ``MAX_SNAPSHOTS`` of them."""
    items = [item.strip() for item in text.split(",")]
    if len(items) > MAX_SNAPSHOTS:
        raise ReplayError(f"--steps: {len(items)} steps, at most {MAX_SNAPSHOTS} snapshots")
    for item in items:
        if not item.isascii() or not item.isdigit() or len(item) > 9:
            raise ReplayError(f"--steps: {item[:20]!r} is not a step number (comma-separated integers from 0)")
    return [int(item) for item in items]


def parse_override(item: str) -> tuple[str, Any]:
    """``key=value``, the value read by Hydra's override grammar, as ``runners.run`` reads it (``010`` is text,
    not YAML 1.1's octal 8; ``1e-3`` a number); one value of a key the recorded config has (no sweep, ``+``, ``~``)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    key, sep, _value = item.partition("=")
    if not sep or not key or any(not part for part in key.split(".")):
        raise ReplayError(f"override {item[:60]!r}: expected key=value, e.g. planner.h_wait=4")
    try:
        override = OverridesParser.create().parse_override(item)
    except HydraException as err:
        reason = " ".join(str(err).split())[:200]
        raise ReplayError(f"override {key[:60]}: not a value Hydra can read ({reason})") from None
    if override.is_add() or override.is_force_add() or override.is_delete() or override.package:
        raise ReplayError(f"override {key[:60]}: a replay changes recorded values only (no +, ++, ~ or @package)")
    if override.is_sweep_override():
        raise ReplayError(f"override {key[:60]}: one value per key (a sweep of values: python -m runners.sweep)")
    return override.key_or_group, override.value()


def navigator_for(config: dict[str, Any], robot_radius: float) -> PlanningLayer:
    """The planning layer a run with this (recorded) configuration used; ``robot_radius`` in cm. The whole config is
    validated as ``runners.run`` validates it (the sonar sectors are checked together, say), but the planning layer
    gets only the parts :data:`NAVIGATOR_SOURCES` names."""
    ep = episode_config(config)
    evaluator = FastEvaluator(ControllerSpec.from_dict(config["controller"]))
    return build_planning_layer(policy=ep.policy, params=ep.navigator, planner=ep.planner, limits=ep.robot,
                           robot_radius=robot_radius, dt=ep.dt, front_sector_deg=ep.sonar.front, controller=evaluator)


def check_overrides(overrides: list[tuple[str, Any]]) -> None:
    """Each key once (not also inside another given key), and only keys of :data:`OVERRIDABLE`;
    :class:`ReplayError` naming the first key that is not."""
    seen: list[str] = []
    for key, _value in overrides:
        for other in seen:
            if key == other:
                raise ReplayError(f"override {key}: given twice (one value per key)")
            if key.startswith(other + ".") or other.startswith(key + "."):
                raise ReplayError(f"override {key}: overlaps override {other} (one value per key)")
        seen.append(key)
        if any(_within(key, source) for source in RECORDED_INPUT_SOURCES):
            raise ReplayError(f"override {key}: the sonar sector the recorded front readings were taken over: it "
                              "cannot change in an open-loop replay; run the episode again with runners.run")
        if not any(_within(key, source) for source in OVERRIDABLE):
            raise ReplayError(f"override {key}: has no effect on an open-loop replay (the recorded inputs are "
                              f"replayed; only {', '.join(OVERRIDABLE)} can change a decision); run the episode "
                              "again with runners.run")


def _within(key: str, source: str) -> bool:
    """``key`` is ``source`` or a key inside it (dotted paths)."""
    return key == source or key.startswith(source + ".")


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
    keep = returned & ~moving
    # the episode's own direction arithmetic (fuzzynav.sensing.laser), not a re-derivation with np.cos
    d = beam_directions(LaserConfig(beams=len(ranges)), s["heading_deg"])
    pts = np.stack([s["x_cm"] + ranges[keep] * d[keep, 0], s["y_cm"] + ranges[keep] * d[keep, 1]], axis=1)
    return Observation(state, goal, (son["left_cm"], son["front_cm"], son["right_cm"]), tracks, pts)


def _compare(k: int, recorded: dict[str, Any], d: Decision) -> Divergence | None:
    if recorded["mode"] != d.mode:
        return Divergence(k, "mode", recorded["mode"], d.mode)
    for name, value in (("dtheta_deg", d.dtheta_deg), ("v_cm_s", d.v_cm_s)):
        if abs(recorded[name] - value) > TOLERANCE:
            return Divergence(k, name, recorded[name], round(float(value), 4))  # (a numpy float printed as such)
    if recorded["new_plan"] != d.new_plan:
        return Divergence(k, "new_plan", recorded["new_plan"], d.new_plan)
    fields = recorded.get("policy_fields")
    if fields is not None:  # logs written before policies have none
        replayed = dict(d.fields)
        if set(fields) != set(replayed):
            return Divergence(k, "policy_fields", sorted(fields), sorted(replayed))
        for key, value in sorted(fields.items()):
            now = replayed[key]
            same = (abs(float(now) - value) <= TOLERANCE if isinstance(value, float) and not isinstance(now, str | bool)
                    else now == value)
            if not same:
                return Divergence(k, f"policy_fields.{key}", value, now.item() if hasattr(now, "item") else now)
    if d.new_plan and d.plan is not None and recorded.get("planning"):
        p = recorded["planning"]
        for name in ("strategy", "tc", "tS", "tG"):
            if p[name] != getattr(d.plan, name):
                return Divergence(k, f"planning.{name}", p[name], getattr(d.plan, name))
    return None


def replayable_steps(log: EpisodeLog) -> int:
    """Steps whose recorded inputs and decision are all in the log (an episode that ended with an error may
    have written part of its last step)."""
    return min(len(log.decisions), len(log.states), len(log.sonar), len(log.tracks), len(log.laser))


def replay(log: EpisodeLog, config: dict[str, Any], stop_at_first: bool) -> list[Divergence]:
    """Feed the recorded inputs of every step to a planning layer built from ``config``."""
    navigator = navigator_for(config, log.robot_radius)
    navigator.reset(int(log.meta.get("seed", "0")))  # as the episode did: a policy's randomness comes from it
    goal = log.goal
    active: ActivePlan | None = None
    out = []
    for k, recorded in enumerate(log.decisions[:replayable_steps(log)]):
        decision, active = navigator.decide(_observation(log, k, goal), active)  # type: ignore[arg-type]
        diff = _compare(k, recorded, decision)
        if diff is not None:
            out.append(diff)
            if stop_at_first:
                break
    return out


def _controller(name: str) -> dict[str, Any]:
    """A controller definition: a YAML file, or a name in conf/controller/ (regular files only, a bounded
    size: a FIFO would block the read)."""
    path = Path(name)
    if not path.exists():
        path = CONF / "controller" / f"{name}.yaml"
    if not path.exists():
        raise ReplayError(f"controller {name!r}: no such file (looked in {CONF / 'controller'})")
    try:
        st = path.stat()
        if not stat.S_ISREG(st.st_mode):
            raise ReplayError(f"{path}: {file_kind(st.st_mode)}, not a controller file")
        if st.st_size > MAX_CONTROLLER_BYTES:
            raise ReplayError(f"{path}: {st.st_size} bytes, more than {MAX_CONTROLLER_BYTES} for a controller file")
        data = yaml.load(path.read_text(encoding="utf-8"), Loader=SAFE_LOADER)
    except (OSError, UnicodeDecodeError) as err:
        raise ReplayError(f"{path}: cannot read: {getattr(err, 'strerror', None) or err}") from None
    except yaml.YAMLError as err:
        raise ReplayError(f"{path}: not valid YAML ({getattr(err, 'problem', None) or err})") from None
    if not isinstance(data, dict):
        raise ReplayError(f"{path}: a controller file is a mapping (inputs, outputs, rules)")
    try:  # validated here, so that a bad rule names this file, not the log it is replayed against
        ControllerSpec.from_dict(data)
    except ControllerSpecError as err:
        raise ReplayError(f"{path}: {err}") from None
    return data


def check_out_stem(stem: Path) -> None:
    """``--out``, the path stem of the PNG/GIF (``.png``/``.gif`` is appended): :class:`ReplayError` for a stem
    that is an existing directory (the images went beside it, outside the directory named), a device, FIFO or
    other non-regular file (``/dev/null`` became ``/dev/null.png``), or whose directory does not exist or is
    not writable."""
    if stem.is_dir():
        raise ReplayError(f"--out: {stem}: is a directory; --out is a path stem (e.g. {stem / 'replay'})")
    if (stem.exists() or stem.is_symlink()) and not stem.is_file():
        raise ReplayError(f"--out: {stem}: not a regular file; --out is a path stem for the PNG/GIF")
    parent = stem.parent
    if not parent.exists():
        raise ReplayError(f"--out: {stem}: the directory {parent} does not exist")
    if not parent.is_dir():
        raise ReplayError(f"--out: {stem}: {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ReplayError(f"--out: {stem}: the directory {parent} is not writable")


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("log", help="an episode log (.mcap)")
    parser.add_argument("overrides", nargs="*", help="key=value changes of the recorded config (counterfactual)")
    parser.add_argument("--verify", action="store_true", help="re-decide every step; exit 1 at the first change")
    parser.add_argument("--controller", action="append",
                        help="counterfactual controller: a name in conf/controller/ or a YAML file")
    parser.add_argument("--animate", action="store_true", help="also write an animated GIF")
    parser.add_argument("--steps", help="comma-separated steps to draw snapshots at")
    parser.add_argument("--out", help="output path stem for the PNG/GIF (default: beside the log)")
    parser.add_argument("--quiet", action="store_true", help="no timeline")
    args = parser.parse_intermixed_args(_after_double_dash(sys.argv[1:] if argv is None else list(argv)))
    try:
        return _run(args)
    except ReplayError as err:
        print("error: " + str(err).replace("\n", "\\n"), file=sys.stderr)  # one line, even for odd file names
        return 2


def _after_double_dash(argv: list[str]) -> list[str]:
    """``argv`` with the arguments after ``--`` (positional, whatever they start with) made unmistakable for
    argparse's intermixed parsing, which drops ``--`` and then read ``-x.mcap`` as an unknown option (or said the
    log was missing): a file name that starts with a dash is given as ``./-x.mcap``, the same file."""
    if "--" not in argv:
        return argv
    cut = argv.index("--")
    return [*argv[:cut], *(f"./{a}" if a.startswith("-") else a for a in argv[cut + 1:])]


def _run(args: argparse.Namespace) -> int:
    """The replay of ``args``; every problem with the arguments or the log is a :class:`ReplayError`."""
    path = Path(args.log)
    steps = parse_steps(args.steps) if args.steps is not None else None
    overrides = [parse_override(item) for item in args.overrides]
    check_overrides(overrides)
    if args.controller is not None:
        if len(args.controller) > 1:
            raise ReplayError(f"--controller: given {len(args.controller)} times (one controller per replay)")
        args.controller = args.controller[0]
    if args.verify and (args.controller or overrides):
        raise ReplayError("--verify: re-decides with the recorded config; it cannot be combined with "
                          "--controller/overrides (without --verify they list every step that differs)")
    if args.out is not None and (args.verify or args.controller or overrides):
        raise ReplayError("--out: --verify, --controller and overrides list the steps that differ and draw no "
                          "picture; --out names the picture of a plain replay")
    if args.out is not None:
        if args.out.endswith(("/", os.sep)):  # Path() drops the slash: the picture went beside the folder named
            raise ReplayError(f"--out: {args.out}: names a folder; --out is a path stem (e.g. {args.out}replay)")
        check_out_stem(Path(args.out))
    if not path.exists() and not path.is_symlink():
        raise ReplayError(f"{path}: no such file")
    try:
        log = load_episode(path, ALL_TOPICS)
    except LogError as err:
        raise ReplayError(str(err)) from None
    if not log.decisions:
        raise ReplayError(f"{path}: no /planner/decision messages to replay")
    if args.verify and not log.complete:
        raise ReplayError(f"{path}: truncated log (no MCAP summary; {log.steps} steps readable): an unfinished "
                          "episode cannot be verified")
    if steps is not None and any(k >= log.steps for k in steps):
        raise ReplayError(f"--steps: step {max(steps)} is beyond the episode's {log.steps} steps "
                          f"(0 to {log.steps - 1})")
    counterfactual = bool(args.controller or overrides)
    if args.verify or counterfactual:
        return _decide_again(log, path, args, overrides, counterfactual)
    if not args.quiet:
        print("\n".join(timeline(log)))
    from analysis.render import render_gif, render_png

    stem = Path(args.out) if args.out else path.with_suffix("")
    for target in [stem.with_suffix(".png")] + ([stem.with_suffix(".gif")] if args.animate else []):
        try:
            written = render_png(log, target, steps) if target.suffix == ".png" else render_gif(log, target)
        except OSError as err:
            raise ReplayError(f"{target}: cannot write: {err.strerror or err}") from None
        print(f"wrote {written}")
    return 0


def _decide_again(log: EpisodeLog, path: Path, args: argparse.Namespace, overrides: list[tuple[str, Any]],
                  counterfactual: bool) -> int:
    """``--verify`` and counterfactual replays: the recorded inputs through a planning layer rebuilt from the
    recorded (or changed) config."""
    if log.goal is None:
        raise ReplayError(f"{path}: the first /scene has no goal: the planning layer cannot be rebuilt")
    if log.meta.get("policy") == AGENT:
        raise ReplayError(f"{path}: an agent's episode (Gymnasium): its actions came from outside and cannot be "
                          "decided again")
    config = copy.deepcopy(log.config)
    if args.controller:
        config["controller"] = _controller(args.controller)
    for key, value in overrides:
        _set(config, key, value)
    try:
        diffs = replay(log, config, stop_at_first=not counterfactual)
    except (ConfigFileError, ValueError, KeyError, TypeError, AttributeError) as err:
        # the config's own validation raises ValueError subclasses; KeyError/TypeError/AttributeError come from a
        # recorded config that lacks a section or has one of another type (hand-written or old logs)
        which = "changed" if counterfactual else "recorded"
        kind = f"{type(err).__name__}: " if type(err) in (KeyError, TypeError, AttributeError) else ""
        raise ReplayError(f"{path}: cannot rebuild the planning layer from the {which} config: {kind}{err}") from None
    steps = replayable_steps(log)
    if counterfactual:
        print(f"counterfactual replay of {steps} recorded steps: {len(diffs)} decisions differ")
        for d in diffs:
            print(f"  step {d.step}: {d.field} recorded {d.recorded!r}, now {d.replayed!r}")
        return 0
    if diffs:
        d = diffs[0]
        print(f"{path}: decision differs at step {d.step}: {d.field} recorded {d.recorded!r}, "
              f"replayed {d.replayed!r}")
        return 1
    print(f"{path}: all {steps} decisions reproduced")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
