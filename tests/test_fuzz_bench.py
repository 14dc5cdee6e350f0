"""Hypothesis fuzzing of the benchmark commands' inputs: a mutated ``bench.json`` given to the performance page
(runners.benchmarks.page) and mutated command lines of runners.bench, runners.benchmarks.report and
runners.benchmarks.baseline. Each gives a valid result or a one-line error naming the file or option, with a
non-zero exit, before any measurement starts — never a traceback, and nothing written outside the output."""

from __future__ import annotations

import copy
import json
import math
import re
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from runners import bench
from runners.benchmarks import baseline, report
from runners.benchmarks import page as bench_page
from tests.test_docs import _results

_junk = st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20), st.floats(allow_nan=True),
                  st.text(max_size=6), st.lists(st.integers(), max_size=2), st.dictionaries(st.text(max_size=3),
                                                                                           st.integers(), max_size=2))


def _paths(value, prefix=()):
    """Every (path, container) leaf and branch of a JSON value."""
    yield prefix
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _paths(v, (*prefix, i))


def _mutated(draw_index: int, how: str, junk, within: tuple[str, ...] = ()) -> dict:
    """_results() with one leaf or branch deleted or replaced by ``junk`` (only under the keys ``within``, if given)."""
    results = copy.deepcopy(_results())
    paths = [p for p in _paths(results) if p and (not within or p[0] in within)]
    path = paths[draw_index % len(paths)]
    parent = results
    for key in path[:-1]:
        parent = parent[key]
    if how == "delete":
        del parent[path[-1]]
    else:
        parent[path[-1]] = junk
    return results


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(index=st.integers(0, 10**6), how=st.sampled_from(["delete", "replace"]), junk=_junk)
def test_a_mutated_bench_json_gives_a_page_or_a_one_line_error(tmp_path_factory, index, how, junk):
    _page_or_one_line_error(tmp_path_factory, _mutated(index, how, junk), junk)


#: issue #36's sections and the others the page shows through the bench's printers (a mutation lands there often)
_PRINTED = ("main_job", "large_sweep", "kernels", "main_job_targets", "recorded", "tuning", "machine")


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(index=st.integers(0, 10**6), how=st.sampled_from(["delete", "replace"]), junk=_junk)
def test_a_mutated_main_job_section_gives_a_page_or_a_one_line_error(tmp_path_factory, index, how, junk):
    results = _mutated(index, how, junk, within=_PRINTED)
    text = _page_or_one_line_error(tmp_path_factory, results, junk)
    if text is not None:  # the untouched sections are still shown
        for title, key, _ in bench_page.SECTIONS:
            if key not in _PRINTED and key in results:
                assert not text.split(f"## {title}\n\n")[1].startswith(("Not shown", "Not measured")), title


def _page_or_one_line_error(tmp_path_factory, mutated: dict, junk) -> str | None:
    """The page of ``mutated`` (None when the command refused it with a one-line error and wrote nothing). No NaN or
    infinity is printed as a figure (``junk`` that is text spelling them may show as that text)."""
    tmp = tmp_path_factory.mktemp("page")
    results = tmp / "bench.json"
    results.write_text(json.dumps(mutated, allow_nan=True))
    page = tmp / "performance.md"
    code = _main_quietly(bench_page.main, [str(results), str(page)])
    assert code in (0, 2)
    text = None
    if code == 0:
        text = page.read_text()
        assert text.startswith("# Performance\n")
        if isinstance(junk, float) or not re.search(r"nan|inf", json.dumps(junk).lower()):  # a NaN is a figure
            assert "nan" not in text.lower().replace("not measured", "")
            assert not re.search(r"\binf\b", text.lower())
    else:
        assert not page.exists()
    assert {p.name for p in tmp.iterdir()} <= {"bench.json", "performance.md"}
    return text


_out = st.one_of(st.sampled_from(["", ".", "/", "/proc/nope.json", "/nonexistent/dir/x.json", "a\x00b",
                                  "x" * 300, "dir/", "ok.json"]), st.text(max_size=12))
_count = st.one_of(st.integers(-5, 10**7).map(str), st.sampled_from(["", "1e3", "nan", "0x10", " 3"]),
                   st.text(max_size=5))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(out=_out)
def test_bench_refuses_an_unusable_out_before_measuring(monkeypatch, tmp_path_factory, out):
    tmp = tmp_path_factory.mktemp("bench")
    monkeypatch.chdir(tmp)
    (tmp / "dir").mkdir()

    def measuring(*args, **kwargs):  # reached only when --out was accepted
        raise _Measuring

    monkeypatch.setattr(bench, "bench_fuzzy", measuring)
    try:
        code = _main_quietly(bench.main, ["--out", out])
    except _Measuring:
        assert out not in ("", ".", "/", "dir/") and "\x00" not in out
        return
    assert code == 2


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(episodes=_count, seeds=_count, out=_out)
def test_bench_report_refuses_bad_options_before_measuring(monkeypatch, tmp_path_factory, episodes, seeds, out):
    tmp = tmp_path_factory.mktemp("report")
    monkeypatch.chdir(tmp)
    (tmp / "dir").mkdir()

    def measuring(*args, **kwargs):
        raise _Measuring

    monkeypatch.setattr(report, "bench_report", measuring)
    try:
        code = _main_quietly(report.main, ["--episodes", episodes, "--seeds", seeds, "--out", out])
    except _Measuring:
        assert 1 <= int(episodes) <= report.MAX_EPISODES and 1 <= int(seeds) <= report.MAX_SEEDS
        return
    assert code == 2


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(commit=st.one_of(st.text(max_size=12), st.sampled_from(["--output=/tmp/x", "-h", "HEAD~100000", "../..",
                                                               "0" * 40])),
       rounds=_count)
def test_bench_baseline_refuses_bad_options_or_says_not_measured(monkeypatch, commit, rounds):
    monkeypatch.setattr(baseline, "_measure", _raise_measuring)
    monkeypatch.setattr(baseline, "build_kernels", lambda commit, tree: "")
    try:
        code = _main_quietly(baseline.main, ["--commit", commit, "--rounds", rounds, "--episodes", "1",
                                             "--passes", "1"])
    except _Measuring:
        return  # a commit of this checkout: measured (not here)
    assert code in (1, 2)


class _Measuring(Exception):
    """The measurement would start here."""


def _raise_measuring(*args, **kwargs):
    raise _Measuring


def _main_quietly(main, argv: list[str]) -> int:
    """A command's exit code, argparse's SystemExit included; its stderr must be one line per problem."""
    import contextlib
    import io

    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main(argv)
        except SystemExit as exit_:
            code = exit_.code if isinstance(exit_.code, int) else 2
    text = err.getvalue() or out.getvalue()  # the baseline's "not measured" line is its output
    if code:
        lines = text.strip().splitlines()
        assert "Traceback" not in text and lines, text[-2000:]
        assert "error:" in lines[-1] or lines[-1].startswith("bench_report:") or "not measured" in lines[-1], \
            text[-2000:]
        assert len([ln for ln in lines if not ln.startswith("usage:") and not ln.startswith(" ")]) == 1, text
    return code


def test_fuzzers_reach_both_outcomes(tmp_path):
    """The page fuzzer's mutations can give a page and an error, so that the test above can fail either way."""
    good = tmp_path / "bench.json"
    good.write_text(json.dumps(_results()))
    assert _main_quietly(bench_page.main, [str(good), str(tmp_path / "p.md")]) == 0
    good.write_text("{")
    assert _main_quietly(bench_page.main, [str(good), str(tmp_path / "q.md")]) == 2
    assert not Path(tmp_path / "q.md").exists() and math.isfinite(1.0)
