"""The policy seam (fuzzynav/policies/base.py) and the ``direct`` floor baseline."""

from __future__ import annotations

import numpy as np
import pytest

from fuzzynav.kinematics import RobotLimits, RobotState, step_unicycle
from fuzzynav.planning.layer import Observation
from fuzzynav.policies.base import POLICIES, Action, Policy, PolicyContext, make_policy, register_policy
from fuzzynav.policies.direct import DirectPolicy, direct_command

CTX = PolicyContext(RobotLimits(), robot_radius=20.0)


def observe(state: RobotState, goal=(500.0, 0.0)) -> Observation:
    return Observation(state, goal, (130.0, 130.0, 130.0), (), np.zeros((0, 2)))


def test_registry_builds_by_name_and_refuses_unknown_names_and_double_registration():
    policy = make_policy("direct", {}, CTX)
    assert isinstance(policy, DirectPolicy) and isinstance(policy, Policy)
    with pytest.raises(ValueError, match=r"policy: unknown policy 'nope' \(known: .*direct"):
        make_policy("nope", {}, CTX)
    with pytest.raises(ValueError, match="already registered"):
        register_policy("direct")(lambda params, context: policy)
    assert POLICIES["direct"] is DirectPolicy


def test_direct_parameters_are_checked_and_named():
    with pytest.raises(ValueError, match=r"navigator\.speed_cm_s: must be in \(0, 1,000\] cm/s"):
        make_policy("direct", {"speed_cm_s": 0}, CTX)
    with pytest.raises(ValueError, match=r"navigator\.speed: unknown key"):
        make_policy("direct", {"speed": 10}, CTX)


def test_direct_turns_to_the_goal_and_lands_on_it():
    # goal straight behind-left: turn +135 (the robot clamps it), cruise speed
    assert direct_command(0.0, 0.0, 0.0, (-100.0, 100.0), 25.0, 10.0, 40.0, 1.0) == (135.0, 25.0)
    # 12 cm from the goal: 12 cm/s lands on it; 4 cm: v_min (the robot cannot go slower)
    assert direct_command(0.0, 0.0, 0.0, (12.0, 0.0), 25.0, 10.0, 40.0, 1.0) == (0.0, 12.0)
    assert direct_command(0.0, 0.0, 0.0, (4.0, 0.0), 25.0, 10.0, 40.0, 1.0)[1] == 10.0
    state, policy = RobotState(0.0, 0.0, 90.0), make_policy("direct", {"speed_cm_s": 30}, CTX)
    policy.reset(0)
    for _ in range(30):
        action = policy.act(observe(state))
        assert isinstance(action, Action) and action.mode == "direct"
        state = step_unicycle(state, action.dtheta_deg, action.v_cm_s, 1.0, CTX.limits)
        if np.hypot(state.x - 500.0, state.y) <= 1e-6:
            break
    assert np.hypot(state.x - 500.0, state.y) <= 1e-6
