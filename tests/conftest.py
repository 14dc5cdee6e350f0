"""Shared fixtures: the shipped controller definitions and scenarios, loaded from conf/."""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

from fuzzynav.controller.fuzzy_spec import ControllerSpec
from fuzzynav.scenarios.scenario import Scenario, scenario_from_dict

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "conf"


def one_error_line(err: str) -> str:
    """The only non-blank line of ``err`` (a command's stderr), which must be ``error: ...`` without a traceback."""
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in err, err
    return lines[0]


def require_compiled(module: object, name: str) -> None:
    """At a kernel test module's top: skip it when the compiled kernel ``fuzzynav.<name>`` (``module``, None when
    not built) is missing; fail instead in CI (CI=true), where the install has a C compiler and a silently
    missing build would leave the kernel untested."""
    if module is not None:
        return
    if os.environ.get("CI"):
        pytest.fail(f"fuzzynav.{name} was not built (pip install -e . compiles it; a C compiler is needed)",
                    pytrace=False)
    pytest.skip(f"fuzzynav.{name} not built (no C compiler at install): its Python/numpy form runs alone",
                allow_module_level=True)


@pytest.fixture
def forkable() -> None:
    """This process without other threads, so that the analysis forks its workers (analysis.forked): joblib's
    worker pool, which an earlier test may have started (its threads stay), is shut down; skipped where the
    process still cannot fork."""
    from joblib.externals.loky import reusable_executor

    from analysis import forked

    if reusable_executor._executor is not None:
        reusable_executor._executor.shutdown(wait=True)
    for thread in threading.enumerate():  # a thread about to end (a log's git lookup) is waited for briefly
        if thread is not threading.main_thread():
            thread.join(timeout=2.0)
    if not forked.can_fork():
        others = sorted(t.name for t in threading.enumerate() if t is not threading.main_thread())
        reason = f"this process cannot fork (other threads run: {others}, or no fork on this platform)"
        if os.environ.get("CI") == "true" and sys.platform == "linux":  # in CI these tests must run
            pytest.fail(reason)
        pytest.skip(reason)


def load_yaml(path: Path) -> dict:
    with open(path) as f:
        return yaml.safe_load(f)


def load_controller(name: str) -> ControllerSpec:
    return ControllerSpec.from_dict(load_yaml(CONF / "controller" / f"{name}.yaml"))


def load_scenario(name: str) -> Scenario:
    return scenario_from_dict(load_yaml(CONF / "scenario" / f"{name}.yaml"))


@pytest.fixture(scope="module")
def slurm(tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest) -> Iterator[object]:
    """A one-node Slurm cluster on this machine for the module's tests (:mod:`tests.slurm_cluster`), stopped at
    the end of the module whatever happened; skipped without Slurm, munge or root (a failure in CI)."""
    from tests.slurm_cluster import one_node_cluster

    yield from one_node_cluster(tmp_path_factory, request)


@pytest.fixture(scope="session")
def table1() -> ControllerSpec:
    return load_controller("table1")


@pytest.fixture(scope="session")
def listing() -> ControllerSpec:
    return load_controller("listing")


@pytest.fixture(autouse=True)
def _slurm_cluster_named(request: pytest.FixtureRequest) -> None:
    """A test on the Slurm cluster records the cluster in its report (shown by :func:`pytest_terminal_summary`:
    on pytest-xdist's workers the fixture's own line is not printed)."""
    if "slurm" in request.fixturenames:
        request.node.user_properties.append(("slurm_cluster", request.getfixturevalue("slurm").describe()))


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The files marked ``long`` (minutes each) first, otherwise in their order: pytest-xdist hands out whole files
    in this order, and a long file handed out last kept one worker busy alone at the end (6 of the suite's 30 min)."""
    items.sort(key=lambda item: item.get_closest_marker("long") is None)


def pytest_terminal_summary(terminalreporter) -> None:
    """Show which CPU configurations the datasets were verified under (tests/test_cpu_independence.py) and the Slurm
    cluster the Slurm tests passed on, so a CI log proves they ran."""
    passed = [(name, value) for report in terminalreporter.stats.get("passed", [])
              for name, value in getattr(report, "user_properties", [])]
    lines = [value for name, value in passed if name == "verified_under"]
    if lines:
        terminalreporter.section("portable numerics: datasets verified under other CPU configurations")
        for line in lines:
            terminalreporter.write_line(line)
    clusters = [value for name, value in passed if name == "slurm_cluster"]
    if clusters:
        terminalreporter.section("slurm: tests passed on a one-node cluster started on this machine")
        for cluster in sorted(set(clusters)):
            terminalreporter.write_line(f"{cluster}: {clusters.count(cluster)} test(s)")
