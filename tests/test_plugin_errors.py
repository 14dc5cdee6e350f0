"""A broken plug-in of another package (an entry point that cannot be loaded) is one line naming the entry point,
exit 2, from every command that meets it: never a traceback from inside Hydra or the registry.

The entry points are declared by a ``*.dist-info`` folder on ``PYTHONPATH`` (what an installed package leaves), so
nothing is installed into the test environment."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT

pytestmark = pytest.mark.long  # minutes: started first (tests/conftest.py)

CASES = {
    "fuzzynav.conf": ("no_such_pkg.conf", []),
    "fuzzynav.policies": ("no_such_mod:Policy", ["navigator.policy=dwa"]),
    "fuzzynav.pedestrians": ("no_such_mod:Model", ["scenario=crowd_crossing"]),
    "fuzzynav.generators": ("no_such_mod:generate", ["scenario=random_mixed"]),
}


def _broken_package(tmp_path: Path, group: str, value: str) -> dict[str, str]:
    info = tmp_path / "site" / "broken_plugin-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[{group}]\nbroken = {value}\n")
    return {**os.environ, "PYTHONPATH": str(tmp_path / "site")}


@pytest.mark.parametrize("group", sorted(CASES))
@pytest.mark.parametrize("command", ["runners.run", "runners.sweep"])
def test_a_broken_entry_point_is_one_line(group, command, tmp_path):
    value, overrides = CASES[group]
    env = _broken_package(tmp_path, group, value)
    args = [*overrides, "episodes=1", f"hydra.run.dir={tmp_path / 'run'}", f"hydra.sweep.dir={tmp_path / 'sweep'}"]
    if command == "runners.sweep":
        args.append("sweep=quick")
    proc = subprocess.run([sys.executable, "-m", command, *args], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=300, stdin=subprocess.DEVNULL)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and len(lines) == 1, proc.stderr[-2000:]
    assert "entry point 'broken'" in lines[0] and group in lines[0], lines[0]
    assert not (ROOT / "outputs").exists() or not any((ROOT / "outputs").rglob(tmp_path.name))


def _package_with_module(tmp_path: Path, entry_points: str, module: str) -> dict[str, str]:
    site = tmp_path / "site"
    info = site / "hplug-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: hplug\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(entry_points)
    (site / "hplug_mod.py").write_text(module)
    return {**os.environ, "PYTHONPATH": str(site)}


@pytest.mark.parametrize("module, entry, says", [
    ("raise SystemExit(0)\n", "evil = hplug_mod:P", "loading it failed: SystemExit"),
    ("class E(BaseException):\n    pass\nraise E('custom')\n", "evil = hplug_mod:P", "loading it failed: E: custom"),
    ("P = 42\n", "evil = hplug_mod:P", "names int, not a factory"),
    ("class P:\n    config_class = dict\n", "evil = hplug_mod:P", "config_class must be a dataclass"),
    ("class P:\n    pass\n", "Upper = hplug_mod:P", "expected a lowercase letter"),
    ("class P:\n    pass\n", "dwa = hplug_mod:P", "'dwa' is already registered"),
])
def test_a_bad_policy_plug_in_is_one_line_naming_its_entry_point(tmp_path, module, entry, says):
    env = _package_with_module(tmp_path, f"[fuzzynav.policies]\n{entry}\n", module)
    for args in (["-m", "runners.run", "navigator=dwa", f"hydra.run.dir={tmp_path / 'run'}"],
                 ["-m", "fuzzynav.policies"]):
        proc = subprocess.run([sys.executable, *args], cwd=tmp_path, env=env, capture_output=True, text=True,
                              timeout=300, stdin=subprocess.DEVNULL)
        lines = proc.stderr.strip().splitlines()
        assert proc.returncode == 2 and len(lines) == 1, (args, proc.returncode, proc.stderr[-2000:])
        assert "entry point" in lines[0] and says in lines[0], lines[0]


def test_resume_reruns_the_episodes_of_a_plug_in_whose_code_changed(tmp_path):
    """The code of another package's policy is part of its episodes' identity, as a ``_target_`` policy's is: a
    resumed sweep after the code changed runs them again instead of keeping logs of the old code."""
    from analysis.episode_log import load_episode

    module = ("from fuzzynav.policies.base import Action\nSPEED = 10.0\n\n\nclass Slow:\n    name = 'slowpol'\n\n"
              "    def __init__(self, params, context):\n        pass\n\n    def reset(self, seed):\n        pass\n\n"
              "    def act(self, observation):\n        return Action('slow', 0.0, SPEED, {})\n")
    env = _package_with_module(tmp_path, "[fuzzynav.policies]\nslowpol = hplug_mod:Slow\n", module)
    sweep = tmp_path / "sweep"
    args = [sys.executable, "-m", "runners.sweep", "sweep=quick", "scenario=head_on", "planner=none",
            "navigator=direct", "navigator.policy=slowpol", "episodes=1", f"hydra.sweep.dir={sweep}"]

    def speeds() -> set[float]:
        (log,) = [p for p in sweep.rglob("*.mcap")  # not the copy a resume set aside
                  if not {".fuzzynav", "earlier"} & set(p.relative_to(sweep).parts)]
        return {d["v_cm_s"] for d in load_episode(log).decisions}

    subprocess.run(args, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300, check=True)
    assert speeds() == {10.0}
    (tmp_path / "site" / "hplug_mod.py").write_text(module.replace("SPEED = 10.0", "SPEED = 30.0"))
    resumed = subprocess.run([*args, "resume=true"], cwd=tmp_path, env=env, capture_output=True, text=True,
                             timeout=300, check=True)
    assert speeds() == {30.0}
    # the old code's log is superseded: kept in the control folder, not analysed (counted beside its re-run, each
    # seed of the group was there twice)
    out = resumed.stdout + resumed.stderr
    assert "written by different code" not in out and "1 log(s) of episodes this sweep ran again with other code" \
        in out, out[-2000:]
    (old,) = (sweep / ".fuzzynav" / "superseded").rglob("*.mcap")
    assert {d["v_cm_s"] for d in load_episode(old).decisions} == {10.0}
    summary = (sweep / "summary.csv").read_text().splitlines()
    assert len(summary) == 2, summary  # the header and the one episode


@pytest.mark.parametrize("name, owner", [("navigator/dwa.yaml", "fuzzynav's conf/"),
                                         ("scenario/head_on.yaml", "fuzzynav's conf/"),
                                         ("navigator/wall.yaml", "package aplug_conf")])
def test_a_plug_in_config_file_that_would_never_be_used_is_one_line(tmp_path, name, owner):
    """A plug-in's ``navigator/dwa.yaml`` lost silently to fuzzynav's own (the first folder wins in Hydra); a file
    that another package before it has already, likewise: one line naming the entry point and the file."""
    site = tmp_path / "site"
    info = site / "hplug-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: hplug\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[fuzzynav.conf]\na = aplug_conf\nb = bplug_conf\n")
    for package in ("aplug_conf", "bplug_conf"):
        (site / package / "navigator").mkdir(parents=True)
        (site / package / "__init__.py").write_text("")
        (site / package / "navigator" / f"{package}_own.yaml").write_text("policy: dwa\n")
    (site / "bplug_conf" / name).parent.mkdir(exist_ok=True)
    (site / "bplug_conf" / name).write_text("policy: dwa\n")
    if owner != "fuzzynav's conf/":
        (site / "aplug_conf" / name).write_text("policy: dwa\n")
    proc = subprocess.run([sys.executable, "-m", "runners.run", f"hydra.run.dir={tmp_path / 'run'}"], cwd=tmp_path,
                          env={**os.environ, "PYTHONPATH": str(site)}, capture_output=True, text=True, timeout=300,
                          stdin=subprocess.DEVNULL)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr[-2000:]
    assert "entry point 'b'" in lines[0] and f"{name} is also in {owner}" in lines[0], lines[0]
    assert not (tmp_path / "run").exists()


def test_resume_reruns_the_episodes_of_a_plug_in_generator_whose_code_changed(tmp_path):
    """Another package's scenario generator is code the episode runs, like its policy: a resumed sweep after the
    generator changed runs its episodes again (the scenario they would get is not the one logged)."""
    from mcap.reader import make_reader

    module = ("WALKER_SPEED = 30.0\n\n\ndef make(params, seed, name):\n"
              "    return {'name': name, 'bounds': [0, 0, 1200, 600],\n"
              "            'robot': {'start': [100, 300], 'heading': 0, 'goal': [1100, 300], 'radius': 20},\n"
              "            'static_obstacles': [],\n"
              "            'dynamic_obstacles': [{'id': 'w', 'radius': 20, 'start': [1000, 300],\n"
              "                                   'velocity': [-WALKER_SPEED, 0]}], 'max_steps': 120}\n")
    env = _package_with_module(tmp_path, "[fuzzynav.generators]\nhgen = hplug_mod:make\n", module)
    conf = tmp_path / "conf"
    (conf / "scenario").mkdir(parents=True)
    (conf / "scenario" / "hgen_walk.yaml").write_text("generator: hgen\nname: hgen_walk\n")
    sweep = tmp_path / "sweep"
    args = [sys.executable, "-m", "runners.sweep", "sweep=quick", f"hydra.searchpath=[file://{conf}]",
            "scenario=hgen_walk", "planner=none", "episodes=1", f"hydra.sweep.dir={sweep}"]

    def walker_speed() -> str:
        (log,) = [p for p in sweep.rglob("*.mcap") if not {".fuzzynav", "earlier"} & set(p.relative_to(sweep).parts)]
        with open(log, "rb") as f:
            meta = next(m.metadata for m in make_reader(f).iter_metadata() if m.name == "fuzzynav.run")
        return meta["scenario_yaml"]

    subprocess.run(args, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300, check=True)
    assert "-30.0" in walker_speed()
    (tmp_path / "site" / "hplug_mod.py").write_text(module.replace("WALKER_SPEED = 30.0", "WALKER_SPEED = 45.0"))
    subprocess.run([*args, "resume=true"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
                   check=True)
    assert "-45.0" in walker_speed() and "-30.0" not in walker_speed()


# -- a _target_ policy whose code raises what usually comes from outside (issue 37, hostile corpus) ---------------
def _target_module(tmp_path: Path, source: str) -> dict[str, str]:
    (tmp_path / "odd_policy.py").write_text(source)
    return {**os.environ, "PYTHONPATH": str(tmp_path)}


@pytest.mark.parametrize("statement", ["raise SystemExit(3)", "import sys; sys.exit(0)"])
def test_a_policy_module_that_exits_at_import_is_the_fields_error(tmp_path, statement):
    """It ended the run with its own exit status (3, or 0: a silent 'success') and no word."""
    env = _target_module(tmp_path, f"{statement}\n")
    proc = subprocess.run([sys.executable, "-m", "runners.run", "navigator=custom", "navigator._target_=odd_policy.P",
                           f"hydra.run.dir={tmp_path / 'run'}"], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 2 and proc.stderr.strip().splitlines() == [
        f"error: config: navigator._target_: importing 'odd_policy' failed: SystemExit: {statement[-2]}"]


@pytest.mark.parametrize("method", ["act", "reset"])
def test_a_policy_raising_keyboard_interrupt_is_its_error_not_a_ctrl_c(tmp_path, method):
    """It was reported as "interrupted (Ctrl-C)", exit 130, and stopped the sweep: no signal was received."""
    source = ("from fuzzynav.policies.base import Action\n\n\nclass P:\n    name = 'odd'\n\n"
              "    def __init__(self, params, context):\n        pass\n\n"
              f"    def reset(self, seed):\n        {'raise KeyboardInterrupt' if method == 'reset' else 'pass'}\n\n"
              "    def act(self, observation):\n        raise KeyboardInterrupt\n")
    env = _target_module(tmp_path, source)
    proc = subprocess.run([sys.executable, "-m", "runners.sweep", "scenario=head_on,crossing_right", "episodes=2",
                           "navigator=custom", "navigator._target_=odd_policy.P", "planner=none",
                           f"hydra.sweep.dir={tmp_path / 'sweep'}", "hydra.launcher.n_jobs=1"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert "Ctrl-C" not in proc.stderr + proc.stdout, proc.stderr[-2000:]
    if method == "reset":  # as any failure of reset(seed): the configuration's error, before any episode of its job
        assert proc.returncode == 1 and proc.stderr.strip().splitlines()[0] == (
            "error: job 0 failed: config: policy odd_policy.P: reset(seed) raised KeyboardInterrupt (no signal was "
            "received: treated as the code's error)"), proc.stderr[-2000:]
        assert not list((tmp_path / "sweep").rglob("*.mcap"))
        return
    # as for any episode that raised: the sweep goes on, and its summary counts them as errors
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "4 left out: 4 error" in proc.stdout
    summary = (tmp_path / "sweep" / "summary.csv").read_text()
    assert summary.count(",error,,,,,,error,") == 4, summary  # every episode ran and failed on its own
    assert "policy odd_policy.P: act() raised KeyboardInterrupt (no signal was received" in summary


def test_a_policy_whose_act_never_returns_is_stopped_by_one_sigterm(tmp_path):
    """SIGTERM waited for a step that never ended: the run hung until killed. Now the step in flight gets
    STEP_GRACE_S, then the episode ends as interrupted, its log finished, exit 143."""
    import signal
    import time

    from analysis.logs import iter_messages
    from runners.sweeping.stop import STEP_GRACE_S

    marker = tmp_path / "acting"
    env = _target_module(tmp_path, (
        "import time\nfrom pathlib import Path\n\n\nclass P:\n    name = 'stuck'\n\n"
        "    def __init__(self, params, context):\n        pass\n\n    def reset(self, seed):\n        pass\n\n"
        f"    def act(self, observation):\n        Path({str(marker)!r}).touch()\n        time.sleep(3600)\n"))
    proc = subprocess.Popen([sys.executable, "-m", "runners.run", "navigator=custom", "navigator._target_=odd_policy.P",
                             f"hydra.run.dir={tmp_path / 'run'}"], cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not marker.exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
        assert marker.exists(), proc.communicate(timeout=5)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=STEP_GRACE_S + 60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143, err[-2000:]
    (log,) = (tmp_path / "run").glob("*.mcap")
    (end,) = [m for topic, _, m in iter_messages(log) if topic == "/episode"]
    assert end["outcome"] == "interrupted" and "had not ended" in end["reason"], end


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_a_policy_whose_act_never_returns_does_not_hold_a_stopped_sweep(tmp_path, n_jobs):
    """A sweep job reads the stop file between steps only: with a step that never ends, SIGTERM to the sweep
    waited forever. Now the job's stop-file watch gives the step STEP_GRACE_S, then interrupts it: the sweep
    exits 143 with every log finished, the stuck episode's as interrupted with the reason."""
    import signal
    import time

    from analysis.logs import iter_messages
    from runners.sweeping.stop import STEP_GRACE_S

    marker = tmp_path / "acting"
    env = _target_module(tmp_path, (
        "import time\nfrom pathlib import Path\n\n\nclass P:\n    name = 'stuck'\n\n"
        "    def __init__(self, params, context):\n        pass\n\n    def reset(self, seed):\n        pass\n\n"
        f"    def act(self, observation):\n        Path({str(marker)!r}).touch()\n        time.sleep(3600)\n"))
    sweep = tmp_path / "sweep"
    proc = subprocess.Popen([sys.executable, "-m", "runners.sweep", "scenario=head_on,crossing_right",
                             "navigator=custom", "navigator._target_=odd_policy.P", "planner=none",
                             f"hydra.sweep.dir={sweep}", f"hydra.launcher.n_jobs={n_jobs}"],
                            cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 180
        while not marker.exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
        assert marker.exists(), proc.communicate(timeout=5)
        proc.send_signal(signal.SIGTERM)  # to the launching process only, as `kill PID` does
        out, err = proc.communicate(timeout=STEP_GRACE_S + 90)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 143, (out + err)[-3000:]
    logs = sorted(sweep.rglob("*.mcap"))
    assert logs, out + err
    for log in logs:
        (end,) = [m for topic, _, m in iter_messages(log) if topic == "/episode"]
        assert end["outcome"] == "interrupted", (log, end)
    assert any("had not ended" in m["reason"] for log in logs for topic, _, m in iter_messages(log)
               if topic == "/episode"), out + err
