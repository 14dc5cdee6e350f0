"""runners.benchmarks.report: the report stage (measured) and the whole report (read stage estimated) against the
budget."""

from __future__ import annotations

from runners.benchmarks.report import BUDGET_S, REPORT_BUDGET_S, budget_lines, summary_line


def _result(report_s: float, read_s: float) -> dict:
    return {"cores": 2,
            "real": {"episodes": 210, "seeds_per_configuration": 10, "sweep_s": 40.0, "read_stage_s": 0.63,
                     "report_stage_s": 4.0, "measured": True},
            "synthetic": {"episodes": 10_000, "failed": 1420, "report_stage_s": report_s, "measured": True,
                          "read_stage_s_estimate": read_s, "total_s_estimate": read_s + report_s,
                          "budget_s": BUDGET_S, "report_stage_budget_s": REPORT_BUDGET_S, "html_kb": 25.0,
                          "html_table_rows": 70, "images": 21, "images_kb": 900.0}}


def test_budget_lines_say_what_is_measured_and_what_is_estimated():
    stage, whole = budget_lines(_result(7.4, 30.0))
    assert stage == "report stage, 10000 episodes: 7.4 s (measured) — within its 15 s share"
    assert whole.startswith("whole report, 10000 episodes: ~37 s = read stage ~30 s (estimated: the 210 real logs' "
                            "one-process time per log")
    assert "report stage 7.4 s (measured) — within the 60 s budget" in whole
    stage, whole = budget_lines(_result(16.0, 50.0))
    assert "OVER its 15 s share" in stage and "OVER the 60 s budget" in whole
    assert "(measured)" in summary_line(_result(7.4, 30.0)) and "(estimated" in summary_line(_result(7.4, 30.0))


def test_the_whole_report_of_existing_logs_is_measured(tmp_path):
    import subprocess
    import sys

    from tests.conftest import ROOT
    out = tmp_path / "r.json"
    res = subprocess.run([sys.executable, "-m", "runners.benchmarks.report", "--logs", str(ROOT / "datasets" /
    "paper_fig5"
                                                                                       / "logs"), "--out", str(out)],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("whole report of 21 logged episodes (0 left out): ") and "(measured)" in res.stdout
    missing = subprocess.run([sys.executable, "-m", "runners.benchmarks.report", "--logs", str(tmp_path / "none")],
                             cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert missing.returncode == 2 and "--logs: " in missing.stderr and "no such file" in missing.stderr


def test_bad_arguments_are_one_line_errors(tmp_path):
    import subprocess
    import sys

    from tests.conftest import ROOT
    not_a_log = tmp_path / "x.mcap"
    not_a_log.write_text("hello")
    for args, code, text in ((["--episodes", "0"], 2, "--episodes: must be in [1, 1,000,000], got 0"),
                             (["--seeds", "-3"], 2, "--seeds: must be in [1, 10,000], got -3"),
                             (["--logs", str(not_a_log)], 1, "--logs: no usable episode among them (1 left out)")):
        res = subprocess.run([sys.executable, "-m", "runners.benchmarks.report", *args], cwd=ROOT, capture_output=True,
                             text=True, timeout=120)
        assert res.returncode == code and text in res.stderr and "Traceback" not in res.stderr, (args, res.stderr)
        assert text in res.stderr.strip().splitlines()[-1]  # one line (after argparse's usage)
