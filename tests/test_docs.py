"""The documentation: the site builds with ``mkdocs build --strict``, the README's example runs as shown, the
README keeps CI's test command, and the performance page is generated from the benchmark's results."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from runners.benchmarks import page as bench_page

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _mkdocs() -> str | None:
    """The mkdocs of this interpreter's environment (the dev extra), else one on PATH."""
    here = Path(sys.executable).parent / "mkdocs"
    return str(here) if here.exists() else shutil.which("mkdocs")


def _fenced(text: str, language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", text, re.S | re.M)


def test_the_site_builds_strictly(tmp_path: Path):
    mkdocs = _mkdocs()
    if mkdocs is None:
        message = "mkdocs is not installed (pip install -c constraints.txt -e '.[dev]')"
        if os.environ.get("CI"):
            pytest.fail(message, pytrace=False)
        pytest.skip(message)
    site = tmp_path / "site"
    had_site = (ROOT / "site").exists()
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}  # Material's banner about its successor, not a build problem
    proc = subprocess.run([mkdocs, "build", "--strict", "--site-dir", str(site)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-6000:]
    assert (site / "index.html").exists()
    assert (site / "tutorials" / "policy" / "index.html").exists()
    assert "Episode" in (site / "reference" / "episode" / "index.html").read_text()  # mkdocstrings rendered it
    assert (ROOT / "site").exists() == had_site  # built into the temporary directory only


def test_readme_is_short_and_keeps_ci_test_command():
    text = README.read_text()
    assert len(text.splitlines()) <= 300
    lines = (ROOT / ".ci" / "run").read_text().strip().splitlines()
    (ci,) = [line for line in lines if line.startswith('"$PY" -m venv')]
    command = ci.replace('"$PY"', "python3.11")
    assert command in _fenced(text, "bash")[1], "the README's test command differs from .ci/run's"
    # and CI runs its pytest once more with the compiled kernels off (issue #36), after it, as the README says
    assert lines[-1] == "FUZZYNAV_KERNEL=python .venv/bin/python -m pytest" and lines.index(ci) < len(lines) - 1
    assert "FUZZYNAV_KERNEL=python" in text
    image = re.search(r"!\[[^]]*\]\(([^)]+)\)", text).group(1)
    assert (ROOT / image).is_file()
    for link in re.findall(r"\]\((docs/[^)#]+)", text):
        assert (ROOT / link).is_file(), link


def test_readme_library_example_prints_what_it_says(tmp_path):  # from a folder outside the checkout
    text = README.read_text()
    code = _fenced(text, "python")[0]
    expected = text[text.index(code) + len(code):]
    expected = _fenced(expected, "text")[0]
    proc = subprocess.run([sys.executable, "-"], input=code, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout == expected


def _results() -> dict:
    """A small bench.json of the form ``python -m runners.bench`` writes (made-up numbers)."""
    stages = {"sensors": 150.0, "rest": 120.0, "logging": 110.0, "tracking": 50.0, "tpt": 5.0, "controller": 2.0}
    fuzzy = {"controller": "table1", "fast_us_per_decision": 1.2,
             "batch_us_per_decision": 0.95, "max_disagreement_dtheta_deg": 1.7e-13, "max_disagreement_v_cm_s": 3.5e-14,
             "peers": [{"engine": "ferrifuzz", "installed": False}], "skfuzzy_version": "0.5.0",
             "skfuzzy_us_per_decision": 27000.0, "ratio": 22000.0}
    return {
        "machine": {"python": "3.11.9", "processor": "x86_64", "system": "Linux",
                    "compiled_kernels": {"_raycast": True, "_orca": False}},
        "quick": True,
        "fuzzy": [fuzzy],
        "simulation": {"scenario": "mixed", "steps": 960, "repetitions": 7, "steps_per_s_without_logging": 3500.0,
                       "steps_per_s_with_logging": 2200.0, "logging_share_of_step": 0.36,
                       "logging_share_per_pair": [0.36], "us_per_step_by_stage": stages},
        "sweep": {"episodes": 100, "cores": 2, "rounds": 1, "own_compute_s_before": 1.6, "own_compute_s_after": 1.6,
                  "ideal_s": 0.8, "shapes": [{"jobs": 4, "episodes_per_job": 25, "wall_over_all_cores": 1.6,
                                               "rounds_over_all_cores": [1.6], "wall_s_to_summary": 3.0,
                                               "all_cores_s": 1.9, "wall_over_ideal": 3.7, "wall_s_with_report": 3.5,
                                               "wall_with_report_over_ideal": 4.3,
                                               "phases_s": {"start-up": 1.0, "episodes": 1.5}}]},
        "analysis": {"scenario": "overtaking", "episodes": 20, "seconds": 0.1, "episodes_per_s": 207.0,
                     "episodes_per_s_best": 208.0, "repetitions": 3, "messages_per_s": 100000.0, "mean_steps": 100.0},
        "memory": {"episodes": 60, "rss_mb_at_10pct": 240.0, "rss_mb_at_end": 240.5, "growth": 0.002},
        "targets": [{"name": "analysis, one process", "value": 207.0, "threshold": 200.0, "higher_is_better": True,
                     "unit": "episodes/s", "met": True, "note": ""},
                    {"name": "single decision ours / ferrifuzz (table1)", "value": None, "threshold": 1.0,
                     "higher_is_better": False, "unit": "", "met": None, "note": "ferrifuzz not installed"}],
        **_main_job_results(),
    }


def _main_job_results() -> dict:
    """Issue #36's sections of a full run's bench.json (made-up numbers) and the targets the bench reads off them."""
    from runners.benchmarks.targets import main_job_targets

    results = {
        "machine": {"kernels_built": {"_raycast": True, "_orca": True}},
        "main_job": {"cores": 2, "episodes": 105, "rounds": 3, "sweep_wall_s": 30.0, "sweep_first_log_s": 3.0,
                     "sweep_last_log_s": 27.0, "plain_s": 2.8, "first_step_s": 0.41, "report_s": 3.5,
                     "metrics_s": 0.5, "metrics_command_s": 2.0, "sim_wall_s": 6.0, "sim_phase_s": 3.1,
                     "plain_episodes_per_s": 37.5, "sweep_episodes_per_s": 3.5, "sweep_efficiency": 0.0467,
                     "sweep_efficiency_to_last_log": 0.0519, "episodes_phase_efficiency": 0.0583,
                     "simulated_cores": 16, "simulated_sweep_efficiency": 0.0292,
                     "simulated_episodes_phase_efficiency": 0.0565, "report_episodes_per_s": 30.0,
                     "metrics_episodes_per_s": 210.0, "metrics_command_episodes_per_s": 52.5,
                     "report_over_metrics": 0.1429, "report_over_metrics_command": 0.5714},
        "large_sweep": {"cores": 2, "episodes": 1008, "rounds": 2, "overrides": ["episodes=8", "seed=range(0,48,8)"],
                        "wall_s": 120.0, "first_log_s": 4.0, "last_log_s": 110.0, "plain_s": 27.0,
                        "sim_wall_s": 14.0, "sim_phase_s": 9.5, "plain_episodes_per_s": 37.33,
                        "sweep_efficiency": 0.1125, "episodes_phase_efficiency": 0.1273, "simulated_cores": 16,
                        "simulated_sweep_efficiency": 0.1206, "simulated_episodes_phase_efficiency": 0.1777},
        "kernels": {"rounds": 2,
                    "medians_s": {"default sweep": {"all on": 30.0, "_raycast": 33.0, "_orca": 30.3, "all off": 34.0},
                                  "orca crowd sweep (docs/crowds.md)": {"all on": 2.0, "_raycast": 2.5, "_orca": 7.4,
                                                                        "all off": 8.0}},
                    "gain": {"default sweep": {"_raycast": 1.1, "_orca": 1.01, "all off": 1.13},
                             "orca crowd sweep (docs/crowds.md)": {"_raycast": 1.25, "_orca": 3.7, "all off": 4.0}}},
        "recorded": {"people": 300, "steps": 600, "repetitions": 3, "present_per_step": 13.8,
                     "in_laser_range_per_step": 0.42, "replay_us_per_step": 51.0, "sensing_extra_us_per_step": 61.0,
                     "mixed_us_per_step": 1800.0, "share_of_mixed_step": 0.062},
        "tuning": {"trials": 20, "episodes_per_trial": 10, "episodes": 200, "scenario": "head_on", "study_s": 12.0,
                   "plain_episodes_s": 8.0, "trials_per_minute": 100.0, "overhead": 0.5, "overhead_s_per_trial": 0.2,
                   "episodes_in_study_s": 8.5, "metrics_s": 1.5, "sampler_storage_compose_s": 2.0,
                   "study_setup_s": 0.6},
    }
    results["main_job_targets"] = [t.as_dict() for t in main_job_targets(results)]
    del results["machine"]
    return results


def test_the_performance_page_is_generated_from_bench_json(tmp_path: Path):
    path = tmp_path / "bench.json"
    path.write_text(json.dumps(_results()))
    page = tmp_path / "performance.md"
    assert bench_page.main([str(path), str(page)]) == 0
    text = page.read_text()
    assert text.startswith("# Performance\n")
    assert "| analysis, one process | 207 episodes/s | >= 200 episodes/s | met |" in text
    assert "| single decision ours / ferrifuzz (table1) | not measured | <= 1 | not measured |" in text
    assert "1 of 2 targets met in this run." in text
    assert "| with logging | 2200 |" in text
    assert "| table1     fuzzynav" in text or "table1     fuzzynav" in text  # the benchmark's own fuzzy table
    assert "| 4 × 25 | 1.60 |" in text
    assert "207.0 episodes/s" in text and "+0.2%" in text
    assert "| compiled kernels in use | 1 of 2 (raycast) |" in text
    for missing in ("Report", "Crowds", "Side by side with the targets' starting point"):
        assert f"## {missing}\n\nNot measured in this run.\n" in text
    assert "## What each number measures" in text
    # issue #36's sections, as the bench's own printers print them, and its targets with their verdicts
    assert "sweep efficiency: 0.05  (the whole command, 30.0 s" in text
    assert "time to first step of runners.run: 0.41 s" in text and "report / metrics = 0.14" in text
    assert "sweep efficiency (1,000 episodes): 0.11 on 2 cores" in text
    assert "_orca                                     1.01                      3.70    3.70" in text
    assert "Recorded people: 300 people over 600 steps" in text and "100.0 trials/min" in text
    assert "2 of 9 targets met in this run." in text
    assert "| time to the first step of runners.run | 0.41 s | < 0.5 s | met |  |" in text
    assert "| kernel _raycast, best end-to-end gain | 1.25 x | >= 1.3 x | **not met** | orca crowd sweep" in text
    assert "| sweep efficiency, a 1,000-episode sweep as a whole command | 0.113 | >= 0.8 | **not met** | 2 cores |" \
        in text
    measures = text[text.index("## What each number measures"):]
    for entry in ("Recorded people", "The main job", "A 1,000-episode sweep", "Kernels end to end",
                  "Tuning studies", "Targets"):
        assert f"- **{entry}**" in measures, entry
    assert "Not shown" not in text and "about 6 minutes" not in text


def test_the_performance_page_of_a_quick_run_says_what_it_did_not_measure(tmp_path: Path):
    from runners.benchmarks.targets import main_job_targets

    results = _results()
    del results["large_sweep"], results["kernels"]
    results["machine"]["kernels_built"] = {"_raycast": True, "_orca": True}
    results["main_job_targets"] = [t.as_dict() for t in main_job_targets(results)]
    text = bench_page.render(results)
    for title in ("A 1,000-episode sweep", "Kernels end to end"):
        assert f"## {title}\n\nNot measured in this run (`--quick` leaves it out: the full run measures it).\n" in text
    assert ("| sweep efficiency, a 1,000-episode sweep as a whole command | not measured | >= 0.8 | not measured | "
            "no large_sweep in a --quick run: the full run measures it |") in text
    assert "| kernel _orca, best end-to-end gain | not measured | >= 1.3 x | not measured | no kernels in a" in text
    assert "1 of 8 targets met in this run." in text  # the not measured ones are not met
    results["quick"] = False  # a full run that lacks them (it failed): not measured, no reason invented
    assert "## Kernels end to end\n\nNot measured in this run.\n" in bench_page.render(results)


@pytest.mark.parametrize(("edit", "section", "why"), [
    (lambda r: r["main_job_targets"][3].update(met=False), "Targets of issue #36 (the main job)",
     "met False is not the verdict of its value and threshold"),
    (lambda r: r["main_job_targets"][0].update(value=0.9), "Targets of issue #36 (the main job)",
     "met False is not the verdict"),
    (lambda r: r["main_job_targets"][3].update(sign=">"), "Targets of issue #36 (the main job)",
     "does not match higher_is_better"),
    (lambda r: r["main_job_targets"][0].update(value="0.9"), "Targets of issue #36 (the main job)",
     "is not a finite number"),
    (lambda r: r["main_job"].update(sweep_efficiency=float("nan")), "The main job",
     "`main_job.sweep_efficiency` in this run's results is not a finite number"),
    (lambda r: r["kernels"]["gain"]["default sweep"].update(_orca=float("inf")), "Kernels end to end",
     "`kernels.gain.default sweep._orca`"),
    (lambda r: r["large_sweep"].pop("wall_s"), "A 1,000-episode sweep", "KeyError: 'wall_s'"),
])
def test_the_performance_page_shows_no_figure_it_cannot_trust(edit, section, why):
    """An edited verdict, a NaN or a missing field: that section says why it is not shown; the others are shown."""
    results = _results()
    edit(results)
    text = bench_page.render(results)
    body = text.split(f"## {section}\n\n")[1].split("\n## ")[0]
    assert body.startswith("Not shown: ") and why in body, body
    assert text.count("Not shown") == 1 and "nan" not in text.lower() and "| 0.9 |" not in text


def test_what_each_number_measures_is_one_list_item_per_section():
    """The fixed text's entries stay separate items of one list as Markdown reads it (a lazy continuation line or a
    nested list would swallow the next entry)."""
    import markdown

    html = markdown.markdown(bench_page.MEASURES)
    entries = re.findall(r"^- \*\*([^*]+)\*\*", bench_page.MEASURES, re.M)
    assert re.findall(r"<li><strong>([^<]+)</strong>", html) == entries and html.count("<ul>") == 1
    assert len(entries) == len(bench_page.SECTIONS) - 1  # the two target tables share the entry "Targets"


def test_the_performance_page_refuses_what_is_not_bench_output(tmp_path: Path, capsys):
    bad = tmp_path / "bench.json"
    bad.write_text("[1, 2]")
    assert bench_page.main([str(bad), str(tmp_path / "p.md")]) == 2
    assert bench_page.main([str(tmp_path / "missing.json"), str(tmp_path / "p.md")]) == 2
    assert not (tmp_path / "p.md").exists()
    err = capsys.readouterr().err
    assert err.count("error: ") == 2


def test_the_committed_performance_page_is_a_generated_one():
    text = (ROOT / "docs" / "performance.md").read_text()
    assert "Generated by `python -m runners.benchmarks.page" in text
    assert "## What each number measures" in text


def test_the_limits_page_shows_the_limits_the_code_applies():
    from fuzzynav.params import limits

    size_limits = limits.markdown_table().split("\n\n")[0]
    page = (ROOT / "docs" / "troubleshooting.md").read_text()
    missing = [line for line in size_limits.splitlines() if line not in page]
    assert not missing, f"docs/troubleshooting.md differs from python -m fuzzynav.params.limits: {missing}"
