"""The bench's simulation of the launcher's schedule (runners.benchmarks.main_job.simulated_wall_s) and issue #36's
targets built from the main job's figures."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from runners.benchmarks.main_job import simulated_wall_s
from runners.benchmarks.targets import main_job_targets


def test_jobs_go_to_the_first_free_worker_in_order() -> None:
    # 2 workers: job 0 (3 s) on w0, job 1 (1 s) on w1, job 2 (1 s) on w1 at 1, job 3 (2 s) on w1 at 2 -> ends at 4
    assert simulated_wall_s([3.0, 1.0, 1.0, 2.0], 2, 0.5, 0.25) == pytest.approx((4.75, 4.0))
    assert simulated_wall_s([1.0] * 32, 16, 0.0, 0.0) == pytest.approx((2.0, 2.0))
    assert simulated_wall_s([], 16, 1.0, 2.0) == (3.0, 0.0)


@given(st.lists(st.floats(0.0, 10.0), max_size=60), st.integers(1, 32))
def test_makespan_bounds(spans: list[float], workers: int) -> None:
    _, phase = simulated_wall_s(spans, workers, 0.0, 0.0)
    lower = max([sum(spans) / workers, *spans], default=0.0)
    assert lower - 1e-9 <= phase <= sum(spans) / workers + max(spans, default=0.0) + 1e-9


def test_targets_from_the_main_job_figures() -> None:
    job = {"cores": 2, "sweep_efficiency": 0.2, "episodes_phase_efficiency": 0.81, "simulated_cores": 16,
           "simulated_sweep_efficiency": 0.05, "first_step_s": 0.45, "report_over_metrics": 0.3}
    large = {"cores": 2, "sweep_efficiency": 0.5, "simulated_cores": 16, "simulated_sweep_efficiency": 0.15}
    rows = main_job_targets({"main_job": job, "large_sweep": large})
    assert len(rows) == 8 and len({(t.name, t.note) for t in rows}) == 8
    assert rows[-1].value is None and rows[-1].met is None  # no kernels' table in these results: not measured
    assert [t.name for t in rows if t.met] == ["sweep efficiency, the default sweep's episodes phase",
                                               "time to the first step of runners.run"]
