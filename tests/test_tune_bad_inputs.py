"""Bad input to ``python -m runners.tune`` (issue #39): one line naming the file and the field, a non-zero exit,
nothing lost; the search-space parser and the command fuzzed with hypothesis."""

from __future__ import annotations

import contextlib
import hashlib
import io
import math
import subprocess
import sys

import optuna
import pytest
import yaml
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st
from optuna.distributions import CategoricalDistribution, FloatDistribution, IntDistribution

import runners.tuning.study as study_module
from runners import tune
from runners.sweeping import lock
from runners.tuning.space import SpaceError, format_value, parse_space
from runners.tuning.storage import open_storage
from runners.tuning.study import FAIL_REASON, counted
from tests.conftest import ROOT
from tests.test_tune import TINY, study_file


def run_main(*args: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = tune.main(list(args))
        except SystemExit as exc:  # argparse
            code = exc.code
    return code, out.getvalue(), err.getvalue()


def one_line_error(code: int, err: str, *words: str) -> None:
    assert code != 0
    lines = [line for line in err.split("\n") if line.strip()]  # "\n" only: splitlines also splits at \x1e
    assert len(lines) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in lines[0], lines[0]


@pytest.mark.parametrize(("change", "words"), [
    ({"space": ["planner.h_wait=int(range(5,1))"]}, ["space[0] (planner.h_wait)", "inverted"]),
    ({"space": ["planner.safety_margin_cm=interval(3,3)"]}, ["space[0] (planner.safety_margin_cm)", "empty"]),
    ({"space": []}, ["space", "empty"]),
    ({"space": ["planner.h_wiat=int(range(1,4))"]}, ["space[0] (planner.h_wiat=1)", "h_wiat"]),
    ({"space": ["navigator=choice(fuzzy_tpt,nosuch)"]}, ["space[0] (navigator=nosuch)", "nosuch"]),
    ({"space": ["planner=choice(auto,wait)"]}, ["base[0]", "also searched"]),
    ({"space": ["planner.h_wait=int(range(-3,2))"]}, ["space[0] (planner.h_wait=-3)", "h_wait"]),
    ({"space": ["planner.h_wait=4"]}, ["space[0]", "one value"]),
    ({"objectives": [{"metric": "sucess", "direction": "maximize"}]}, ["objectives[0].metric", "sucess"]),
    ({"objectives": [{"metric": "spl", "direction": "up"}]}, ["objectives[0].direction"]),
    ({"heldout_seeds": {"start": 1, "count": 3}}, ["heldout_seeds", "overlap train_seeds"]),
    ({"scenarios": ["nosuch_world"]}, ["scenarios[0] (nosuch_world)"]),
    ({"sampler": "cmaes", "objectives": [{"metric": "spl", "direction": "maximize"},
                                         {"metric": "time_to_goal_s", "direction": "minimize"}]}, ["sampler"]),
    ({"trials": 0}, ["trials"]),
    ({"bogus": 1}, ["bogus", "unknown field"]),
])
def test_bad_study_file_is_one_line_naming_file_and_field(tmp_path, change, words):
    path = study_file(tmp_path, **change)
    code, _, err = run_main(str(path), "--out", str(tmp_path / "study"))
    one_line_error(code, err, str(path), *words)
    assert code == 2
    assert not (tmp_path / "study" / "study.db").exists()  # nothing stored, no trial run
    assert not (tmp_path / "study" / "trials").exists()


@pytest.mark.parametrize("content", [b"garbage{{{\n", b"SQLite format 3\x00" + b"\x01" * 500])
def test_corrupt_storage_is_one_line_and_left_as_it_was(tmp_path, content):
    out = tmp_path / "study"
    out.mkdir()
    name = "study.journal" if content.startswith(b"garbage") else "study.db"
    (out / name).write_bytes(content)
    code, _, err = run_main(str(study_file(tmp_path)), "--out", str(out))
    one_line_error(code, err, str(out / name))
    assert (out / name).read_bytes() == content
    assert not (out / "trials").exists()


def test_study_folder_in_use_is_refused_and_the_study_kept(tmp_path):
    out, path = tmp_path / "study", study_file(tmp_path, trials=1)
    assert run_main(str(path), "--out", str(out), "--no-heldout")[0] == 0
    before = hashlib.sha256((out / "study.db").read_bytes()).hexdigest()
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from pathlib import Path; "
                               "from runners.sweeping import lock; lock.acquire(Path(sys.argv[1])); print('held', "
                               "flush=True); time.sleep(60)", str(out)], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        code, _, err = run_main(str(path), "--out", str(out), "--trials", "2", "--no-heldout")
    finally:
        holder.kill()
        holder.wait()
    one_line_error(code, err, str(out), "in use by pid")
    assert hashlib.sha256((out / "study.db").read_bytes()).hexdigest() == before
    lock.release(out)


def test_storage_kind_mismatch_is_refused(tmp_path):
    out, path = tmp_path / "study", study_file(tmp_path, trials=1)
    assert run_main(str(path), "--out", str(out), "--no-heldout")[0] == 0
    code, _, err = run_main(str(path), "--out", str(out), "--storage", "journal")
    one_line_error(code, err, "stored in sqlite")
    lock.release(out)


def test_nan_objective_fails_each_trial_with_its_reason_then_one_line(tmp_path):
    # head_on has no ORCA pedestrian: the TPT prediction error for ORCA pedestrians is undefined in every episode
    path = study_file(tmp_path, trials=2, objectives=[{"metric": "tpt_ade_cm_orca", "direction": "maximize"}])
    out = tmp_path / "study"
    code, stdout, err = run_main(str(path), "--out", str(out))
    one_line_error(code, err, "no trial completed", "tpt_ade_cm_orca undefined in head_on", "fill")
    assert code == 1
    trials = optuna.load_study(study_name="tiny", storage=open_storage(out, "sqlite")).get_trials()
    assert [t.state.name for t in trials] == ["FAIL", "FAIL"] and all(map(counted, trials))
    assert "trial 1 failed: objective tpt_ade_cm_orca is nan" in stdout
    lock.release(out)


def test_crashed_trial_is_recorded_and_the_study_goes_on(tmp_path, monkeypatch):
    real = study_module.run_configuration
    calls = []

    def crash_once(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("simulated crash inside the trial")
        return real(*args, **kwargs)

    monkeypatch.setattr(study_module, "run_configuration", crash_once)
    out = tmp_path / "study"
    code, stdout, _ = run_main(str(study_file(tmp_path)), "--out", str(out), "--no-heldout")
    assert code == 0
    trials = optuna.load_study(study_name="tiny", storage=open_storage(out, "sqlite")).get_trials()
    assert [t.state.name for t in trials] == ["COMPLETE", "FAIL", "COMPLETE"]
    assert trials[1].user_attrs[FAIL_REASON] == "crashed: RuntimeError: simulated crash inside the trial"
    assert "trial 1 failed: crashed" in stdout
    lock.release(out)


def test_bad_command_line_is_one_line(tmp_path):
    for args in (["nosuch_study", "--out", str(tmp_path / "s")], [str(study_file(tmp_path)), "--workers", "0"],
                 [str(study_file(tmp_path)), "--trials", "-1"], [str(study_file(tmp_path)), "--out", ""],
                 [str(study_file(tmp_path)), "--out", str(study_file(tmp_path))]):
        code, _, err = run_main(*args)
        one_line_error(code, err)
        assert code == 2
    assert {p.name for p in tmp_path.iterdir()} == {"tiny.yaml"}


ARGS = st.lists(st.one_of(st.sampled_from(["--trials", "--workers", "--storage", "--out", "--no-heldout", "--bogus",
                                           "-h=1", "sqlite", "journal", "--to-journal", "0", "-5", "1e9", "nan", "",
                                           "--launcher", "slurm", "local", "hydra.launcher.partition=x"]),
                          st.text(max_size=12)), max_size=5)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(args=ARGS)
def test_fuzzed_command_line_is_one_line(tmp_path_factory, args):
    tmp = tmp_path_factory.mktemp("argv")
    if "-h" in args or "--help" in args or any(a.startswith("--h") and "--help".startswith(a) for a in args):
        return  # the help text is not an error
    # a study file that cannot run, so that a command line that parses ends at the study file in one line
    bad = tmp / "bad.yaml"
    bad.write_text("space: 1\n")
    code, _, err = run_main(str(bad), *args)
    one_line_error(code, err)
    assert {p.name for p in tmp.iterdir()} <= {"bad.yaml"}


def no_slurm(monkeypatch, tmp_path) -> None:
    """This process as on a machine without Slurm: none of its commands on PATH."""
    (tmp_path / "bin").mkdir(exist_ok=True)
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))


@pytest.mark.parametrize(("args", "words"), [
    (["--launcher", "pbs"], ["--launcher", "invalid choice: 'pbs'"]),
    (["--launcher", "slurm", "--workers", "0"], ["--workers: 0 is outside [1, 256]"]),
    (["--launcher", "slurm", "--workers", "257"], ["--workers: 257 is outside [1, 256]"]),
    (["hydra.launcher.partition=cpu"], ["'hydra.launcher.partition=cpu'", "need --launcher slurm"]),
    (["--launcher", "slurm", "partition=cpu"], ["'partition=cpu'", "hydra.launcher.<key>=<value>"]),
    (["--launcher", "slurm", "hydra.launcher.parttion=cpu"], ["launcher options", "hydra.launcher.parttion"]),
    (["--launcher", "slurm", "hydra.launcher.timeout_min=soon"], ["launcher options", "timeout_min"]),
    (["--launcher", "slurm", "hydra.launcher.tasks_per_node=4"], ["hydra.launcher.tasks_per_node=4", "--workers"]),
    (["--launcher", "slurm", "--storage", "sqlite"], ["--storage sqlite", "journal"]),
    (["--launcher", "slurm", "--workers", "4", "hydra.launcher.partition=cpu"],
     ["--launcher slurm: Slurm's sbatch, srun, squeue not found on PATH", "--launcher local"]),
])
def test_bad_launcher_input_is_one_line_and_nothing_written(tmp_path, monkeypatch, args, words):
    """Slurm workers asked for wrongly, or on a machine without Slurm: one line, exit 2, before any file."""
    no_slurm(monkeypatch, tmp_path)
    code, _, err = run_main(str(study_file(tmp_path)), "--out", str(tmp_path / "study"), *args)
    one_line_error(code, err, *words)
    assert code == 2
    assert {p.name for p in tmp_path.iterdir()} == {"tiny.yaml", "bin"}


def test_a_comparison_passes_the_launcher_and_its_options_to_its_studies(tmp_path, monkeypatch):
    """``--compare`` with ``--launcher slurm`` and an option after the comparison's name: each study's command is
    asked for Slurm workers with that option (here: no Slurm on the machine, one line, exit 2, no trial)."""
    no_slurm(monkeypatch, tmp_path)
    code, _, err = run_main("--compare", "suite_v2", "hydra.launcher.partition=cpu", "--out", str(tmp_path / "cmp"),
                            "--launcher", "slurm")
    one_line_error(code, err, "--launcher slurm: Slurm's sbatch, srun, squeue not found on PATH")
    assert code == 2 and not list((tmp_path / "cmp").rglob("trials"))


LAUNCHER_ARGS = st.lists(st.one_of(
    st.sampled_from(["--launcher", "slurm", "local", "pbs", "--workers", "0", "2", "300", "--storage", "sqlite",
                     "journal", "--to-journal", "--no-heldout", "hydra.launcher.partition=cpu",
                     "hydra.launcher.timeout_min=abc",
                     "hydra.launcher.nodes=2", "+hydra.launcher.additional_parameters.constraint=c",
                     "~hydra.launcher.qos", "hydra.x=1", "hydra.launcher.partition=", "hydra.launcher=1"]),
    st.builds(lambda k, v: f"hydra.launcher.{k}={v}", st.sampled_from(["partition", "account", "qos", "mem_gb",
                                                                       "timeout_min", "bogus"]),
              st.text(max_size=8)),
    st.text(max_size=12)), max_size=5)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(args=LAUNCHER_ARGS)
def test_fuzzed_launcher_options_are_one_line(tmp_path_factory, monkeypatch, args):
    """Any command line that asks for Slurm workers (last: --launcher slurm) on a machine without Slurm ends in
    one line, exit 2, before the study folder is created."""
    if any(a.startswith("-h") or (a.startswith("--h") and "--help".startswith(a)) for a in args):
        return  # the help text is not an error
    tmp = tmp_path_factory.mktemp("launcher")
    no_slurm(monkeypatch, tmp)
    code, _, err = run_main(str(study_file(tmp)), "--out", str(tmp / "study"), *args, "--launcher", "slurm")
    one_line_error(code, err)
    assert code == 2
    assert {p.name for p in tmp.iterdir()} == {"tiny.yaml", "bin"}


# ---- fuzzing -----------------------------------------------------------------------------------------------------

KEYS = st.sampled_from(["planner.h_wait", "planner.safety_margin_cm", "a.b", "planner", "x"])
NUMBERS = st.one_of(st.integers(-10**6, 10**6), st.floats(allow_nan=True, allow_infinity=True))
VALUES = st.one_of(
    st.builds(lambda a, b: f"interval({a},{b})", NUMBERS, NUMBERS),
    st.builds(lambda a, b: f"int(interval({a},{b}))", NUMBERS, NUMBERS),
    st.builds(lambda a, b, c: f"range({a},{b},{c})", NUMBERS, NUMBERS, NUMBERS),
    st.builds(lambda a, b: f"tag(log,interval({a},{b}))", NUMBERS, NUMBERS),
    st.builds(lambda xs: f"choice({','.join(xs)})", st.lists(st.text("abc12._-", min_size=1, max_size=4), max_size=5)),
    st.text(max_size=30),
)


@settings(max_examples=300, deadline=None)
@given(entries=st.lists(st.builds(lambda k, v: f"{k}={v}", KEYS, VALUES), max_size=4))
@example(entries=["planner.safety_margin_cm=int(interval(-1E257,0))"])  # a 258-digit integer bound
def test_space_parser_gives_parameters_or_one_line(entries):
    try:
        parameters = parse_space(entries)
    except SpaceError as err:
        assert "\n" not in str(err) and str(err).startswith("space")
        return
    assert len({p.key for p in parameters}) == len(parameters) == len(entries)
    for p in parameters:
        d = p.distribution
        if isinstance(d, IntDistribution | FloatDistribution):
            assert math.isfinite(d.low) and math.isfinite(d.high) and d.low < d.high
            assert not d.log or d.low > 0
        else:
            assert isinstance(d, CategoricalDistribution) and len(d.choices) >= 2
        # a value of the space written as an override reads back as the same value
        value = d.choices[0] if isinstance(d, CategoricalDistribution) else d.low
        assert p.contains(value)
        assert parse_space([f"{p.key}=choice({format_value(value)},zz_other)"])[0].distribution.choices[0] == value


@settings(max_examples=200, deadline=None)
@given(low=st.floats(-1e6, 1e6), width=st.floats(1e-3, 1e6), log=st.booleans())
def test_intervals_keep_their_bounds(low, width, log):
    low = abs(low) + 1e-3 if log else low
    high = low + width
    if not low < high:
        return
    text = f"planner.safety_margin_cm={'tag(log,' if log else ''}interval({low!r},{high!r}){')' if log else ''}"
    d = parse_space([text])[0].distribution
    assert (d.low, d.high, d.log) == (low, high, log)


JUNK = st.one_of(st.none(), st.booleans(), st.integers(-5, 10**12), st.floats(allow_nan=True),
                 st.text(max_size=20), st.lists(st.text(max_size=10), max_size=3),
                 st.dictionaries(st.text(max_size=8), st.integers(), max_size=2))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(sorted(TINY)), value=JUNK, raw=st.one_of(st.none(), st.binary(max_size=200)))
def test_fuzzed_study_file_is_one_line_or_a_study(tmp_path_factory, field, value, raw):
    from runners.tuning.study_file import MAX_TRIALS

    # a valid study of thousands of trials is no bad input, only a long run (53,106 trials ran for many minutes)
    assume(not (raw is None and field == "trials" and type(value) is int and 3 < value <= MAX_TRIALS))
    tmp = tmp_path_factory.mktemp("fuzz")
    path = tmp / "tiny.yaml"
    if raw is not None:
        path.write_bytes(raw)
    else:
        path.write_text(yaml.safe_dump({**TINY, "trials": 1, "train_seeds": {"start": 0, "count": 1},
                                        field: value}))
    out = tmp / "study"
    code, _, err = run_main(str(path), "--out", str(out), "--no-heldout")
    if code != 0:
        one_line_error(code, err)
        assert str(path) in err or str(out) in err, err
    assert {p.name for p in tmp.iterdir()} <= {"tiny.yaml", "study"}  # nothing written outside the study folder
    lock.release(out)
