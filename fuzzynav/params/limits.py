"""Every documented limit on fuzzynav's inputs, in one place: the code checks these and the README table is
printed from them (``python -m fuzzynav.params.limits``), so the two cannot disagree.

Two kinds:

- **size and work limits** (:data:`SIZE_LIMITS`): file size, YAML nodes, vertices, obstacles, rules, steps,
  episodes... Each bounds the time or memory one input can cost, so that a typo (``n_static=1e8``) or a
  hostile file ends with a one-line error instead of a hang;
- **value ranges** of the run configuration (:data:`FIELD_RANGES`, keyed by the dotted field as written on
  the command line, e.g. ``planner.safety_margin_cm``): every number must be finite and inside its range.
  A plug-in's parameters (a policy's ``navigator.*``) carry their ranges on their own config dataclass instead
  (:func:`ranged`), so that no table here names them. A test checks that every numeric field of
  :class:`fuzzynav.episode.EpisodeConfig` and of every registered policy's config has a range.

Units are those of the field: cm, cm/s, s, degrees, counts.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Limit:
    """A size or work limit: at most ``value`` of ``what``; ``why`` says what it protects."""

    field: str
    value: int
    why: str


@dataclass(frozen=True)
class Range:
    """A closed or half-open interval ``[lo, hi]`` (``lo_open``/``hi_open`` exclude the end) in ``unit``;
    ``integer`` demands an integer. ``why`` explains the bounds."""

    lo: float
    hi: float
    unit: str = ""
    why: str = ""
    lo_open: bool = False
    hi_open: bool = False
    integer: bool = False

    def contains(self, x: float) -> bool:
        above = x > self.lo if self.lo_open else x >= self.lo
        below = x < self.hi if self.hi_open else x <= self.hi
        return above and below

    def text(self) -> str:
        """``(0, 60] s`` or ``[1, 1000]``."""
        lo = _num(self.lo)
        hi = _num(self.hi)
        unit = f" {self.unit}" if self.unit else ""
        return f"{'(' if self.lo_open else '['}{lo}, {hi}{')' if self.hi_open else ']'}{unit}"


def _num(x: float) -> str:
    return f"{int(x):,}" if float(x).is_integer() else f"{x:g}"


# -- names that become file names ---------------------------------------------------------------------------
NAME_MAX_CHARS = 64
#: letters, digits, ``_ - .``; not starting with ``.`` (no hidden files, no ``..``), at most 64 characters
NAME_PATTERN = re.compile(rf"[A-Za-z0-9_-][A-Za-z0-9_.-]{{0,{NAME_MAX_CHARS - 1}}}", re.ASCII)

# -- data files (scenario and controller YAML) ---------------------------------------------------------------
MAX_DATA_FILE_BYTES = 1_000_000
MAX_YAML_NODES = 10_000  # after alias expansion
MAX_YAML_DEPTH = 32
MAX_TEXT_CHARS = 10_000  # a free-text field (description)
MAX_MANIFEST_BYTES = 20_000_000  # a dataset manifest: about 1.3 kB per episode (suite_v1: 560 episodes, 0.7 MB)
MAX_MANIFEST_NODES = 1_000_000  # about 40 per episode

# -- scenarios ----------------------------------------------------------------------------------------------
MAX_COORD_CM = 1e9  # |x| of every scenario number (coordinates, radii, speeds)
MAX_STATIC_OBSTACLES = 500
MAX_POLYGON_VERTICES = 1_000
MAX_TOTAL_VERTICES = 2_000
MAX_DYNAMIC_OBSTACLES = 100
#: recorded people (obstacles of model ``recorded``), beside the other dynamic obstacles: a replayed person is an
#: array lookup per step, and one outside the sensors' range is neither sensed nor tracked (runners.bench: 300)
MAX_RECORDED_PEOPLE = 300
#: annotations a recorded scenario keeps, all people together: about 46 bytes each in the scenario every log holds
#: (its metadata is read up to 1 MB: analysis.log_check)
MAX_RECORDED_ANNOTATIONS = 15_000
RECORDED_MODEL = "recorded"  # the obstacle model whose obstacles count against MAX_RECORDED_PEOPLE
MAX_WAYPOINTS = 1_000
MAX_STEPS = 100_000
MAX_PEDESTRIAN_SUBSTEPS = 20_000_000  # reactive pedestrians x substeps per step x max_steps

# -- controllers --------------------------------------------------------------------------------------------
MAX_CONTROLLER_VARIABLES = 16  # inputs and outputs together
MAX_TERMS = 32  # per variable
MAX_RULES = 1_000
MAX_UNIVERSE_STEPS = 10_000  # grid steps of one variable's universe
MAX_CONTROLLER_ABS = 1e6  # |x| of universes, breakpoints and fallbacks, in the variable's unit
MAX_STEER_DEG = 180.0  # the steering output's universe lies within [-180, 180] degrees
MAX_SPEED_CM_S = 1_000.0  # speeds: robot limits, the speed output's universe, planner speeds

# -- runs ---------------------------------------------------------------------------------------------------
MAX_EPISODES_PER_RUN = 10_000
MAX_SEED = 9_007_199_254_740_991  # 2^53 - 1: seeds stay exact as float64 (pandas tables of the analysis)
MAX_LAUNCHER_JOBS = 256
MAX_SWEEP_JOBS = 100_000

# -- policies -------------------------------------------------------------------------------------------------------
MAX_POLICY_FIELDS = 64  # a policy's own values per step (Action.fields)
MAX_POLICY_FIELD_CHARS = 256  # a field's name or string value

SIZE_LIMITS: tuple[Limit, ...] = (
    Limit("config file size: scenario, controller and every other file a run composes (bytes)", MAX_DATA_FILE_BYTES,
          "checked before anything parses the file (a 100 MB file kept Hydra busy for minutes); shipped "
          "files are < 10 kB"),
    Limit("YAML nodes per file after alias expansion", MAX_YAML_NODES,
          "Hydra's OmegaConf builds about 5,000 nodes per second, several times per run; aliases (&a / *a) "
          "can expand exponentially (\"billion laughs\")"),
    Limit("YAML nesting depth", MAX_YAML_DEPTH, "the parsers recurse once per level"),
    Limit("dataset manifest size (bytes)", MAX_MANIFEST_BYTES,
          "checked before it is parsed, like a scenario file; about 15,000 episodes"),
    Limit("dataset manifest YAML nodes after alias expansion", MAX_MANIFEST_NODES,
          "about 40 per episode; no YAML tags or interpolations either"),
    Limit("name (scenario, controller, obstacle id; characters)", NAME_MAX_CHARS,
          "names become log file names: letters, digits, _ - . only, not starting with ."),
    Limit("description (characters)", MAX_TEXT_CHARS, "stored in every log's metadata"),
    Limit("scenario numbers, absolute value (cm, cm/s)", int(MAX_COORD_CM),
          "1e9 cm = 10,000 km; coordinates stay exact to about 1e-7 cm"),
    Limit("static_obstacles", MAX_STATIC_OBSTACLES, "sonar and contact checks per step grow with them"),
    Limit("static_obstacles[i].polygon vertices", MAX_POLYGON_VERTICES, "ray casting: beams x edges per step"),
    Limit("polygon vertices in a scenario", MAX_TOTAL_VERTICES,
          "ray casting: 2,000 edges within laser range cost about 5-10 ms per step"),
    Limit("dynamic_obstacles (other than recorded people)", MAX_DYNAMIC_OBSTACLES,
          "tracking (Hungarian) and TPT grow with them"),
    Limit("dynamic_obstacles of model recorded (replayed people)", MAX_RECORDED_PEOPLE,
          "a replay is an array lookup per step and only present people in the sensors' range are sensed: 300 add "
          "about 6 % to a step (runners.bench)"),
    Limit("annotations of a recorded window, all people together", MAX_RECORDED_ANNOTATIONS,
          "the scenario is logged whole in every log (about 46 bytes an annotation; a log's metadata is read up to "
          "1 MB)"),
    Limit("dynamic_obstacles[i].waypoints", MAX_WAYPOINTS, "path bookkeeping per step"),
    Limit("max_steps (also params.max_steps)", MAX_STEPS,
          "an episode of 100,000 steps takes minutes and writes a log of about 200 MB"),
    Limit("reactive pedestrian-substeps per episode (pedestrians x substeps per step x max_steps)",
          MAX_PEDESTRIAN_SUBSTEPS, "an ORCA pedestrian's substep costs about 0.1 ms: 20 million is about an hour"),
    Limit("params.n_static of random_mixed", MAX_STATIC_OBSTACLES, "as static_obstacles (200 placements each)"),
    Limit("params.n_dynamic of random_mixed", MAX_DYNAMIC_OBSTACLES, "as dynamic_obstacles"),
    Limit("controller variables (inputs + outputs)", MAX_CONTROLLER_VARIABLES, "evaluated at every decision"),
    Limit("terms per variable", MAX_TERMS, "sampled memberships are terms x grid points"),
    Limit("rules", MAX_RULES, "evaluated at every decision"),
    Limit("grid steps per universe ((max - min) / resolution)", MAX_UNIVERSE_STEPS,
          "the batch evaluator allocates grid x 1024 floats per output"),
    Limit("controller numbers, absolute value (universes, params, fallback)", int(MAX_CONTROLLER_ABS),
          "widths and centroids stay finite (1e308 overflowed)"),
    Limit("a policy's own fields per step (Action.fields)", MAX_POLICY_FIELDS,
          "logged at every step: 64 fields of 256 characters are 16 kB a step"),
    Limit("characters of a policy field's name or string value", MAX_POLICY_FIELD_CHARS,
          "logged at every step"),
    Limit("episodes per run (seeds per job)", MAX_EPISODES_PER_RUN,
          "every scenario of a run is validated before its first episode; split bigger runs into jobs"),
    Limit("seed + episodes", MAX_SEED, "2^53 - 1: seeds stay exact in the analysis' float64 tables"),
    Limit("hydra.launcher.n_jobs, absolute value (0 is refused)", MAX_LAUNCHER_JOBS, "one worker process each"),
    Limit("jobs of one sweep", MAX_SWEEP_JOBS,
          "Hydra lists and checks every job before the first runs (a million took minutes); batch seeds into "
          "longer jobs: episodes=K seed='range(0,N,K)'"),
)

_CM = "cm"
_M = "a margin or distance in cm; 10 m is far beyond the sensors"
_R = "a distance in cm, at most the longest sensor range (100 m)"
_S = "a speed in cm/s; the robot drives 10-40 cm/s"
_N = "a noise standard deviation in cm; beyond 10 m it swamps every reading"

#: why-texts of the common kinds of range, for the config classes that declare their own (:func:`ranged`)
WHY_MARGIN, WHY_REACH, WHY_SPEED = _M, _R, _S

MIN_DT_S = 1e-3  # a millisecond: below it a step is no navigation step, and speeds per step lose their digits
MAX_DT_S = 60.0  # a minute: sensing and the TPT sample once per step

#: The range of every numeric run-configuration field (dotted as on the command line).
FIELD_RANGES: dict[str, Range] = {
    "seed": Range(0, MAX_SEED, why="numpy seeds are non-negative; see seed + episodes", integer=True),
    "episodes": Range(1, MAX_EPISODES_PER_RUN, why="at least one episode per run", integer=True),
    "dt": Range(MIN_DT_S, MAX_DT_S, "s", "seconds per step; sensing and the TPT sample once per step (the "
                "analysis reads logs in this range only)"),
    "robot.max_turn_deg": Range(0, 180, "deg", "turn per step; 180 reaches every heading", lo_open=True),
    "robot.v_min": Range(0, MAX_SPEED_CM_S, "cm/s", _S, lo_open=True),
    "robot.v_max": Range(0, MAX_SPEED_CM_S, "cm/s", _S, lo_open=True),
    "sensors.sonar.left": Range(-360, 360, "deg", "sector bounds relative to the heading"),
    "sensors.sonar.front": Range(-360, 360, "deg", "sector bounds relative to the heading"),
    "sensors.sonar.right": Range(-360, 360, "deg", "sector bounds relative to the heading"),
    "sensors.sonar.range_cm": Range(0, 10_000, _CM, "sensor range up to 100 m", lo_open=True),
    "sensors.sonar.arc_step_deg": Range(0.1, 30, "deg", "arc sampling: at most 3,600 points per sector"),
    "sensors.sonar.stationary_below_cm_s": Range(0, MAX_SPEED_CM_S, "cm/s", _S),
    "sensors.laser.range_cm": Range(0, 10_000, _CM, "sensor range up to 100 m", lo_open=True),
    "sensors.laser.beams": Range(8, 3_600, "", "ray casting per step grows with the beams", integer=True),
    "sensors.laser.noise_std_cm": Range(0, 1_000, _CM, _N),
    "perception.position_noise_std_cm": Range(0, 1_000, _CM, _N),
    "perception.velocity_noise_std_cm_s": Range(0, 1_000, "cm/s", "a noise standard deviation in cm/s"),
    "perception.confirm_frames": Range(1, 1_000, "frames", "ground truth reports an obstacle from this frame",
                                       integer=True),
    "perception.tracker.cluster_gap_cm": Range(0, 1_000, _CM, _M, lo_open=True),
    "perception.tracker.min_points": Range(3, 3_600, "", "a circle fit needs 3 points; at most every beam",
                                           integer=True),
    "perception.tracker.max_radius_cm": Range(0, 10_000, _CM, _R, lo_open=True),
    "perception.tracker.max_fit_rms_cm": Range(0, 1_000, _CM, _M, lo_open=True),
    "perception.tracker.gate_cm": Range(0, 10_000, _CM, _R, lo_open=True),
    "perception.tracker.max_speed_cm_s": Range(0, MAX_SPEED_CM_S, "cm/s", _S, lo_open=True),
    "perception.tracker.min_speed_cm_s": Range(0, MAX_SPEED_CM_S, "cm/s", _S),
    "perception.tracker.max_missed": Range(0, 1_000, "frames", "frames a lost track is kept", integer=True),
    "perception.tracker.velocity_alpha": Range(0, 1, "", "smoothing factor", lo_open=True),
    "planner.h_wait": Range(0, 1_000, "steps", "compared with waitTime <= n_traj", integer=True),
    "planner.n_traj": Range(1, 1_000, "steps", "steps predicted per table; TPT and planning grow with it",
                            integer=True),
    "planner.safety_margin_cm": Range(0, 1_000, _CM, _M),
    "planner.successor_speeds": Range(0, MAX_SPEED_CM_S, "cm/s", _S, lo_open=True),
    "planner.n_headings": Range(1, 361, "", "successor headings per speed", integer=True),
    "planner.heading_step_deg": Range(0.1, 180, "deg", "evasion tries 2 x max_turn / step headings"),
    "planner.astar_max_expansions": Range(1, 100_000, "", "A* work per plan", integer=True),
    "planner.detour_tolerance_cm": Range(0, 1_000, _CM, _M, lo_open=True),
    "planner.detour_max_steps": Range(1, 1_000, "steps", "greedy and A* depth per plan", integer=True),
    "planner.static_margin_cm": Range(0, 1_000, _CM, _M),
    "planner.cruise_speed": Range(0, MAX_SPEED_CM_S, "cm/s", _S, lo_open=True),
    "planner.plan_tolerance_cm": Range(0, 1_000, _CM, _M, lo_open=True),
    "planner.plan_check_margin_cm": Range(0, 1_000, _CM, _M),
}

#: the metadata key of a config dataclass field's range (:func:`ranged`)
RANGE_KEY = "fuzzynav_range"


def ranged(default: Any, rng: Range, robot_speed: bool = False) -> Any:
    """A config dataclass field with ``default`` and its documented range, for a plug-in's own parameters
    (``margin_cm: float = ranged(10.0, Range(0, 1_000, "cm", "why"))``): parsing and checks read it from the field.
    ``robot_speed``: a speed (cm/s) the policy commands as it is, which must also lie within the robot's speed range
    (``robot.v_min`` .. ``robot.v_max``): the robot would drive another speed than the one configured."""
    return dataclasses.field(default=default, metadata={RANGE_KEY: rng, ROBOT_SPEED_KEY: robot_speed})


ROBOT_SPEED_KEY = "fuzzynav_robot_speed"


def robot_speed_fields(config: Any) -> list[tuple[str, float]]:
    """(field name, value) of each field of a config dataclass declared with ``ranged(..., robot_speed=True)``."""
    if not dataclasses.is_dataclass(config):
        return []
    return [(f.name, getattr(config, f.name)) for f in dataclasses.fields(config) if f.metadata.get(ROBOT_SPEED_KEY)]


def field_range(f: dataclasses.Field, dotted: str) -> Range | None:
    """The range of config field ``f`` (dotted name ``dotted``, as on the command line): its own, else
    :data:`FIELD_RANGES`'s entry; None when it has neither (strings, booleans)."""
    return f.metadata.get(RANGE_KEY) or FIELD_RANGES.get(dotted)


def declared_ranges(cls: type, prefix: str) -> dict[str, Range]:
    """The ranges a config dataclass declares on its own fields (:func:`ranged`), by dotted name under ``prefix``."""
    return {f"{prefix}.{f.name}": f.metadata[RANGE_KEY] for f in dataclasses.fields(cls) if RANGE_KEY in f.metadata}


#: Sequence fields: at most this many items (each item checked against its FIELD_RANGES entry).
FIELD_MAX_ITEMS: dict[str, int] = {"planner.successor_speeds": 20, "sensors.sonar.left": 2,
                                   "sensors.sonar.front": 2, "sensors.sonar.right": 2}


def range_table(ranges: dict[str, Range]) -> str:
    """Configuration ranges as a Markdown table (field, range, why)."""
    lines = ["| field | range | why |", "|---|---|---|"]
    lines += [f"| `{field}` | {rng.text()}{' (integer)' if rng.integer else ''} | {rng.why} |"
              for field, rng in ranges.items()]
    return "\n".join(lines)


def markdown_table() -> str:
    """The limits as two Markdown tables (size and work limits; configuration ranges), for the docs. A policy's
    own parameters: ``python -m fuzzynav.policies``."""
    lines = ["| input | limit | why |", "|---|---|---|"]
    lines += [f"| {lim.field} | {lim.value:,} | {lim.why} |" for lim in SIZE_LIMITS]
    return "\n".join([*lines, "", range_table(FIELD_RANGES)])


if __name__ == "__main__":
    print(markdown_table())
