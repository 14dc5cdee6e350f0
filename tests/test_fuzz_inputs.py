"""A fuzzer of fuzzynav's inputs (issue 14, item 7): Hypothesis mutates VALID inputs — the shipped
``conf/scenario/*.yaml`` and ``conf/controller/*.yaml``, their text, and the default run configuration as
command-line overrides (strategies in ``tests/fuzz_mutations.py``) — and every example must end in one of:

- a valid result: the input is accepted, its numbers are finite, its names are safe file names, and a few
  simulation steps (in-process) or a whole run (command) work, logging only inside the output directory;
- a clean error: one line (in-process: the exception's message; command: non-zero exit with at most two
  stderr lines, the first ``error: ``) naming the file and the field, no traceback.

Failure classes: ``traceback`` (an unexpected exception), ``hang`` (over the time limit), ``silent`` (accepted,
but wrong: NaN kept, unsafe name, a controller that only ever returns its fallback or never moves, a
simulation that raises, a file outside the output directory), ``unclear`` (an error that is not one line
naming a field).

Most examples run in-process through the parsers (fast); a bounded number run the real command
(``python -m runners.run`` with ``hydra.searchpath`` pointing at the mutated file). CI runs a fixed,
derandomised set (about 45 s on 2 cores); ``FUZZNAV_FUZZ_EXAMPLES=2000`` runs that many random examples per
in-process test (and 1/50 as many commands); ``FUZZNAV_FUZZ_REPORT=file.jsonl`` records every example's
class instead of stopping at the first failure (for counting).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from fuzzynav.controller.fuzzy_spec import sample_membership
from fuzzynav.episode import Episode, EpisodeConfig
from fuzzynav.params import limits
from fuzzynav.scenarios.scenario import scenario_from_dict
from runners.configuration import run_inputs
from runners.configuration.data_files import CONFIG_FILE, SCENARIO_OR_CONTROLLER, DataFileError, check_data_text
from runners.progress import is_progress_line
from tests.conftest import CONF, ROOT
from tests.fuzz_mutations import alias_bomb, mutations, override, paths, text_mutation

EXAMPLES = int(os.environ.get("FUZZNAV_FUZZ_EXAMPLES", "0"))
REPORT = os.environ.get("FUZZNAV_FUZZ_REPORT")
IN_PROCESS_S = 20.0  # time limit of one in-process example (the slowest legal ones take about 3 s)
COMMAND_S = 180.0  # time limit of one command (a run takes 3-10 s on a busy 2-core machine)


def fuzz_settings(ci_examples: int, share: float = 1.0) -> settings:
    """``ci_examples`` fixed examples in CI; ``share`` x ``FUZZNAV_FUZZ_EXAMPLES`` random ones when set."""
    n = max(ci_examples, int(EXAMPLES * share)) if EXAMPLES else ci_examples
    return settings(max_examples=n, deadline=None, derandomize=not EXAMPLES,
                    database=None, print_blob=True,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.filter_too_much, HealthCheck.large_base_example])


def _load(path: Path) -> Any:
    return yaml.safe_load(path.read_text())


SCENARIOS = {p.stem: _load(p) for p in sorted((CONF / "scenario").glob("*.yaml"))}
CONTROLLERS = {p.stem: _load(p) for p in sorted((CONF / "controller").glob("*.yaml"))}
#: whole files to mutate as text: the data files, and the other groups' config files (same size limits)
TEXT_GROUPS = ("scenario", "controller", "navigator", "planner", "perception", "robot", "sensors", "sweep")
TEXTS = {f"{p.parent.name}/{p.name}": p.read_text() for g in TEXT_GROUPS for p in sorted((CONF / g).glob("*.yaml"))}


def _default_config() -> dict[str, Any]:
    """The default run configuration as Hydra composes it, without scenario, controller and Hydra's node."""
    from hydra import compose, initialize_config_dir

    from runners.configuration import schema

    schema.register()
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = OmegaConf.to_container(compose("config"), resolve=True)
    return {k: v for k, v in cfg.items() if k not in ("scenario", "controller")}


CONFIG = _default_config()
BASE_SCENARIO = scenario_from_dict(SCENARIOS["head_on"])
BASE_EVALUATOR = run_inputs.load_evaluator({"controller": CONTROLLERS["table1"]})


# -- outcomes ---------------------------------------------------------------------------------------------------
class Finding(AssertionError):
    """An example that is neither a valid result nor a clean error."""


class Hang(BaseException):  # not an Exception: the code under test must not be able to catch it
    pass


def note(entry: str, steps: list[str], cls: str, detail: str = "") -> None:
    """Record the example's class (``ok``/``error`` or a failure class); a failure fails the test unless a
    report file is being written."""
    if REPORT:
        with open(REPORT, "a") as f:
            f.write(json.dumps({"entry": entry, "class": cls, "steps": steps, "detail": detail[:300]}) + "\n")
        return
    if cls not in ("ok", "error"):
        raise Finding(f"{cls}: {entry} after {steps}: {detail}")


@contextlib.contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    def alarm(signum, frame):
        raise Hang()

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds, 0.5)  # and every 0.5 s after: code catching it cannot hide a hang
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


# texts of Python exceptions leaking into a message instead of a statement about the input
_LEAKS = ("object has no attribute", "unhashable", "not supported between", "NoneType", "object is not",
          "positional argument", "invalid literal", "list index", "KeyError", "Traceback", "too many values",
          "not enough values", "object of type")
_FILE = re.compile(r"^\S+\.yaml(?::\d+)*: \S")  # a problem of the file itself (size, YAML), maybe a field
_FIELD = re.compile(r"^(?:(?:scenario|controller)(?:=\S+)?: )?(?P<field>[^:]+?): \S")


def unclear(message: str) -> str | None:
    """Why an error message is not one clear line naming the file or a field, or None."""
    if "\n" in message or "\r" in message:
        return "more than one line"
    if len(message) > 600:  # "unknown key (allowed: …)" lists every key of a section: up to about 450
        return "longer than 600 characters"
    m = _FIELD.match(message)
    if not _FILE.match(message) and (not m or m.group("field").strip() in ("", "error", "config", "ValueError",
                                                                           "TypeError")):
        return "does not start with a file or field"
    leak = next((t for t in _LEAKS if t in message), None)
    return f"Python's own error text ({leak!r})" if leak else None


def attempt(entry: str, steps: list[str], fn: Callable[[], Any], errors: tuple[type[BaseException], ...]
            ) -> tuple[bool, Any]:
    """Run ``fn`` under the time limit: (True, result), or (False, None) after noting a clean error or a
    failure."""
    try:
        with time_limit(IN_PROCESS_S):
            return True, fn()
    except Hang:
        note(entry, steps, "hang", f"over {IN_PROCESS_S} s")
    except errors as err:
        why = unclear(str(err))
        note(entry, steps, "unclear" if why else "error", f"{why}: {err}" if why else str(err))
    except Exception as err:
        note(entry, steps, "traceback", f"{type(err).__name__}: {err}")
    return False, None


# -- invariants of accepted inputs ----------------------------------------------------------------------------
def nonfinite(value: Any, where: str = "") -> str | None:
    """The first non-finite number in a dataclass tree / container, or None."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            found = nonfinite(getattr(value, f.name), f"{where}.{f.name}")
            if found:
                return found
    elif isinstance(value, tuple | list):
        for i, item in enumerate(value):
            found = nonfinite(item, f"{where}[{i}]")
            if found:
                return found
    elif isinstance(value, float) and not math.isfinite(value):
        return f"{where} = {value}"
    return None


def few_steps(scenario, evaluator, config: EpisodeConfig, steps: int) -> str | None:
    """Run a few steps; a problem (exception, non-finite state) as text, or None."""
    episode = Episode(scenario, evaluator, config, seed=0)
    for _ in range(steps):
        if episode.done:
            break
        record = episode.step()
        state = record.next_state
        if not all(math.isfinite(x) for x in (state.x, state.y, state.heading, state.v)):
            return f"non-finite robot state {state}"
    return None


def scenario_problem(scenario) -> str | None:
    if not limits.NAME_PATTERN.fullmatch(scenario.name):
        return f"unsafe name {scenario.name!r}"
    bad = nonfinite(scenario)
    if bad:
        return f"non-finite number kept: {bad}"
    return few_steps(scenario, BASE_EVALUATOR, EpisodeConfig(), 3)


def controller_problem(evaluator) -> str | None:
    """Accepted controllers must work: finite outputs inside the universes, some rule's output (at the peaks
    of its antecedent terms) differing from the fallback, and a speed > 0 somewhere."""
    spec = evaluator.spec
    if not limits.NAME_PATTERN.fullmatch(spec.name):
        return f"unsafe name {spec.name!r}"
    variables = spec.variables
    mid = {v.name: 0.5 * (v.universe[0] + v.universe[1]) for v in spec.inputs}
    results = []
    for rule in spec.rules[:30]:
        inputs = dict(mid)
        for var_name, term_name in rule.antecedent:
            var = variables[var_name]
            term = var.terms[var.term_index(term_name)]
            inputs[var_name] = float(var.grid[int(np.argmax(sample_membership(term, var.grid, var.universe[1])))])
        dtheta, v = evaluator.evaluate(inputs)
        for value, role in ((dtheta, "dtheta"), (v, "v")):
            lo, hi = spec.output_for(role).universe
            if not (math.isfinite(value) and lo - 1e-9 <= value <= hi + 1e-9):
                return f"{role} = {value} outside the universe [{lo}, {hi}] for {inputs}"
        results.append((dtheta, v))
    if results and all(r == (spec.fallback_dtheta, spec.fallback_v) for r in results):
        return "every rule's output is the fallback (no rule ever contributes)"
    if results and not any(v > 0 for _, v in results):
        return "the speed is never > 0: the robot cannot move under fuzzy control"
    return None


# -- in-process entry points -----------------------------------------------------------------------------------
def check_scenario(data: Any, steps: list[str], entry: str = "scenario") -> None:
    ok, scenario = attempt(entry, steps, lambda: run_inputs.load_scenario({"scenario": data}, 3),
                           (run_inputs.ConfigFileError,))
    if ok:
        ok, problem = attempt(entry, steps, lambda: scenario_problem(scenario), ())
        if ok:
            note(entry, steps, "silent" if problem else "ok", problem or "")


def check_controller(data: Any, steps: list[str], entry: str = "controller") -> None:
    def load():
        evaluator = run_inputs.load_evaluator({"controller": data})
        run_inputs.check_controller_fits(evaluator.spec, EpisodeConfig())
        return evaluator

    ok, evaluator = attempt(entry, steps, load, (run_inputs.ConfigFileError,))
    if ok:
        ok, problem = attempt(entry, steps, lambda: controller_problem(evaluator), ())
        if ok:
            note(entry, steps, "silent" if problem else "ok", problem or "")


def check_config(plain: Any, steps: list[str]) -> None:
    def load():
        if not isinstance(plain, dict):
            raise ValueError(f"config: expected a mapping, got {type(plain).__name__}")
        return run_inputs.run_seeds(plain), run_inputs.episode_config(plain)

    ok, loaded = attempt("config", steps, load, (ValueError,))
    if not ok:
        return
    seeds, config = loaded
    problem = nonfinite(config) or (None if seeds else "no episode to run")
    if not problem:
        ok, problem = attempt("config", steps, lambda: few_steps(BASE_SCENARIO, BASE_EVALUATOR, config, 5), ())
        if not ok:
            return
    note("config", steps, "silent" if problem else "ok", problem or "")


@fuzz_settings(150)
@given(data=st.data())
def test_fuzz_scenarios(data):
    name = data.draw(st.sampled_from(sorted(SCENARIOS)), label="base")
    tree, steps = data.draw(mutations(SCENARIOS[name]), label="mutations")
    check_scenario(tree, [name, *steps])


@fuzz_settings(120)
@given(data=st.data())
def test_fuzz_controllers(data):
    name = data.draw(st.sampled_from(sorted(CONTROLLERS)), label="base")
    tree, steps = data.draw(mutations(CONTROLLERS[name]), label="mutations")
    check_controller(tree, [name, *steps])


CONFIG_PATHS = [p for p in paths(CONFIG) if p]


@fuzz_settings(150)
@given(data=st.data())
def test_fuzz_run_config(data):
    tree, steps = data.draw(mutations(CONFIG, CONFIG_PATHS), label="mutations")
    check_config(tree, steps)


@fuzz_settings(100)
@given(data=st.data())
def test_fuzz_file_texts(data):
    """Whole-file mutations: the data-file check (what runs before Hydra parses a file), then what Hydra
    does with an accepted file (OmegaConf, under the time limit), then the parser."""
    name = data.draw(st.sampled_from(sorted(TEXTS)), label="base")
    raw, what = data.draw(text_mutation(TEXTS[name]), label="mutation")
    steps = [name, what]
    entry = "text"
    group = name.split("/")[0]
    kind = SCENARIO_OR_CONTROLLER if group in ("scenario", "controller") else CONFIG_FILE
    ok, _ = attempt(entry, steps, lambda: check_data_text(raw, "fz.yaml", kind), (DataFileError,))
    if not ok:
        return
    ok, tree = attempt(entry, steps, lambda: yaml.safe_load(raw), ())
    if not ok:
        return
    try:  # Hydra's own rejections (e.g. keys OmegaConf refuses) are Hydra's messages: the commands check those
        with time_limit(IN_PROCESS_S):
            OmegaConf.create(tree if isinstance(tree, dict) else {"x": tree})
    except Hang:
        note(entry, steps, "hang", "OmegaConf took longer than the limit on an accepted file")
        return
    except Exception:
        pass
    if group == "scenario":
        check_scenario(tree, steps, entry)
    elif group == "controller":
        check_controller(tree, steps, entry)


# -- through the real command ----------------------------------------------------------------------------------
def _new_files(root: Path, before: set[Path]) -> set[Path]:
    return {p for p in root.rglob("*") if p.is_file()} - before


def run_command(overrides: list[str], entry: str, steps: list[str], expect: list[str]) -> None:
    """``python -m runners.run`` with ``overrides``: a run that logs inside its output directory only, or a
    clean error naming one of ``expect`` (file or field)."""
    with tempfile.TemporaryDirectory(prefix="fuzznav-fuzz-") as tmp:
        tmp_path = Path(tmp)
        out, cwd = tmp_path / "a" / "b" / "out", tmp_path / "cwd"
        cwd.mkdir()
        before = {p for p in tmp_path.rglob("*") if p.is_file()}
        roots_before = set(Path("/").glob("*.mcap"))
        try:
            res = subprocess.run([sys.executable, "-m", "runners.run", *overrides, f"hydra.run.dir={out}"], cwd=cwd,
                                 capture_output=True, text=True, timeout=COMMAND_S,
                                 env={**os.environ, "PYTHONPATH": str(ROOT)})
        except subprocess.TimeoutExpired:
            note(entry, steps, "hang", f"over {COMMAND_S} s")
            return
        outside = sorted(str(p) for p in _new_files(tmp_path, before) if out not in p.parents)
        outside += sorted(str(p) for p in set(Path("/").glob("*.mcap")) - roots_before)
        if outside:
            note(entry, steps, "silent", f"files outside the output directory: {outside[:3]}")
            return
        lines = [ln for ln in res.stderr.splitlines() if ln.strip() and not is_progress_line(ln)]
        if "Traceback" in res.stderr:
            note(entry, steps, "traceback", res.stderr[-600:])
        elif res.returncode == 0:
            bad = [ln for ln in res.stdout.splitlines() if ": error after" in ln]
            note(entry, steps, "silent" if bad or not list(out.glob("*.mcap")) else "ok",
                 bad[0] if bad else ("" if list(out.glob("*.mcap")) else "exit 0 without a log"))
        elif len(lines) > 2 or not lines or not lines[0].startswith("error: "):
            note(entry, steps, "unclear", res.stderr[-600:])
        elif not any(e in lines[0] for e in expect):
            note(entry, steps, "unclear", f"names none of {expect}: {lines[0]}")
        else:
            note(entry, steps, "error", lines[0])


# max_steps stays as shipped in commands (in-process examples mutate it): a legal 100,000-step run is not a hang
_SHORT = {"max_steps"}


@fuzz_settings(6, share=1 / 50)
@given(data=st.data())
def test_fuzz_commands(data):
    kind = data.draw(st.sampled_from(["scenario", "controller", "text", "override"]), label="kind")
    with tempfile.TemporaryDirectory(prefix="fuzznav-conf-") as conf:
        if kind == "override":
            line = data.draw(override(CONFIG), label="override")
            key = line.lstrip("~+").split("=")[0]
            run_command([line], "command override", [line], [key.split(".")[0], "config:"])
            return
        group = "controller" if kind == "controller" else "scenario"
        if kind == "text":
            name = data.draw(st.sampled_from(sorted(TEXTS)), label="base")
            raw, what = data.draw(text_mutation(TEXTS[name]), label="mutation")
            group, steps = name.split("/")[0], [name, what]
        else:
            bases = CONTROLLERS if kind == "controller" else SCENARIOS
            name = data.draw(st.sampled_from(sorted(bases)), label="base")
            where = [p for p in paths(bases[name]) if not _SHORT & {str(k) for k in p}]
            tree, steps = data.draw(mutations(bases[name], where), label="mutations")
            raw = yaml.safe_dump(tree, sort_keys=False, allow_unicode=False).encode()
            steps = [name, *steps]
        (Path(conf) / group).mkdir()
        (Path(conf) / group / "fz.yaml").write_bytes(raw)
        run_command([f"hydra.searchpath=[file://{conf}]", f"{group}=fz"], f"command {kind}", steps, ["fz.yaml"])


# -- the tester's reported cases that need a generated input (the others are in tests/bad_inputs/) -----------
def test_huge_scenario_file_is_refused_before_it_is_read(tmp_path):
    """A 100 MB scenario file took Hydra over 300 s; now its size alone refuses it (a sparse file: cheap)."""
    (tmp_path / "scenario").mkdir()
    big = tmp_path / "scenario" / "huge.yaml"
    with open(big, "wb") as f:
        f.truncate(100_000_000)
    res = subprocess.run([sys.executable, "-m", "runners.run", f"hydra.searchpath=[file://{tmp_path}]",
                          "scenario=huge", f"hydra.run.dir={tmp_path / 'out'}"], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 2 and res.stderr.count("\n") == 1, res.stderr
    assert "huge.yaml: 100,000,000 bytes, more than the limit of 1,000,000" in res.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("group", ["navigator", "planner", "sweep"])
def test_an_alias_bomb_in_any_config_group_is_one_line_not_a_hang(group, tmp_path):
    """Not only scenario and controller files: a navigator, planner or sweep file that expands to 10^9 nodes hung
    Hydra's loader; every file the command composes is checked as text first (interpolations stay allowed)."""
    (tmp_path / group).mkdir()
    (tmp_path / group / "bomb.yaml").write_text("# @package _global_\n" * (group == "sweep")
                                                + "note: '${seed}'\n" + alias_bomb(10, 9))
    command = "runners.sweep" if group == "sweep" else "runners.run"
    res = subprocess.run([sys.executable, "-m", command, f"hydra.searchpath=[file://{tmp_path}]",
                          f"{group}=bomb", f"hydra.run.dir={tmp_path / 'out'}", f"hydra.sweep.dir={tmp_path / 'out'}"],
                         cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and res.stderr.count("\n") == 1, res.stderr
    assert f"{group}/bomb.yaml:" in res.stderr and "YAML nodes once aliases are expanded" in res.stderr, res.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("edit, says", [
    (("SweepProgress\n", "SweepProgress\n      scenario: x\n"),
     "hydra.callbacks.sweep_progress: got an unexpected keyword argument 'scenario'"),
    (("runners.sweep.SweepProgress", "runners.sweep.NoSuch"),
     "hydra.callbacks.sweep_progress._target_: cannot import 'runners.sweep.NoSuch'"),
])
@pytest.mark.parametrize("command", ["runners.run", "runners.sweep"])
def test_a_callback_hydra_cannot_instantiate_is_one_line(edit, says, command, tmp_path):
    """The fuzzer's find: a sweep preset whose callback has a stray key (a duplicated line) was Hydra's five-line
    ``Error in call to target``; every ``hydra.callbacks`` entry is checked with the config."""
    (tmp_path / "sweep").mkdir()
    (tmp_path / "sweep" / "fz.yaml").write_text((CONF / "sweep" / "default.yaml").read_text().replace(*edit))
    res = subprocess.run([sys.executable, "-m", command, f"hydra.searchpath=[file://{tmp_path}]", "sweep=fz",
                          f"hydra.run.dir={tmp_path / 'out'}", f"hydra.sweep.dir={tmp_path / 'out'}"],
                         cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and says in res.stderr, res.stderr
    assert res.stderr.startswith(f"error: {tmp_path / 'sweep' / 'fz.yaml'}: "), res.stderr
    assert not (tmp_path / "out").exists()


def test_200k_vertex_polygon_is_refused_at_once():
    """A 200,000-vertex polygon ran 297 s without output; the parser counts before converting."""
    import time

    data = {**SCENARIOS["head_on"], "static_obstacles": [{"polygon": [[500 + i * 1e-3, 200] for i in range(200_000)]}]}
    start = time.perf_counter()
    with pytest.raises(run_inputs.ConfigFileError, match=r"static_obstacles\[0\]\.polygon: 200,000 points, more "
                                                         r"than the limit of 1,000"):
        run_inputs.load_scenario({"scenario": data})
    assert time.perf_counter() - start < 1.0


def test_alias_bomb_is_counted_not_built():
    from tests.fuzz_mutations import alias_bomb

    with pytest.raises(DataFileError, match="more than 10,000 YAML nodes once aliases are expanded"), time_limit(5):
        check_data_text(alias_bomb(10, 9), "bomb.yaml")  # 10^9 nodes expanded
