"""JSON schemas of fuzzynav's own log topics (``fuzzynav.*``). Units are in the field names or descriptions:
``_cm`` centimetres, ``_cm_s`` cm/s, ``_deg`` degrees, ``_s`` seconds, ``_us`` microseconds."""

from __future__ import annotations

from analysis.log_format.foxglove import time_schema


def _n(desc: str) -> dict:
    return {"type": "number", "description": desc}


def _i(desc: str, minimum: int | None = 0) -> dict:
    d: dict = {"type": "integer", "description": desc}
    if minimum is not None:
        d["minimum"] = minimum
    return d


def _s(desc: str) -> dict:
    return {"type": "string", "description": desc}


def _b(desc: str) -> dict:
    return {"type": "boolean", "description": desc}


def _arr(items: dict, desc: str) -> dict:
    return {"type": "array", "items": items, "description": desc}


def _xy(desc: str) -> dict:
    return {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2, "description": desc}


def _obj(title: str, desc: str, props: dict, optional: tuple[str, ...] = ()) -> dict:
    return {"title": title, "description": desc, "type": "object", "properties": props,
            "required": [k for k in props if k not in optional], "additionalProperties": False}


def _stamped(title: str, desc: str, props: dict, optional: tuple[str, ...] = ()) -> dict:
    base = {"timestamp": time_schema("Simulation time of the step (s since the episode start)"),
            "step": _i("Step index (0-based); the message describes the world at time step * dt")}
    return _obj(title, desc, {**base, **props}, optional)


def sonar() -> dict:
    return _stamped("fuzzynav.Sonar", "Sonar readings: distance from the robot surface to the nearest static "
                    "obstacle or wall in each sector, 0..range (range = nothing seen)", {
                        "left_cm": _n("Left sector reading, cm"), "front_cm": _n("Front sector reading, cm"),
                        "right_cm": _n("Right sector reading, cm"), "range_cm": _n("Sonar range, cm")})


def _track_item() -> dict:
    return _obj("fuzzynav.Track", "A perceived moving obstacle", {
        "id": _i("Track id"), "x_cm": _n("Position x, cm"), "y_cm": _n("Position y, cm"),
        "vx_cm_s": _n("Velocity x, cm/s"), "vy_cm_s": _n("Velocity y, cm/s"), "speed_cm_s": _n("Speed, cm/s"),
        "heading_deg": _n("Moving angle phi, degrees [0, 360) CCW from +x"), "radius_cm": _n("Radius, cm")})


def tracks() -> dict:
    return _stamped("fuzzynav.Tracks", "Moving obstacles as perceived this step (laser tracking or ground truth)", {
        "mode": {"type": "string", "enum": ["laser", "ground_truth"], "description": "Perception mode"},
        "moving_beams": _arr({"type": "integer", "minimum": 0}, "Indices of the /laser beams attributed to "
                             "moving obstacles; the other returns are the static points"),
        "tracks": _arr(_track_item(), "Perceived moving obstacles")})


def obstacles_truth() -> dict:
    item = _obj("fuzzynav.ObstacleTruth", "A moving obstacle's true state", {
        "id": _s("Obstacle id from the scenario"), "x_cm": _n("Position x at the step, cm"),
        "y_cm": _n("Position y at the step, cm"), "vx_cm_s": _n("Velocity x, cm/s"), "vy_cm_s": _n("Velocity y, cm/s"),
        "radius_cm": _n("Radius, cm"), "next_x_cm": _n("Position x one step later, cm"),
        "next_y_cm": _n("Position y one step later, cm"),
        "present": _b("In the world at the step: sensed, touchable and measured (absent: before a recorded person "
                      "appears or after it leaves; its position is then where it will appear or where it left). "
                      "Written only by scenarios whose obstacles come and go; a log without it has every obstacle "
                      "present throughout"),
        "next_present": _b("In the world one step later (given with present); the robot can touch the obstacle "
                           "over the step only when both are true"),
        "reacting": _b("Moved over this step by its reaction to the robot, not by its recording's replay (a "
                       "recorded person with react_cm; once true, true to the end). Written only by scenarios "
                       "whose people may react")}, optional=("present", "next_present", "reacting"))
    return _stamped("fuzzynav.ObstaclesTruth", "True states of the moving obstacles",
                    {"obstacles": _arr(item, "All moving obstacles of the scenario")})


def robot_state() -> dict:
    return _stamped("fuzzynav.RobotState", "The robot at sensing time and after the step's move", {
        "x_cm": _n("Position x at the step, cm"), "y_cm": _n("Position y at the step, cm"),
        "heading_deg": _n("Heading at the step, degrees [0, 360) CCW from +x"),
        "v_cm_s": _n("Speed commanded on the previous step, cm/s (0 = standing)"),
        "next_x_cm": _n("Position x after the move, cm"), "next_y_cm": _n("Position y after the move, cm"),
        "next_heading_deg": _n("Heading after the move, degrees"), "next_v_cm_s": _n("Speed of the move, cm/s"),
        "radius_cm": _n("Robot radius, cm"),
        "contact_static": _b("The robot touched a static obstacle or wall during the move (swept)"),
        "contact_dynamic": _arr({"type": "string"}, "Ids of moving obstacles touched during the move"),
        "new_contacts": _i("Contacts that started on this step"),
        "distance_to_goal_cm": _n("Distance from the position after the move to the goal, cm")})


def tpt() -> dict:
    return _stamped("fuzzynav.TPT", "Trajectory Prediction Table: row k predicts time step + k (row 0 = now)", {
        "n_traj": _i("Number of predicted steps (rows 1..n_traj)", 1), "dt_s": _n("Step length, s"),
        "robot_speed_cm_s": _n("Speed the robot is predicted to move at, cm/s"),
        "robot_radius_cm": _n("Robot radius, cm"), "safety_margin_cm": _n("Safety margin, cm"),
        "robot_cm": _arr(_xy("Predicted robot position, cm"), "Robot position per row, cm"),
        "obstacle_ids": _arr({"type": "integer"}, "Track id of each obstacle column"),
        "obstacle_radii_cm": _arr({"type": "number"}, "Radius of each obstacle, cm"),
        "obstacle_velocities_cm_s": _arr(_xy("Velocity, cm/s"), "Velocity of each obstacle, cm/s"),
        "obstacles_cm": _arr(_arr(_xy("Position, cm"), "Obstacles at one row"),
                             "Predicted obstacle positions, [row][obstacle] -> [x, y] cm"),
        "collide": _arr(_arr({"type": "boolean"}, "Collision with each obstacle"),
                        "Collision matrix [row][obstacle]")})


def decision() -> dict:
    planning = _obj("fuzzynav.Planning", "The dynamic path planner's quantities when a plan was made", {
        "strategy": {"type": "string", "enum": ["wait", "detour", "evade", "stop"], "description": "Chosen strategy"},
        "tc": _i("First predicted collision step"), "tS": _i("tc - 1"), "tG": _i("First free step after tc"),
        "wait_time": _i("tG - tS - 1, steps"), "h_wait": _i("Wait threshold hWait, steps"),
        "obstacle_id": _i("Track id of the colliding obstacle"),
        "detour_start": {"type": ["integer", "null"], "description": "tS' (detour only)"},
        "phi_low_deg": {"type": ["number", "null"], "description": "phiLow of the first expansion, degrees"},
        "reason": _s("Why this strategy"),
        "path_cm": _arr(_xy("Position, cm"), "Planned positions for steps 1..L after this step, cm")})
    return _stamped("fuzzynav.Decision", "The navigation decision of one step", {
        "mode": {"type": "string", "pattern": "^[a-z][a-z0-9_]{0,31}$",
                 "description": "wait/detour/evade/stop: following a plan of the TPT layer; otherwise the "
                                "policy's own mode (fuzzy policy: direct = to the target, fuzzy = the fuzzy "
                                "controller; dwa, apf, vfh, orca, direct, ...)"},
        "policy": _s("The navigation policy (navigator.policy, or the import path of navigator._target_)"),
        "policy_fields": {"type": "object", "additionalProperties": {"type": ["number", "boolean", "string"]},
                          "description": "The policy's own values of this step (e.g. DWA's scores)"},
        "new_plan": _b("A plan was made on this step"),
        "left_cm": _n("Sonar left input, cm"), "front_cm": _n("Sonar front input, cm"),
        "right_cm": _n("Sonar right input, cm"),
        "angle_deg": _n("Included angle input, degrees (0 = target right, 90 ahead, 180 left)"),
        "dtheta_deg": _n("Steering increment output, degrees (positive = left)"),
        "v_cm_s": _n("Speed output, cm/s (0 = stand still)"),
        "strategy": _s("Configured strategy (auto | wait | detour | none)"),
        "planning": {"oneOf": [planning, {"type": "null"}], "description": "Planner quantities (new plans only)"},
        "compute_time_us": _n("Wall time of the decision (perception excluded), microseconds; not reproducible")})


def episode() -> dict:
    return _obj("fuzzynav.Episode", "How the episode ended (written last)", {
        "timestamp": time_schema("Simulation time at the end"),
        "outcome": {"type": "string", "enum": ["goal", "collision", "timeout", "error", "interrupted"],
                    "description": "Outcome"},
        "steps": _i("Number of steps run"), "time_s": _n("Simulated time, s"),
        "contacts": _i("Contacts counted (entering contact counts once)"), "reason": _s("Human-readable reason")})


FUZZYNAV_SCHEMAS = {
    "fuzzynav.Sonar": sonar,
    "fuzzynav.Tracks": tracks,
    "fuzzynav.ObstaclesTruth": obstacles_truth,
    "fuzzynav.RobotState": robot_state,
    "fuzzynav.TPT": tpt,
    "fuzzynav.Decision": decision,
    "fuzzynav.Episode": episode,
}
