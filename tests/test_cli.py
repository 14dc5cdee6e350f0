"""The real command: `python -m runners.run` with Hydra overrides."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tests.conftest import ROOT

pytestmark = pytest.mark.long  # minutes: started first (tests/conftest.py)


def run_cli(tmp_path, *overrides):
    return subprocess.run([sys.executable, "-m", "runners.run", f"hydra.run.dir={tmp_path}", *overrides],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)


def test_default_run_prints_outcome_and_log_path(tmp_path):
    out = run_cli(tmp_path)
    assert out.returncode == 0, out.stderr
    assert "head_on policy=fuzzy strategy=auto h_wait=2 seed=0: goal after" in out.stdout
    assert f"log: {tmp_path}/head_on__auto__h2__table1__laser__s0.mcap" in out.stdout


def test_overrides_and_episodes(tmp_path):
    out = run_cli(tmp_path, "planner=none", "episodes=2", "seed=5")
    assert out.returncode == 0, out.stderr
    lines = [ln for ln in out.stdout.splitlines() if "strategy=none" in ln]
    assert len(lines) == 2 and "seed=6: collision" in lines[1]
    assert len(list(tmp_path.glob("*.mcap"))) == 2


def test_bad_override_is_one_line_error(tmp_path):
    out = run_cli(tmp_path, "planner.strategy=fly")
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == [
        "error: config: planner.strategy: unknown strategy 'fly' (known: auto, wait, detour, none)"]
    assert not list(tmp_path.glob("*.mcap"))


def test_bench_quick_writes_results(tmp_path):
    out = tmp_path / "bench.json"
    res = subprocess.run([sys.executable, "-m", "runners.bench", "--quick", "--out", str(out)], cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    import json
    data = json.loads(out.read_text())
    for row in data["fuzzy"]:
        assert row["ratio"] > 1 and row["max_disagreement_dtheta_deg"] <= 0.01
        assert row["max_disagreement_v_cm_s"] <= 0.01
    assert "fuzzy decision" in res.stdout and res.stdout.startswith("compiled kernels (")
    from fuzzynav.numerics import compiled

    if os.environ.get("CI"):  # CI's install has a C compiler: every kernel built, in use unless switched off
        assert data["machine"]["kernels_built"] == {k.rpartition(".")[2]: True for k in compiled.KERNELS}
        assert data["machine"]["compiled_kernels"] == dict.fromkeys(compiled.KERNELS, not compiled.switched_off())
    assert data["machine"]["kernels"] == compiled.in_use()
    for section in ("simulation", "sweep", "analysis", "memory", "tuning"):
        assert section in data, section
    assert data["simulation"]["steps_per_s_with_logging"] > 0
    assert [r["model"] for r in data["crowd"]] == ["scripted", "social_force", "orca", "random_walk"]
    assert all(r["pedestrians"] == 20 and r["steps_per_s_with_logging"] > 0 for r in data["crowd"])
    assert "crowds (crowd_crossing, 20 pedestrians" in res.stdout
    rec = data["recorded"]  # issue #38: replaying 300 recorded people
    assert rec["people"] == 300 and rec["replay_us_per_step"] > 0 and rec["mixed_us_per_step"] > 0
    assert 0 < rec["present_per_step"] < 300 and "Recorded people: 300 people" in res.stdout
    assert set(data["simulation"]["us_per_step_by_stage"]) >= {"sensors", "tracking", "logging", "controller"}
    assert data["sweep"]["episodes"] >= 100 and len(data["sweep"]["shapes"]) == 2
    assert data["sweep"]["rounds"] == 1
    job = data["main_job"]  # issue #36: the default sweep as a user runs it, beside one plain process
    assert job["episodes"] == 105 and 0 < job["sweep_efficiency"] <= job["sweep_efficiency_to_last_log"]
    assert job["plain_episodes_per_s"] > 0 and 0 < job["first_step_s"] < job["sweep_wall_s"]
    assert job["report_over_metrics"] > 0
    assert f"sweep efficiency: {job['sweep_efficiency']:.2f}" in res.stdout
    assert data["main_job_targets"][0]["name"] == "sweep efficiency, the default sweep as a whole command"
    for shape in data["sweep"]["shapes"]:
        assert shape["wall_over_ideal"] > 0 and shape["wall_over_all_cores"] > 0 and shape["all_cores_s"] > 0
        assert set(shape["phases_s"]) == {"start-up", "validation + workers", "episodes", "summary", "report"}
        assert shape["jobs"] * shape["episodes_per_job"] == data["sweep"]["episodes"]
    assert data["analysis"]["mean_steps"] > 80  # the target is stated for ~100-step episodes
    base = data["baseline"]  # target 3 side by side with the commit (in a checkout that has it)
    if base["measured"]:
        assert base["logged_ratio"] > 0 and base["plain_ratio"] > 0 and len(base["per_round"]) == 1
        assert "side by side with commit c90ff86" in res.stdout
        for tree in ("earlier", "this"):  # the per-stage before/after
            assert set(base["stage_us_per_step"][tree]) >= {"sensors", "tracking", "logging", "rest"}
    else:
        assert base["why"] and "not measured" in res.stdout
    assert "issue #19 targets:" in res.stdout
    assert {t["name"][:1] for t in data["targets"]} == {"1", "2", "3", "4"}
    assert all(t["met"] in (True, False, None) for t in data["targets"])
    # the performance page shows every section of this run, through the bench's own printers
    from runners.benchmarks import page
    from runners.benchmarks.main_job import FULL_RUN_ONLY

    text = page.render(data)
    shown = {key: title for title, key, _ in page.SECTIONS}
    assert set(data) - {"machine", "quick"} <= set(shown) and set(FULL_RUN_ONLY) <= set(shown)
    assert "Not shown" not in text and f"sweep efficiency: {job['sweep_efficiency']:.2f}" in text
    for key, title in shown.items():
        measured = not text.split(f"## {title}\n\n")[1].startswith("Not measured")
        assert measured == (key in data), key
    assert all(f"## {shown[key]}\n\nNot measured in this run (`--quick` leaves it out" in text for key in FULL_RUN_ONLY)
    targets_36 = {t["name"]: t for t in data["main_job_targets"]}
    assert targets_36["sweep efficiency, a 1,000-episode sweep as a whole command"]["met"] is None
    assert all(t["met"] is None for name, t in targets_36.items() if name.startswith("kernel "))


def test_bench_refuses_an_unwritable_out_before_measuring(tmp_path):
    """``--out /proc/version/b.json`` measured for minutes, then failed: now one line at once."""
    (tmp_path / "dir").mkdir()
    for out, problem in ((tmp_path / "dir", "is a directory"), ("/proc/version/b.json", "is not a directory"),
                         (tmp_path / "no" / "b.json", "does not exist"), ("/dev/null", "not a regular file"),
                         ("/proc/fuzzynav_b.json", "cannot be written")):  # root passes os.access there
        res = subprocess.run([sys.executable, "-m", "runners.bench", "--quick", "--out", str(out)], cwd=ROOT,
                             capture_output=True, text=True, timeout=60)
        assert one_error_line(res).startswith(f"error: --out: {out}: "), res.stderr
        assert problem in res.stderr and res.stdout == ""
        res = subprocess.run([sys.executable, "-m", "runners.benchmarks.report", "--episodes", "1", "--out", str(out)],
                             cwd=ROOT, capture_output=True, text=True, timeout=60)
        assert res.returncode == 2 and problem in res.stderr and res.stdout == "", res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir"]


def test_results_that_cannot_be_written_at_the_end_are_kept_elsewhere(tmp_path):
    """The folder became unwritable while the benchmark measured: the results go to the temporary folder, and
    the message says where (they were lost with a traceback)."""
    from runners.benchmarks.results_file import write_results

    out = tmp_path / "gone" / "bench.json"
    written, problem = write_results(out, '{"x": 1}')
    try:
        assert written != out and written.read_text() == '{"x": 1}'
        assert problem is not None and problem.startswith(f"{out}: cannot be written") and str(written) in problem
    finally:
        written.unlink()


# -- issue 14: sweeps given malformed input ----------------------------------------------------------------------
def run_sweep(*overrides: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "runners.sweep", "scenario=head_on", "episodes=1",
                           "hydra.launcher.n_jobs=1", *overrides], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)


def one_error_line(res: subprocess.CompletedProcess) -> str:
    """The only stderr line of a refused command (exit 2, no traceback)."""
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2 and len(lines) == 1 and "Traceback" not in res.stderr, res.stderr[-2000:]
    return lines[0]


def test_a_job_dir_outside_the_sweep_dir_is_refused(tmp_path):
    """``hydra.sweep.subdir=../escaped`` wrote the job's logs outside the sweep directory, exit 0."""
    for subdir in ("../escaped", str(tmp_path / "abs"), "a/../../escaped", "''"):
        res = run_sweep(f"hydra.sweep.dir={tmp_path / 's'}", f"hydra.sweep.subdir={subdir}", "planner=auto")
        assert one_error_line(res).startswith("error: config: hydra.sweep.subdir: "), res.stderr
        assert "is not a directory inside the sweep directory" in res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_a_job_dir_shared_by_the_jobs_of_a_sweep_is_refused(tmp_path):
    """``planner.safety_margin_cm=5,10 hydra.sweep.subdir=same``: every job wrote into one directory, the margin-10
    logs replaced the margin-5 logs of the same name, '7 episode logs', exit 0 (hostile14b w_margin_same_name)."""
    res = run_sweep(f"hydra.sweep.dir={tmp_path / 's'}", "scenario.max_steps=20", "planner=auto,wait",
                    "planner.safety_margin_cm=5,10", "hydra.sweep.subdir=same")
    assert one_error_line(res) == ("error: config: hydra.sweep.subdir: 'same' is the same directory for each of "
                                   "the 4 jobs (logs of the same name would replace each other); include "
                                   "${hydra.job.num}")
    assert not (tmp_path / "s").exists()
    # one job may use any directory; a directory per job is accepted
    res = run_sweep(f"hydra.sweep.dir={tmp_path / 'one'}", "scenario.max_steps=20", "planner=auto",
                    "hydra.sweep.subdir=same")
    assert res.returncode == 0, res.stderr[-2000:]
    assert len(list((tmp_path / "one" / "same").glob("*.mcap"))) == 1
    res = run_sweep(f"hydra.sweep.dir={tmp_path / 'per'}", "scenario.max_steps=20", "planner=auto",
                    "planner.safety_margin_cm=5,10", "hydra.sweep.subdir=m${hydra.job.num}")
    assert res.returncode == 0, res.stderr[-2000:]
    assert len(list((tmp_path / "per").rglob("*.mcap"))) == 2


def test_a_swept_key_left_out_of_override_dirname_is_refused(tmp_path):
    """``hydra.sweep.subdir=${hydra.job.override_dirname}`` with the swept margin in ``exclude_keys``: both jobs
    shared one directory and the second replaced the first's logs. Excluding the seed stays allowed: it is in
    every log's name."""
    dirname = "hydra.sweep.subdir=${hydra.job.override_dirname}"
    res = run_sweep(f"hydra.sweep.dir={tmp_path / 's'}", "scenario.max_steps=3", "planner=auto", dirname,
                    "hydra.job.config.override_dirname.exclude_keys=[planner.safety_margin_cm]",
                    "planner.safety_margin_cm=10,12")
    assert one_error_line(res).startswith("error: config: hydra.job.config.override_dirname.exclude_keys: "
                                          "planner.safety_margin_cm is swept but left out of hydra.sweep.subdir")
    assert not (tmp_path / "s").exists()
    res = run_sweep(f"hydra.sweep.dir={tmp_path / 'seeds'}", "scenario.max_steps=3", "planner=auto", dirname,
                    "hydra.job.config.override_dirname.exclude_keys=[seed]", "seed=0,1")
    assert res.returncode == 0, res.stderr[-2000:]
    assert len(list((tmp_path / "seeds").rglob("*.mcap"))) == 2


def test_a_log_never_replaces_another_episodes_log(tmp_path):
    """Whatever shares a directory (two runs with different configs into one ``hydra.run.dir``), a finished log of
    another episode is never replaced: one line, exit 1, the first log intact. The same episode again is a re-run
    and replaces its own log."""
    def run(*overrides):
        return subprocess.run([sys.executable, "-m", "runners.run", f"hydra.run.dir={tmp_path}",
                               "scenario.max_steps=3", *overrides], cwd=ROOT, capture_output=True, text=True,
                              timeout=300)

    assert run().returncode == 0
    (log,) = tmp_path.glob("*.mcap")
    before = log.read_bytes()
    res = run("planner.safety_margin_cm=12")
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 1 and len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    assert lines[0] == (f"error: {log}: cannot write the log: the log of another episode (another config) is already "
                        "there and would be replaced (choose another output directory; in a sweep, a "
                        "hydra.sweep.subdir per job)")
    assert log.read_bytes() == before and [p.name for p in tmp_path.glob(".*.partial")] == []
    assert run().returncode == 0


def test_a_sweep_in_a_single_run_is_one_line(tmp_path):
    """``runners.run planner=auto,wait``: Hydra printed five lines of options."""
    res = subprocess.run([sys.executable, "-m", "runners.run", f"hydra.run.dir={tmp_path / 'o'}", "planner=auto,wait"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert one_error_line(res) == ("error: config: planner: 'auto,wait' is a sweep and runners.run runs one "
                                   "configuration: use python -m runners.sweep (or quote the value for a string: "
                                   "planner='...')")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("flag", ["-m", "--multirun"])
def test_hydras_multirun_of_a_single_run_names_the_sweep_command(tmp_path, flag):
    """``runners.run -m planner=wait,detour`` wrote logs but printed no outcome, no summary and no report."""
    res = subprocess.run([sys.executable, "-m", "runners.run", flag, "planner=wait,detour",
                          f"hydra.sweep.dir={tmp_path / 's'}", "scenario=head on"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert one_error_line(res) == (
        "error: -m/--multirun: runners.run runs one configuration; for a sweep (all cores, progress, a summary and "
        f"the report) use: python -m runners.sweep planner=wait,detour hydra.sweep.dir={tmp_path / 's'} "
        "'scenario=head on'")
    assert not (tmp_path / "s").exists() and not (ROOT / "multirun" / "s").exists()


@pytest.mark.parametrize("order", ["custom,dwa", "dwa,custom"])
def test_a_policy_target_in_a_sweep_over_navigators_says_how(tmp_path, order):
    """``navigator=custom,dwa navigator._target_=...``: Hydra said "Key '_target_' is not in struct"."""
    (tmp_path / "my_policies.py").write_text(
        "from fuzzynav.policies.base import Action\n\n\nclass Go:\n    def __init__(self, params, context):\n"
        "        pass\n\n    def act(self, observation):\n        return Action(0.0, 25.0)\n")
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "scenario=head_on", "episodes=1",
                          f"hydra.sweep.dir={tmp_path / 's'}", f"navigator={order}",
                          "navigator._target_=my_policies.Go"], cwd=ROOT, capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONPATH": str(tmp_path)})
    assert one_error_line(res) == (
        "error: config: navigator._target_: the override applies to every job of the sweep, and navigator=dwa has "
        "no such key: give your policy its own navigator option (my_conf/navigator/mine.yaml holding "
        "'_target_: my_policies.Go', with hydra.searchpath=[file://$PWD/my_conf]) and sweep navigator=mine,dwa "
        "(docs/tutorials/policy.md, section 2)")
    assert not (tmp_path / "s").exists()


def test_an_empty_sweep_is_refused(tmp_path):
    res = run_sweep(f"hydra.sweep.dir={tmp_path / 's'}", "seed=range(5,0)", "planner=auto")
    assert one_error_line(res) == "error: config: seed: range(5,0) selects no value (an empty sweep)"
    assert not (tmp_path / "s").exists()


def test_an_unreadable_override_names_its_key(tmp_path):
    res = run_sweep(f"hydra.sweep.dir={tmp_path / 's'}", "planner=auto,")
    assert one_error_line(res).startswith("error: config: planner: cannot read 'planner=auto,': ")


def test_an_override_written_as_an_option_is_one_line(tmp_path):
    """``--planner.h_wait=2`` printed Hydra's 8-line usage."""
    res = run_cli(tmp_path, "--planner.h_wait=2")
    assert one_error_line(res) == ("error: --planner.h_wait=2: unknown option (a config override has no dashes: "
                                   "planner.h_wait=2); see --help")
    assert not list(tmp_path.glob("*.mcap"))


def test_two_spellings_of_one_value_are_counted_as_a_duplicate(tmp_path):
    """``5,5.0`` runs the same episode twice: the summary said "(1 unreadable)"; a copy is a duplicate."""
    res = run_sweep(f"hydra.sweep.dir={tmp_path / 's'}", "planner=auto", "planner.safety_margin_cm=5,5.0")
    assert res.returncode == 0, res.stderr[-2000:]
    assert f"2 episode logs in {tmp_path / 's'} (1 left out: 1 duplicate)" in res.stdout, res.stdout
    assert "unreadable" not in res.stdout


def test_an_empty_output_dir_is_refused(tmp_path):
    """``hydra.run.dir=''`` wrote the log, run.log and .hydra/ into the current directory, exit 0."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}  # run from tmp_path, so that a file in the cwd is seen
    for value in ("''", "' '"):
        res = subprocess.run([sys.executable, "-m", "runners.run", f"hydra.run.dir={value}"], cwd=tmp_path,
                             capture_output=True, text=True, timeout=300, env=env)
        assert one_error_line(res).startswith("error: config: hydra.run.dir: "), res.stderr
        res = subprocess.run([sys.executable, "-m", "runners.sweep", f"hydra.sweep.dir={value}", "planner=auto"],
                             cwd=tmp_path, capture_output=True, text=True, timeout=300, env=env)
        assert one_error_line(res).startswith("error: config: hydra.sweep.dir: "), res.stderr
    assert list(tmp_path.iterdir()) == []


TOO_MANY = "params.n: 2,000 pedestrians, more than the limit of 100"


@pytest.mark.parametrize("overrides, says", [
    (["scenario=crowd_crossing,corridor_flow", "scenario.params.n=4"],
     "config: scenario.params: Key 'params' is not in struct (the sweep's own config, with each swept group at its "
     "default); write ++scenario.params.n=4 to set it in every job where it applies"),
    (["scenario=crowd_crossing", "scenario.params.n=0,2000"], TOO_MANY),
    (["scenario=crowd_crossing", "scenario.params.n=2000,3"], TOO_MANY),
])
def test_a_sweep_that_hydra_or_a_later_job_would_refuse_is_one_line_before_any_job(overrides, says, tmp_path):
    """Hydra composes a sweep's own config with the swept groups at their defaults (its seven-line error, exit 1);
    numbers swept are checked at both ends (2000 was refused by its job, after the first job's logs)."""
    out = tmp_path / "s"
    res = run_sweep(*overrides, "planner=auto", f"hydra.sweep.dir={out}")
    assert one_error_line(res).endswith(says), res.stderr
    assert not out.exists()


def test_the_bench_says_first_which_forms_it_times_and_why():
    from runners.bench import kernels_line

    names = ("fuzzynav.sensing._raycast", "fuzzynav.pedestrians._orca")
    built, none_built = {"_raycast": True, "_orca": True}, {"_raycast": False, "_orca": False}
    head = "compiled kernels (fuzzynav/numerics/compiled.py): "
    assert kernels_line(dict.fromkeys(names, True), built, False) == head + "all 2 in use"
    assert kernels_line({names[1]: True}, {"_orca": True}, False) == head + "_orca in use"
    assert kernels_line(dict.fromkeys(names, False), none_built, False) == \
        head + "none in use, the Python/numpy forms run (not built at install: no C compiler?)"
    assert kernels_line(dict.fromkeys(names, False), built, True) == \
        head + "none in use, the Python/numpy forms run (FUZZYNAV_KERNEL=python)"
    assert kernels_line({names[0]: True, names[1]: False}, built, False) == \
        head + "1 of 2 in use; _orca Python/numpy form (FUZZYNAV_KERNELS_OFF)"
    assert kernels_line({names[0]: False, names[1]: False}, {"_raycast": False, "_orca": True}, False) == \
        head + "0 of 2 in use; _raycast Python/numpy form (not built at install: no C compiler?), _orca " \
               "Python/numpy form (FUZZYNAV_KERNELS_OFF)"


@pytest.mark.parametrize("command, args, expect", [
    ("runners.run", ["+episode=5"], "error: config: episode: no such setting (did you mean episodes?)"),
    ("runners.sweep", ["planner=auto,wait", "+episode=3"], "error: config: episode: no such setting"),
    ("runners.run", ["hydra.mode=MULTIRUN"], "error: -m/--multirun: runners.run runs one configuration"),
    ("runners.sweep", ["planner=auto,wait", "hydra.run.dir=/tmp/x"],
     "error: hydra.run.dir: a single run's folder; a sweep writes into hydra.sweep.dir=/tmp/x"),
    ("runners.run", ["hydra.sweep.dir=/tmp/x"], "error: hydra.sweep.dir: a sweep's folder; a single run writes into"),
    ("runners.run", ["--experimental-rerun", "/dev/null"], "error: --experimental-rerun: Hydra's option is not"),
    ("runners.run", ["--shell-completion"], "error: --shell-completion: Hydra's option is not supported"),
    ("runners.run", [os.fsdecode(b"scenario.description='a\xff'")],
     "error: argument 4 (scenario.description='a\\xff'): not UTF-8 text"),
    ("runners.sweep", ["planner=auto", "dt=interval(0.5,1)"], "error: config: dt: interval(0.5,1) is a continuous"),
    ("runners.sweep", ["planner=auto", "hydra.sweeper.max_batch_size=0"],
     "error: config: hydra.sweeper.max_batch_size: 0 is not a number of jobs"),
    ("runners.sweep", ["planner=auto", "hydra.sweeper.max_batch_size=abc"], "error: config: hydra.sweeper.max_batch"),
    ("runners.sweep", ["planner=auto", "hydra.launcher.n_jobs=null"],
     "error: config: hydra.launcher.n_jobs: must be an integer"),
    ("runners.sweep", ["planner=auto", "hydra.launcher.n_jobs=1,2"],
     "error: config: hydra.launcher.n_jobs: Hydra's own settings cannot be swept"),
    ("runners.sweep", ["planner=auto", "+hydra.launcher.bogus=1"],
     "error: config: hydra.launcher: got an unexpected keyword argument 'bogus'"),
    ("runners.sweep", ["planner=auto", "+hydra.sweeper.bogus=1"],
     "error: config: hydra.sweeper: got an unexpected keyword argument 'bogus'"),
    ("runners.sweep", ["--run"], "error: --run: runners.sweep runs a sweep; one configuration is python -m"),
    ("runners.sweep", ["--config-name", "nope"], "error: --config-name nope: no such config in conf/"),
    ("runners.run", ["--config-name", "nope"], "error: --config-name nope: no such config in conf/"),
    ("runners.run", ["--config-dir", "/nonexistent/d"], "error: --config-dir /nonexistent/d: not a folder"),
    ("runners.sweep", ["--cfg", "job", "planner=auto,wait"],
     "error: config: planner: 'auto,wait' is a sweep; --cfg and --info show one configuration of the sweep"),
    # a second hostile review: Hydra's parser takes options abbreviated, the commands' checks looked for them whole
    ("runners.run", ["--multi"], "error: -m/--multirun: runners.run runs one configuration"),
    ("runners.sweep", ["--ru"], "error: --run: runners.sweep runs a sweep"),
    ("runners.run", ["--run", "--cfg", "job"], "error: --run and --cfg: Hydra takes one of --run, --multirun"),
    ("runners.sweep", ["--cfg", "job", "--info=all"], "error: --cfg and --info: Hydra takes one of"),
    ("runners.run", ["--cfg"], "error: argument --cfg/-c: expected one argument (see --help)"),
    ("runners.run", ["--cfg", "bogus"], "error: argument --cfg/-c: invalid choice: 'bogus'"),
    ("runners.sweep", ["--multirun=1"], "error: argument --multirun/-m: ignored explicit argument '1'"),
    ("runners.sweep", ["sweep=quick,policies"], "error: sweep=quick,policies: a sweep runs one preset of conf/sweep/"),
    ("runners.sweep", ["~sweep"], "error: ~sweep: a sweep runs one preset"),
    ("runners.sweep", ["sweep=glob(q*)"], "error: sweep=glob(q*): a sweep runs one preset"),
    ("runners.sweep", ["seed=range(0,4,0)"], "error: config: seed: range(0,4,0) cannot be listed (a range's step"),
    ("runners.sweep", ["planner=auto", "planner.h_wait=range(1,3,0.0)"], "error: config: planner.h_wait: range(1,3"),
    ("runners.sweep", ["seed=range(0,100000000)"], "error: config: seed: range(0,100000000): the sweep has more than "
                                                   "100,000 jobs"),
    ("runners.sweep", ["planner=glob(zzz*)"], "error: config: planner: glob(zzz*) selects no option (an empty sweep)"),
    ("runners.sweep", ["planner=wait", "planner.safety_margin_cm=5.0,nan,20.0"],
     "error: config: planner.safety_margin_cm: must be finite, got nan"),
    ("runners.sweep", ["+hydra.sweeper.params.planner.h_wait='1,2'"],
     "error: config: hydra.sweeper.params.planner.h_wait: a swept setting with dots cannot be added"),
    ("runners.run", ["~planner", "planner=wait"], "error: config: ~planner: deletes the choice of the config group"),
    ("runners.run", ["-cp", "nope"], "error: --config-path: the folder of an application's primary config"),
    ("runners.sweep", ["hydra.mode=RUN"], "error: hydra.mode=RUN: runners.sweep runs a sweep"),
])
def test_arguments_a_command_cannot_take_are_one_line_before_anything_runs(tmp_path, command, args, expect):
    """Hostile review of the sweep: each was accepted (a typo with '+', a multirun that wrote into ./multirun), or a
    traceback (interval(), max_batch_size, Hydra's options), or logs no tool could read (a byte that is not UTF-8)."""
    out = ["hydra.run.dir" if command == "runners.run" else "hydra.sweep.dir"]
    given = any(a.startswith(("hydra.run.dir", "hydra.sweep.dir")) for a in args)
    own = [] if given else [f"{out[0]}={tmp_path / 'o'}"]
    res = subprocess.run([sys.executable, "-m", command, "scenario=head_on", "episodes=1", *own, *args], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert one_error_line(res).startswith(expect), res.stderr
    assert not (tmp_path / "o").exists()


def test_a_sweep_job_whose_combination_of_values_is_invalid_fails_alone(tmp_path):
    """Each swept value passes the check, one combination does not (v_max 30 with a successor speed of 40): that
    job ended the whole sweep at once (exit 2, no summary, other jobs' episodes cut as .partial logs); now it fails
    alone, named, and the others' episodes are in the summary."""
    sweep = tmp_path / "s"
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "scenario=head_on", "planner=auto", "episodes=1",
                          "robot.v_max=45,30", "planner.successor_speeds=[10,25,30],[10,25,40]",
                          f"hydra.sweep.dir={sweep}"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 1 and "Traceback" not in res.stderr, res.stderr
    assert "error: job 3 failed: config: planner.successor_speeds[2]: 40 cm/s is outside" in res.stderr
    assert "3 episode(s) finished" in res.stdout and (sweep / "summary.csv").is_file()
    assert not list(sweep.rglob(".*.partial"))


@pytest.mark.parametrize("args, expect", [(["--cfg", "job", "planner=wait"], "strategy: wait"),
                                          (["-c", "hydra"], "sweeper:"),
                                          (["--info", "searchpath", "scenario=head_on"], "Config search path")])
def test_hydras_show_options_before_overrides_show_the_sweeps_config(args, expect):
    """The sweep put its preset in front of the arguments: before options followed by overrides it was a second group
    of overrides, and Hydra refused the command ("unrecognized arguments: planner=wait"); with ``--cfg`` the added
    ``--multirun`` was a traceback (only one of --multirun and --cfg)."""
    res = subprocess.run([sys.executable, "-m", "runners.sweep", *args], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0 and expect in res.stdout and not res.stderr.strip(), res.stderr


def test_the_sweeps_preset_goes_where_hydra_reads_overrides():
    from runners.sweep import with_preset

    assert with_preset(["--cfg", "job", "planner=wait"], "sweep=default") == ["--cfg", "job", "sweep=default",
                                                                             "planner=wait"]
    assert with_preset(["planner=wait", "--cfg", "job"], "sweep=default") == ["sweep=default", "planner=wait",
                                                                             "--cfg", "job"]
    assert with_preset(["--info"], "sweep=default") == ["sweep=default", "--info"]
    assert with_preset([], "sweep=default") == ["sweep=default"]


@pytest.mark.parametrize("params, says", [
    ("{planner: 'nope,wait'}", "error: config: no config 'planner/nope' (available: auto, "),
    ("+hydra.sweeper.params.seed='1,abc'", "error: config: seed: Value 'abc' of type 'str' could not be converted"),
])
def test_a_swept_value_of_the_sweepers_params_that_does_not_compose_is_one_line(tmp_path, params, says):
    """A value swept by ``hydra.sweeper.params`` (a preset's, or given whole on the command line) is composed by the
    sweeper, not by the command's check: Hydra printed a dozen lines (the group's options, the search path)."""
    sweep = tmp_path / "s"
    given = params if params.startswith("+") else f"hydra.sweeper.params={params}"
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "episodes=1", given,
                          f"hydra.sweep.dir={sweep}"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    line = one_error_line(res)
    assert line.startswith(says) and "(the sweep's job " in line, line
    assert not list(sweep.rglob("*.mcap*")) and not list(sweep.glob("[0-9]*"))


@pytest.mark.parametrize("params, says", [
    ("+hydra.sweeper.params.seed='range(0,4,0)'", "error: config: seed: range(0,4,0) cannot be listed"),
    ("+hydra.sweeper.params.seed='range(0,-2)'", "error: config: seed: range(0,-2) selects no value"),
    ("+hydra.sweeper.params.seed='range(0,10000000)'", "error: config: the sweep has 10,000,000 jobs, more than"),
])
def test_a_sweep_of_the_sweepers_params_that_cannot_run_is_one_line(tmp_path, params, says):
    """The preset's sweeps are listed by Hydra's sweeper, after the command's check: a zero step was a traceback, an
    empty range ran no job, ten million jobs spent minutes before the first (a first SIGTERM did not end it)."""
    sweep = tmp_path / "s"
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "episodes=1", "scenario=head_on", "planner=wait",
                          params, f"hydra.sweep.dir={sweep}"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and one_error_line(res).startswith(says), res.stderr
    assert not list(sweep.rglob("*.mcap*"))


@pytest.mark.parametrize("args", [["planner=wait", "--cfg", "job", "seed=3"], ["planner=wait", "-cjob", "seed=3"],
                                  ["planner=wait", "--cf", "job", "seed=3"]])
@pytest.mark.parametrize("command", ["runners.run", "runners.sweep"])
def test_options_among_the_overrides_are_read_as_hydras(command, args):
    """Overrides on both sides of an option were refused with Hydra's eight lines of usage; ``-cjob`` and ``--cf``
    (Hydra's parser takes them) were given ``--multirun`` by the sweep: a traceback."""
    res = subprocess.run([sys.executable, "-m", command, *args], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0 and not res.stderr.strip(), res.stderr
    assert "strategy: wait" in res.stdout and "seed: 3" in res.stdout


def test_a_config_dir_provides_options_of_the_groups(tmp_path):
    """``--config-dir`` with a scenario of the user's: the command's check composed from conf/ alone and refused it
    ("no config 'scenario/mine'"), which Hydra itself runs."""
    (tmp_path / "mine" / "scenario").mkdir(parents=True)
    text = (ROOT / "conf" / "scenario" / "head_on.yaml").read_text().replace("name: head_on", "name: mine")
    (tmp_path / "mine" / "scenario" / "mine.yaml").write_text(text)
    res = subprocess.run([sys.executable, "-m", "runners.run", "--config-dir", str(tmp_path / "mine"),
                          "scenario=mine", "episodes=1", f"hydra.run.dir={tmp_path / 'out'}"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("mine policy=fuzzy") and list((tmp_path / "out").glob("mine__*.mcap"))


def test_the_canonical_command_line_keeps_the_overrides_in_their_order():
    from runners.configuration.command_line import canonical_arguments

    args, problem = canonical_arguments(["a=1", "--debug", "b=2", "-cjob", "c=3", "--resolve", "d=4"])
    assert problem is None and args == ["--resolve", "--cfg", "job", "--debug", "a=1", "b=2", "c=3", "d=4"]
    args, problem = canonical_arguments(["a=1", "--debug", "b=2", "--multi", "c=3"])
    assert problem is None and args == ["--multirun", "--debug", "a=1", "b=2", "c=3"]
    assert canonical_arguments(["--help", "x=1"]) == (["--help", "x=1"], None)
    assert canonical_arguments(["--version"]) == (["--version"], None)


def test_a_swept_value_of_the_sweepers_params_that_a_run_refuses_is_one_line(tmp_path):
    """Composed, but out of range: the jobs of ``episodes=1`` ran, the ``episodes=0`` one failed, exit 1 and a resume
    command that could never complete the sweep."""
    sweep = tmp_path / "s"
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "scenario=head_on", "planner=wait",
                          "+hydra.sweeper.params.episodes='0,1'", f"hydra.sweep.dir={sweep}"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and one_error_line(res).startswith(
        "error: config: episodes: must be in [1, 10,000], got 0 (the sweep's job "), res.stderr
    assert not list(sweep.rglob("*.mcap*"))
