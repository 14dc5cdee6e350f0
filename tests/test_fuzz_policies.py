"""Hypothesis fuzzing of what a user's policy can do wrong (its ``act()`` returns anything, raises anything, at
any step; its ``reset`` raises): the episode runs through ``runners.run.run_episode`` exactly as a run or a sweep
job does, and the result is always a log that the analysis reads and checks, with outcome goal, collision,
timeout or error — an error with one line that names the policy — never an exception out of the run, a log
the analysis refuses, or a NaN in the logged state."""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from analysis.episode_log import load_episode
from analysis.metrics import episode_metrics
from fuzzynav.episode import Episode
from fuzzynav.policies.base import Action
from runners import run
from runners.sweeping import stop
from tests.test_suite_and_datasets import EVALUATOR, composed

_number = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**20, 10**20),
                    st.sampled_from([0.0, -0.0, 120.0, -120.0, 120.0000001, 40.0, 1000.0, 1e-300]))
_junk = st.one_of(st.none(), st.booleans(), st.text(max_size=6), st.binary(max_size=4), _number,
                  st.lists(_number, max_size=3), st.complex_numbers())
_fields = st.one_of(st.dictionaries(st.one_of(st.text(max_size=6), st.integers()), _junk, max_size=3), _junk)
_actions = st.one_of(
    st.builds(Action, st.one_of(st.sampled_from(["fuzzed", "go_2", "wait", "detour", "Bad Mode", ""]), _junk),
              _number, _number, _fields),
    _junk,
)
_exceptions = st.sampled_from([ValueError("bad\nnews"), RuntimeError(""), ZeroDivisionError("x"), MemoryError(),
                               RecursionError(), AssertionError(), StopIteration(), KeyError("k"),
                               TypeError("t" * 10_000), ArithmeticError("\x00"), KeyboardInterrupt(), SystemExit(3),
                               GeneratorExit()])
_script = st.lists(st.one_of(st.tuples(st.just("ok"), st.floats(-120, 120), st.floats(0, 40)),
                             st.tuples(st.just("return"), _actions),
                             st.tuples(st.just("raise"), _exceptions)), min_size=1, max_size=6)


class _Scripted:
    """A policy that drives sensibly, then does what the script says at chosen steps."""

    name = "fuzzed"

    def __init__(self, script: list, at: list[int], reset_raises: BaseException | None) -> None:
        self.script, self.at, self.reset_raises, self.k = script, at, reset_raises, 0

    def reset(self, seed: int) -> None:
        self.k = 0
        if self.reset_raises is not None:
            raise self.reset_raises

    def act(self, observation):
        k, self.k = self.k, self.k + 1
        if k in self.at:
            kind, *payload = self.script[self.at.index(k) % len(self.script)]
            if kind == "return":
                return payload[0]
            if kind == "raise":
                raise payload[0]
            return Action("fuzzed", payload[0], payload[1], {})
        return Action("fuzzed", 0.0, 25.0, {})


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(script=_script, at=st.lists(st.integers(0, 30), min_size=1, max_size=6, unique=True),
       reset_raises=st.one_of(st.none(), _exceptions), seed=st.integers(0, 3))
def test_a_misbehaving_policy_gives_a_checked_log_or_one_line_naming_it(monkeypatch, tmp_path_factory, script, at,
                                                                       reset_raises, seed):
    cfg = composed("head_on", planner={"strategy": "none"})
    scenario = run.load_scenario(cfg, seed)
    ep_cfg = dataclasses.replace(run.episode_config(cfg), policy="fuzzed")  # the log's metadata names it
    policy = _Scripted(script, at, reset_raises)
    monkeypatch.setattr(run, "Episode", functools.partial(Episode, policy=policy))
    path = tmp_path_factory.mktemp("policy") / "episode.mcap"
    restore = stop.install(None)  # as in a run: signals routed, so a KeyboardInterrupt raised by code is the code's
    try:
        summary = run.run_episode(scenario, EVALUATOR, ep_cfg, seed, path, "")
    except run.PolicyError as err:  # reset(seed) failed: the configuration's error, before any log
        assert reset_raises is not None and "\n" not in str(err) and "policy" in str(err), str(err)
        assert not path.exists()
        return
    finally:
        restore()
    assert reset_raises is None
    log = load_episode(path)  # checks every message and the file
    assert log.outcome == summary["outcome"] in ("goal", "collision", "timeout", "error")
    if log.outcome == "error":
        reason = summary.get("reason", "") or log.reason
        assert "policy fuzzed" in reason and "\n" not in reason, reason
    xy = np.array([[s["x_cm"], s["y_cm"]] for s in log.states]) if log.states else np.zeros((0, 2))
    assert np.all(np.isfinite(xy))
    row = episode_metrics(log)
    assert all(not isinstance(v, float) or not math.isinf(v) or k.startswith(("min_", "time_to"))
               for k, v in row.items()), row


def test_the_fuzzer_reaches_an_error_and_a_goal(monkeypatch, tmp_path):
    """Its two outcomes, so that the test above can fail both ways."""
    cfg = composed("head_on", planner={"strategy": "none"})
    for script, expected in (([("return", None)], "error"), ([("ok", 0.0, 25.0)], "goal")):
        monkeypatch.setattr(run, "Episode", functools.partial(Episode, policy=_Scripted(script, [0], None)))
        summary = run.run_episode(run.load_scenario(cfg, 0), EVALUATOR,
                                  dataclasses.replace(run.episode_config(cfg), policy="fuzzed"), 0,
                                  tmp_path / f"{expected}.mcap", "")
        assert summary["outcome"] in ((expected,) if expected == "error" else ("goal", "collision"))


pytest.importorskip("hypothesis")
