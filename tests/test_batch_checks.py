"""The analysis decides its message checks per topic over a whole episode at once (``messages_acceptable``) and the
TPT errors over arrays of tables (``tpt_errors``). Both must give what the message-by-message rules and the
straightforward per-table loop give: checked here on mutated real messages and on random tables."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from analysis.episode_log import METRIC_TOPICS, EpisodeLog, load_episode
from analysis.log_check import MESSAGE_CHECKS, CheckError, check_message, messages_acceptable
from analysis.logs import LogError, LogFile
from analysis.tpt_errors import obstacle_models, tpt_errors
from fuzzynav.numerics.portable_math import norm2
from fuzzynav.params.names import DEFAULT_MODEL
from tests.fuzz_mutations import mutations
from tests.handmade import rewrite_log
from tests.valid_logs import recorded_logs  # noqa: F401 - the session fixture

TOPICS = sorted(MESSAGE_CHECKS)


def _messages(path: Path) -> dict[str, list]:
    out: dict[str, list] = {}
    with LogFile(path) as log:
        for topic, _t, msg in log.messages():
            if topic == "/scene" and topic in out:
                continue  # the analysis checks the first scene only
            out.setdefault(topic, []).append(msg)
    return out


def _each_passes(topic: str, msgs: list) -> bool:
    try:
        for m in msgs:
            check_message(topic, m)
    except CheckError:
        return False
    return True


@pytest.fixture(scope="module")
def real_messages(recorded_logs) -> dict[str, list]:  # noqa: F811
    return _messages(recorded_logs[0])


def test_a_real_episode_passes_both_ways(real_messages):
    assert set(real_messages) >= set(METRIC_TOPICS)
    for topic, msgs in real_messages.items():
        assert messages_acceptable(topic, msgs), topic
        assert _each_passes(topic, msgs), topic


@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                  HealthCheck.too_slow])
@given(data=st.data())
def test_the_batch_decision_is_the_message_by_message_decision(real_messages, data):
    topic = data.draw(st.sampled_from(TOPICS))
    msgs = list(real_messages[topic])
    for _ in range(data.draw(st.integers(1, 2))):
        i = data.draw(st.integers(0, len(msgs) - 1))
        msgs[i], _what = data.draw(mutations(msgs[i]))
    assert messages_acceptable(topic, msgs) == _each_passes(topic, msgs)


@pytest.mark.parametrize(("tpt_step", "named"), [(10, "/robot/state message at step 9"), (8, "/tpt message at step 8")])
def test_a_bad_message_is_named_as_one_by_one_reading_names_it(tmp_path, recorded_logs, tpt_step, named):  # noqa: F811
    """Two bad messages on two topics: the first in file order is the one named (the batch only says 'no')."""
    def edit(topic, msg):
        if topic == "/tpt" and msg["step"] == tpt_step:
            msg["robot_cm"][1] = [1.0, "x"]
        if topic == "/robot/state" and msg["step"] == 9:
            msg["heading_deg"] = 400.0
    bad = tmp_path / "bad.mcap"
    rewrite_log(recorded_logs[0], bad, edit)
    with pytest.raises(LogError, match=rf"{named} does not match its schema"):
        load_episode(bad)


# -- the TPT errors against the per-table loop -----------------------------------------------------------------

def _reference_tpt_errors(log: EpisodeLog) -> tuple[float, float, dict[str, tuple[float, float]]]:
    """The definition, one table and one obstacle column at a time (the test's oracle)."""
    if not log.tpts or not log.truth:
        return math.nan, math.nan, {}
    models = obstacle_models(log.meta)
    truth_at = {m["step"]: {o["id"]: (o["x_cm"], o["y_cm"]) for o in m["obstacles"]} for m in log.truth}
    errors: dict[str, list[float]] = {}
    finals: dict[str, list[float]] = {}
    for step, t in log.tpts.items():
        now = truth_at.get(step)
        if not now:
            continue
        ids = list(now)
        true_now = np.array([now[i] for i in ids])
        predicted = np.array(t["obstacles_cm"], dtype=float).reshape(len(t["obstacles_cm"]), -1, 2)
        for j, radius in enumerate(t["obstacle_radii_cm"]):
            pred = predicted[:, j]
            d0 = norm2(true_now - pred[0])
            match = int(np.argmin(d0))
            if d0[match] > radius + 50.0:
                continue
            oid = ids[match]
            rows = [k for k in range(1, len(pred)) if oid in truth_at.get(step + k, {})]
            if rows:
                errs = norm2(pred[rows] - np.array([truth_at[step + k][oid] for k in rows]))
                errors.setdefault(models.get(oid, DEFAULT_MODEL), []).extend(errs.tolist())
                finals.setdefault(models.get(oid, DEFAULT_MODEL), []).append(float(errs[-1]))
    if not errors:
        return math.nan, math.nan, {}
    every = [e for es in errors.values() for e in es]
    every_final = [f for fs in finals.values() for f in fs]
    return (math.fsum(every) / len(every), math.fsum(every_final) / len(every_final),
            {m: (math.fsum(errors[m]) / len(errors[m]), math.fsum(finals[m]) / len(finals[m])) for m in errors})


@st.composite
def _episodes(draw) -> EpisodeLog:
    steps = draw(st.integers(1, 12))
    n_obstacles = draw(st.integers(0, 4))
    ids = [draw(st.sampled_from(["a", "b", "c", "d"])) for _ in range(n_obstacles)]  # repeats allowed
    coord = st.floats(-500, 500, allow_nan=False).map(lambda v: round(v, 1))
    truth = [{"step": k, "obstacles": [{"id": i, "x_cm": draw(coord), "y_cm": draw(coord)} for i in ids]}
             for k in range(steps)]
    tpts = {}
    for step in draw(st.sets(st.integers(0, steps + 2), max_size=6)):
        rows, k = draw(st.integers(1, 5)), draw(st.integers(0, 3))
        tpts[step] = {"step": step, "obstacles_cm": [[[draw(coord), draw(coord)] for _ in range(k)]
                                                     for _ in range(rows)],
                      "obstacle_radii_cm": [draw(st.sampled_from([0.0, 20.0, 300.0])) for _ in range(k)]}
    models = ["social_force", "orca", "custom_model", None]
    scenario = "dynamic_obstacles:\n" + "".join(
        f"  - id: {i}\n" + (f"    model: {m}\n" if m else "") for i, m in zip(
            dict.fromkeys(ids), [draw(st.sampled_from(models)) for _ in dict.fromkeys(ids)], strict=True))
    return EpisodeLog(path=Path("x.mcap"), meta={"scenario_yaml": scenario}, config={}, complete=True, dt=1.0,
                      truth=truth, tpts=tpts)


@settings(max_examples=400, deadline=None)
@given(log=_episodes())
def test_tpt_errors_are_the_per_table_definition_to_the_last_bit(log):
    ade, fde, by_model = tpt_errors(log)
    r_ade, r_fde, r_by_model = _reference_tpt_errors(log)
    same = lambda a, b: (math.isnan(a) and math.isnan(b)) or a == b  # noqa: E731
    assert same(ade, r_ade) and same(fde, r_fde)
    assert by_model.keys() == r_by_model.keys()
    for model, (a, f) in by_model.items():
        assert same(a, r_by_model[model][0]) and same(f, r_by_model[model][1])


def test_the_collector_pause_nests_and_restores_the_state_it_found():
    import gc

    from analysis.logs import collector_paused

    assert gc.isenabled()
    with pytest.raises(RuntimeError), collector_paused():
        assert not gc.isenabled()
        with collector_paused():
            assert not gc.isenabled()
        assert not gc.isenabled()  # the inner pause does not switch it back on
        raise RuntimeError
    assert gc.isenabled()
    gc.disable()
    try:
        with collector_paused():
            pass
        assert not gc.isenabled()  # left as found
    finally:
        gc.enable()
