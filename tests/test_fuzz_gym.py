"""Hypothesis fuzzing of the Gymnasium API (runners.gym_env): any action, seed, options and call order an agent or
a training library might produce gives a valid transition or a one-line ``ValueError``/``ResetNeeded`` naming the
argument — never another exception, a NaN in an observation or reward, or an observation outside its space."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

gymnasium = pytest.importorskip("gymnasium")

from runners.gym_env import NavigationEnv  # noqa: E402

_ENVS: dict[bool, NavigationEnv] = {}


def _env(normalized: bool) -> NavigationEnv:
    """One environment per space form for the whole module (composing the config costs ~0.5 s)."""
    if normalized not in _ENVS:
        _ENVS[normalized] = NavigationEnv("head_on", normalized=normalized)
    return _ENVS[normalized]


_numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**30, 10**30),
                     st.sampled_from([0.0, -0.0, 1e-320, 1e308, -1e308, 120.0, 40.0, 10.0, -1.0, 1.0]))
_scalar_junk = st.one_of(st.none(), st.booleans(), st.text(max_size=8), st.binary(max_size=8),
                         st.complex_numbers(), _numbers)
_actions = st.one_of(
    st.tuples(_numbers, _numbers).map(list),
    st.tuples(_numbers, _numbers).map(lambda t: np.array(t, dtype=object)),
    st.tuples(_numbers, _numbers).map(lambda t: np.array([float(x) if isinstance(x, float) else 0.0 for x in t],
                                                         dtype=np.float32)),
    st.lists(_scalar_junk, max_size=4),
    _scalar_junk,
    st.lists(st.lists(_numbers, max_size=3), max_size=3),
    st.dictionaries(st.text(max_size=4), _numbers, max_size=2),
)
_calls = st.lists(st.one_of(
    st.tuples(st.just("step"), _actions),
    st.tuples(st.just("drive"), st.tuples(st.floats(-200, 200), st.floats(-100, 100))),  # to the episode's end
    st.tuples(st.just("reset"), st.one_of(st.none(), st.integers(-5, 2**60), st.floats(allow_nan=True),
                                          st.text(max_size=5), st.booleans())),
    st.tuples(st.just("options"), st.one_of(st.none(), st.dictionaries(st.text(max_size=4), _numbers, max_size=2),
                                            st.lists(_numbers, max_size=2), st.text(max_size=4))),
), min_size=1, max_size=12)


def _check_obs(env: NavigationEnv, obs: dict) -> None:
    assert env.observation_space.contains(obs), {k: v for k, v in obs.items()}
    for value in obs.values():
        assert np.all(np.isfinite(np.asarray(value, dtype=np.float64)))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(normalized=st.booleans(), calls=_calls)
def test_any_call_sequence_gives_a_valid_transition_or_a_one_line_error(normalized, calls):
    env = _env(normalized)
    env.reset(seed=0)
    for kind, arg in calls:
        try:
            if kind == "step":
                obs, reward, terminated, truncated, info = env.step(arg)
                _check_obs(env, obs)
                assert isinstance(reward, float) and math.isfinite(reward)
                assert isinstance(terminated, bool) and isinstance(truncated, bool) and isinstance(info, dict)
            elif kind == "drive":
                for _ in range(1000):
                    obs, reward, terminated, truncated, info = env.step(list(arg))
                    _check_obs(env, obs)
                    assert math.isfinite(reward)
                    if terminated or truncated:
                        break
                else:
                    raise AssertionError("an episode did not end within 1,000 steps")
            elif kind == "reset":
                obs, info = env.reset(seed=arg)
                _check_obs(env, obs)
            else:
                obs, info = env.reset(seed=1, options=arg)
                _check_obs(env, obs)
        except ValueError as err:
            line = str(err)
            assert "\n" not in line and line.split(":")[0] in ("action", "seed", "options"), line
        except gymnasium.error.ResetNeeded as err:
            assert "reset()" in str(err)


@settings(max_examples=25, deadline=None)
@given(normalized=st.booleans(), action=st.tuples(st.floats(-1e6, 1e6), st.floats(-1e6, 1e6)))
def test_a_finite_action_is_clamped_into_the_robots_range(normalized, action):
    """Any finite pair is a command the robot can execute: the turn within ±max_turn, the speed within [0, v_max]
    (clamped, as the docs say), never a refusal."""
    env = _env(normalized)
    dtheta, v = env.command(list(action))
    lim = env.episode_config.robot
    assert -lim.max_turn_deg <= dtheta <= lim.max_turn_deg and 0.0 <= v <= lim.v_max
