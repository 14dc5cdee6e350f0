"""The simulation step side by side with an earlier commit (part of ``python -m runners.bench``): issue #19's
target 3 asks for a step on ``mixed`` (laser perception, with logging) at least twice as fast as the code the
issue was filed against, which a number printed on another day cannot show.

The earlier commit's ``fuzzynav``, ``runners``, ``analysis`` and ``conf`` are taken from this checkout's git history
(``git archive``, into a temporary directory) and imported from there, with this environment's libraries. A commit
that has compiled kernels gets them built from its own sources and build file (``pip wheel`` of its
``pyproject.toml``/``setup.py``, the kernels copied into the tree): both sides run what their commit ships, and
the result lists each side's kernels; where the build fails (no compiler) the earlier side runs its Python forms
and the result says so. Each
tree runs in its own child process, the trees alternating round by round (the first in one round is the second in
the next), so that a slow spell of the machine hits both alike. A child runs its own tree's ``mixed`` scenario
(``_scenario_and_config`` of ``runners.benchmarks.simulation``, earlier ``runners.bench``, and
``runners.run.run_episode``: the same API at both commits) and reports
CPU seconds per step (``time.process_time``: time the machine gives to other work is not counted), the best of
three passes over the same seeds, without and with logging, then the wall time per step by stage in one more
logged pass (the stages ``runners.bench`` times, by the same function names at both commits). The ratio of a round
is earlier / this; the result is the median over rounds.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from pathlib import Path
from typing import Any

from analysis.cli_args import OneLineParser

ROOT = Path(__file__).resolve().parents[2]
#: the commit issue #19 was filed against (its numbers: ~670 µs per logged step on ``mixed``); pure Python/numpy
ISSUE_19_COMMIT = "c90ff8656d1b33455b27065835ab322b90ef7e3c"
_TREE_PARTS = ("fuzzynav", "runners", "analysis", "conf")
_BUILD_FILES = ("pyproject.toml", "setup.py", "setup.cfg", "MANIFEST.in", "README.md")  # what a wheel build reads
_COMMIT_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_./~^-]{0,199}")

# Run in a child with the tree as its working directory: the tree's packages come first on sys.path, so they,
# not this checkout's (installed in editable mode), are imported; the child checks that every module of the project
# it ran came from the tree.
_CHILD = r"""
import json, sys, tempfile, time, warnings
from pathlib import Path
tree, episodes, passes = Path(sys.argv[1]).resolve(), int(sys.argv[2]), int(sys.argv[3])
sys.path.insert(0, str(tree))
# this checkout's editable install answers for module names it knows before the tree's paths are searched (a
# compiled kernel the tree was built without came from here): the tree alone supplies the project's modules
sys.meta_path[:] = [f for f in sys.meta_path if "__editable__" not in getattr(f, "__module__", "")
                    and "__editable__" not in getattr(type(f), "__module__", "")]
if (tree / "conf" / "__init__.py").exists() and not (tree / "fuzzynav" / "conf").exists():
    # an install maps conf/ to fuzzynav.conf (pyproject's package-dir); so does the tree here
    import importlib.util
    spec = importlib.util.spec_from_file_location("fuzzynav.conf", tree / "conf" / "__init__.py",
                                                  submodule_search_locations=[str(tree / "conf")])
    sys.modules["fuzzynav.conf"] = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(sys.modules["fuzzynav.conf"])
warnings.filterwarnings("ignore")
def only_the_trees():
    # every module of the project imported must be the tree's (the editable install's finder would supply one that
    # the tree lacks from this checkout)
    stray = sorted(name for name, module in list(sys.modules.items())
                   if name.split(".")[0] in ("fuzzynav", "runners", "analysis") and getattr(module, "__file__", None)
                   and not Path(module.__file__).resolve().is_relative_to(tree))
    if stray:
        raise SystemExit(f"modules not from the tree {tree}: {', '.join(stray)}")
import importlib
# the same API at every commit, where the tree has it (runners/benchmarks/ since runners/ has subpackages)
simulation = "runners.benchmarks.simulation" if (tree / "runners" / "benchmarks").is_dir() else "runners.bench"
_scenario_and_config = importlib.import_module(simulation)._scenario_and_config  # the same API at every commit
from runners.run import run_episode
only_the_trees()
scenario, evaluator, cfg = _scenario_and_config("mixed")
with tempfile.TemporaryDirectory() as tmp:
    def run(log):
        t, steps = time.process_time(), 0
        for seed in range(episodes):
            path = Path(tmp) / f"{seed}.mcap" if log else None
            steps += run_episode(scenario, evaluator, cfg, seed, path, "")["steps"]
        return time.process_time() - t, steps
    run(False), run(True)  # warm-up: imports, caches, the first files
    plain, logged = [], []
    for _ in range(passes):
        seconds, steps = run(False)
        plain.append(seconds)
        logged.append(run(True)[0])
    # then one logged pass with the bench's wall-clock timers (the tree's own class, the same at both commits)
    # on the functions it times, by the same names at both commits; what is in none of them is "rest"
    import importlib
    # the same functions in whichever module the tree has them (the layout changed: flat fuzzynav/ and runners/,
    # then subpackages); chosen by the tree's files, since importing a module the tree lacks would take this
    # checkout's
    def module(*candidates):
        for name in candidates:
            if (tree / (name.replace(".", "/") + ".py")).exists():
                return importlib.import_module(name)
        raise SystemExit(f"the tree {tree} has none of {', '.join(candidates)}")
    episode_mod = module("fuzzynav.episode")
    laser_mod = module("fuzzynav.sensing.laser", "fuzzynav.laser")
    nav_mod = module("fuzzynav.planning.layer", "fuzzynav.planning.navigator", "fuzzynav.navigator")
    layer_class = getattr(nav_mod, "PlanningLayer", None) or nav_mod.Navigator
    FuzzyPolicy = module("fuzzynav.policies.fuzzy", "fuzzynav.fuzzy_policy").FuzzyPolicy
    Sonar = module("fuzzynav.sensing.sonar", "fuzzynav.sonar").Sonar
    timers_module = module("runners.benchmarks.stage_timers", "runners.stage_timers", "runners.bench")
    Timers = getattr(timers_module, "Timers", None) or timers_module._Timers
    EpisodeLogWriter = module("runners.logs.mcap_log", "runners.mcap_log").EpisodeLogWriter
    timers = Timers()
    for owner, attr, stage in ((Sonar, "read", "sensors"), (laser_mod, "scan", "sensors"),
                               (episode_mod, "perceive", "tracking"), (nav_mod, "build_tpt", "tpt"),
                               (nav_mod, "find_new_path", "planner"), (layer_class, "_still_valid", "planner"),
                               (FuzzyPolicy, "fuzzy", "controller"), (EpisodeLogWriter, "step", "logging")):
        timers.wrap(owner, attr, stage)
    t = time.perf_counter()
    run(True)
    wall = time.perf_counter() - t
    timers.restore()
    total = dict(timers.total)
    total["rest"] = max(wall - sum(total.values()), 0.0)
only_the_trees()
kernels = []
compiled_py = [p for p in ("numerics/compiled.py", "compiled.py") if (tree / "fuzzynav" / p).exists()]
if compiled_py:  # a commit from before the compiled kernels has none
    import importlib
    compiled = importlib.import_module("fuzzynav." + compiled_py[0][:-3].replace("/", "."))
    full = [name if "." in name else f"fuzzynav.{name}" for name in compiled.KERNELS]  # short names before subpackages
    kernels = [module for name, module in zip(compiled.KERNELS, full, strict=True)
               if compiled.load(name) is not None and not compiled.switched_off()
               and Path(sys.modules[module].__file__).resolve().is_relative_to(tree)]
print(json.dumps({"steps": steps, "kernels": kernels, "plain_us_per_step": min(plain) / steps * 1e6,
                  "logged_us_per_step": min(logged) / steps * 1e6,
                  "stage_us_per_step": {k: v / steps * 1e6 for k, v in total.items()}}))
"""


class BaselineUnavailable(Exception):
    """The earlier commit cannot be measured here (no git, not a checkout, the commit not in its history)."""


def baseline_tree(commit: str, dest: Path) -> Path:
    """Extract ``commit``'s ``fuzzynav``, ``runners``, ``analysis`` and ``conf`` from this checkout's history into
    ``dest``; :class:`BaselineUnavailable` says why it cannot."""
    if not _COMMIT_NAME.fullmatch(commit):  # never an option of git's ("--output=...")
        raise BaselineUnavailable(f"{commit!r} is not a commit name (hex digits, or a branch or tag name)")
    if shutil.which("git") is None:
        raise BaselineUnavailable("git is not installed")
    if not (ROOT / ".git").exists():
        raise BaselineUnavailable(f"{ROOT} is not a git checkout (an installed copy has no history)")
    try:
        res = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", commit, *_TREE_PARTS],
                             capture_output=True, timeout=120)
    except (OSError, subprocess.SubprocessError) as err:
        raise BaselineUnavailable(f"git archive failed: {err}") from None
    if res.returncode != 0:
        first = (res.stderr.decode(errors="replace").strip().splitlines() or ["no output"])[0]
        raise BaselineUnavailable(f"commit {commit[:12]} is not in this checkout's history (a shallow clone?): "
                                  f"{first}")
    _extract(res.stdout, dest)
    return dest


def _extract(archive: bytes, dest: Path) -> None:
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        try:
            tar.extractall(dest, filter="data")
        except TypeError:  # Python 3.11.0-3.11.3 have no extraction filters (the archive is this checkout's own)
            tar.extractall(dest)


def build_kernels(commit: str, tree: Path) -> str:
    """Build ``commit``'s compiled kernels from its own sources into ``tree`` (made by :func:`baseline_tree`): its
    build files are added to a copy, ``pip wheel`` builds it (isolated, as an install does), and the wheel's
    extension modules are put beside their sources in ``tree``. Returns "" when built or when the commit has no
    kernels, else why not (the earlier side then runs its Python forms)."""
    listed = subprocess.run(["git", "-C", str(ROOT), "ls-tree", "--name-only", commit, *_BUILD_FILES],
                            capture_output=True, text=True, timeout=60)
    files = listed.stdout.split() if listed.returncode == 0 else []
    if not any(name.endswith(".c") for name in subprocess.run(
            ["git", "-C", str(ROOT), "ls-tree", "-r", "--name-only", commit, "fuzzynav"],
            capture_output=True, text=True, timeout=60).stdout.split()):
        return ""  # a commit from before the kernels
    if "pyproject.toml" not in files and "setup.py" not in files:
        return f"commit {commit[:12]} has C sources but no build file"
    with tempfile.TemporaryDirectory(prefix="fuzzynav-baseline-build-") as tmp:
        source = Path(tmp) / "source"
        shutil.copytree(tree, source)
        res = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", commit, *files],
                             capture_output=True, timeout=120)
        if res.returncode != 0:
            return "git archive of the build files failed"
        _extract(res.stdout, source)
        wheels = Path(tmp) / "wheels"
        try:
            built = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheels),
                                    str(source)], capture_output=True, text=True, timeout=900)
        except (OSError, subprocess.SubprocessError) as err:
            return f"pip wheel failed: {err}"
        found = sorted(wheels.glob("*.whl")) if built.returncode == 0 else []
        if not found:
            tail = (built.stderr.strip().splitlines() or ["no output"])[-1]
            return f"pip wheel failed: {tail[:200]}"
        with zipfile.ZipFile(found[0]) as wheel:
            for name in wheel.namelist():
                if name.endswith((".so", ".pyd")) and name.split("/")[0] in _TREE_PARTS:
                    target = tree / name
                    target.parent.mkdir(parents=True, exist_ok=True)
                    target.write_bytes(wheel.read(name))
    return ""


def _measure(tree: Path, episodes: int, passes: int) -> dict[str, float]:
    """One child process's result for ``tree`` (see ``_CHILD``)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    res = subprocess.run([sys.executable, "-c", _CHILD, str(tree), str(episodes), str(passes)], cwd=tree, env=env,
                         capture_output=True, text=True, timeout=1800)
    if res.returncode != 0:
        tail = (res.stderr.strip().splitlines() or ["no output"])[-1]
        raise RuntimeError(f"the step measurement in {tree} failed: {tail}")
    try:
        return json.loads((res.stdout.strip().splitlines() or [""])[-1])
    except json.JSONDecodeError:
        raise RuntimeError(f"the step measurement in {tree} printed no result") from None


def bench_baseline(commit: str = ISSUE_19_COMMIT, rounds: int = 5, episodes: int = 24,
                   passes: int = 3) -> dict[str, Any]:
    """CPU µs per step on ``mixed`` of this checkout and of ``commit``, alternated over ``rounds``, and the
    ratios earlier / this (plain and logged; per round and their medians). ``{"measured": False, "why": ...}``
    when the commit cannot be had here or a measurement fails (the rest of the bench's results are kept)."""
    with tempfile.TemporaryDirectory(prefix="fuzzynav-baseline-") as tmp:
        try:
            earlier = baseline_tree(commit, Path(tmp))
        except BaselineUnavailable as err:
            return {"measured": False, "commit": commit, "why": str(err)}
        unbuilt = build_kernels(commit, earlier)
        per_round = []
        try:
            for k in range(rounds):
                order = [("earlier", earlier), ("this", ROOT)]
                if k % 2:
                    order.reverse()
                per_round.append({name: _measure(tree, episodes, passes) for name, tree in order})
        except RuntimeError as err:  # e.g. the earlier code does not run with this environment's libraries
            return {"measured": False, "commit": commit, "why": str(err)}
    plain = [r["earlier"]["plain_us_per_step"] / r["this"]["plain_us_per_step"] for r in per_round]
    logged = [r["earlier"]["logged_us_per_step"] / r["this"]["logged_us_per_step"] for r in per_round]
    return {"measured": True, "commit": commit, "kernels_not_built": unbuilt, "scenario": "mixed", "rounds": rounds,
            "episodes": episodes,
            "passes": passes, "per_round": per_round, "plain_ratio_per_round": plain,
            "logged_ratio_per_round": logged, "plain_ratio": statistics.median(plain),
            "logged_ratio": statistics.median(logged),
            "this_logged_us_per_step": statistics.median(r["this"]["logged_us_per_step"] for r in per_round),
            "earlier_logged_us_per_step": statistics.median(r["earlier"]["logged_us_per_step"] for r in per_round),
            "stage_us_per_step": {name: _median_stages([r[name]["stage_us_per_step"] for r in per_round])
                                  for name in ("earlier", "this")}}


def _median_stages(rounds: list[dict[str, float]]) -> dict[str, float]:
    """Each stage's median over the rounds (0 in a round that did not time it), largest first."""
    names = {k for r in rounds for k in r}
    medians = {k: statistics.median(r.get(k, 0.0) for r in rounds) for k in names}
    return dict(sorted(medians.items(), key=lambda kv: -kv[1]))


def _shown(text: str) -> str:
    """``text`` on one line: control characters (a newline, U+0085) escaped."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def print_baseline(result: dict[str, Any]) -> None:
    if not result["measured"]:
        print(f"target 3 (issue #19, step vs commit {_shown(result['commit'][:7])}): not measured: "
              f"{_shown(result['why'])}")
        return
    steps = {r[name]["steps"] for r in result["per_round"] for name in ("earlier", "this")}
    kernels = {name: len(result["per_round"][0][name]["kernels"]) for name in ("earlier", "this")}
    print(f"side by side with commit {result['commit'][:7]} (mixed, laser perception, {result['episodes']} episodes "
          f"of {'/'.join(str(s) for s in sorted(steps))} steps in all, CPU time, best of {result['passes']}, "
          f"{result['rounds']} alternated rounds): logged step {result['earlier_logged_us_per_step']:.0f} -> "
          f"{result['this_logged_us_per_step']:.0f} µs; compiled kernels in use: {kernels['earlier']} -> "
          f"{kernels['this']}")
    if result.get("kernels_not_built"):
        print(f"  the earlier commit's kernels could not be built ({result['kernels_not_built']}): it ran its "
              "Python forms")
    print(f"  target 3 (issue #19, >= 2 meets it): {result['logged_ratio']:.2f} x with logging (rounds: "
          + ", ".join(f"{r:.2f}" for r in result["logged_ratio_per_round"])
          + f"), {result['plain_ratio']:.2f} x without (rounds: "
          + ", ".join(f"{r:.2f}" for r in result["plain_ratio_per_round"]) + ")")
    earlier, this = result["stage_us_per_step"]["earlier"], result["stage_us_per_step"]["this"]
    print("  wall µs per logged step by stage, earlier -> this (median of rounds): " + ", ".join(
        f"{k} {earlier.get(k, 0.0):.0f} -> {this.get(k, 0.0):.0f}" for k in earlier | this))


def _count(text: str) -> int:
    """argparse type: a whole number from 1 to 1000."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text[:40]!r} is not a whole number") from None
    if not 1 <= value <= 1000:
        raise argparse.ArgumentTypeError(f"must be 1 to 1000, got {value}")
    return value


def main(argv: list[str] | None = None) -> int:
    """``python -m runners.benchmarks.baseline [--commit C] [--rounds N] [--episodes N] [--passes N]``: the side-by-side
    step measurement alone (exit 1 when it could not be measured)."""
    parser = OneLineParser(prog="python -m runners.benchmarks.baseline", description=__doc__.split("\n\n")[0],
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--commit", default=ISSUE_19_COMMIT, help="the earlier commit (default: issue #19's)")
    parser.add_argument("--rounds", type=_count, default=5)
    parser.add_argument("--episodes", type=_count, default=24)
    parser.add_argument("--passes", type=_count, default=3)
    args = parser.parse_args(argv)
    result = bench_baseline(args.commit, args.rounds, args.episodes, args.passes)
    print_baseline(result)
    return 0 if result["measured"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
