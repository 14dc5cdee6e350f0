"""Write small fuzzynav-format logs by hand (no simulator), for metrics with known answers."""

from __future__ import annotations

import json
import zlib
from pathlib import Path

from mcap.writer import CompressionType, Writer

from analysis.log_format import SCHEMAS, TOPICS
from fuzzynav.episode_identity import config_hash

GOAL = (500.0, 500.0)


def _stamp(t: float) -> dict[str, int]:
    ns = round(t * 1e9)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _entity(eid: str, lines=(), cylinders=()) -> dict:
    return {"timestamp": _stamp(0), "frame_id": "world", "id": eid, "lifetime": {"sec": 0, "nsec": 0},
            "frame_locked": False, "metadata": [], "arrows": [], "cubes": [], "spheres": [],
            "cylinders": list(cylinders), "lines": list(lines), "triangles": [], "texts": [], "models": []}


def _loop(points_cm) -> dict:
    return {"type": 1, "points": [{"x": x / 100, "y": y / 100, "z": 0.0} for x, y in points_cm]}


def register_topic(writer: Writer, topic: str) -> int:
    """A JSON channel for one of fuzzynav's topics, declaring the schema the writer declares for it (name and
    text, as ``runners.logs.mcap_log`` embeds them); its channel id."""
    name = TOPICS[topic]
    schema = writer.register_schema(name, "jsonschema", json.dumps(SCHEMAS[name]()).encode())
    return writer.register_channel(topic, "json", schema)


def write_log(path: Path, poses, *, radius: float = 20.0, statics=(), obstacles=None, modes=None, speeds=None,
              contacts_static=None, outcome: str = "goal", bounds=(-200.0, -200.0, 800.0, 800.0),
              goal=GOAL, tolerance: float = 20.0, meta=None, truncate: bool = False) -> Path:
    """``poses``: [(x, y, heading_deg), ...] for steps 0..n (n steps); ``statics``: polygons (cm);
    ``obstacles``: per step a list of (id, x, y, next_x, next_y, r); ``modes``/``speeds`` per step."""
    n = len(poses) - 1
    modes = modes or ["direct"] * n
    speeds = speeds or [25.0] * n
    contacts_static = contacts_static or [False] * n
    w = Writer(open(path, "wb"), compression=CompressionType.ZSTD)  # noqa: SIM115 - closed by finish()
    w.start()
    ch = {t: register_topic(w, t) for t in ("/scene", "/robot/state", "/obstacles/truth", "/planner/decision",
                                            "/episode")}
    metadata = {"config": "dt: 1.0\n", "seed": "0", "scenario": "handmade", "strategy": "auto", "h_wait": "2",
                "controller": "table1", "perception": "laser"}
    # a seed of its own per file name: logs of one config and seed with other content are one episode in conflict
    metadata["seed"] = str(zlib.crc32(path.name.encode()) % 1_000_000)
    metadata.update(meta or {})
    # as runners.run records them: the analysis leaves out a log without them
    metadata.setdefault("fuzzynav_version", "0.0.0+handmade")
    metadata.setdefault("config_hash", config_hash(metadata.get("config", ""), metadata.get("seed", "0"),
                                                   metadata["fuzzynav_version"]))
    w.add_metadata("fuzzynav.run", metadata)

    def put(topic, t, msg):
        w.add_message(ch[topic], log_time=round(t * 1e9), publish_time=round(t * 1e9), data=json.dumps(msg).encode())

    xmin, ymin, xmax, ymax = bounds
    ents = [_entity("walls", lines=[_loop([(xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax)])])]
    ents += [_entity(f"static/{i}", lines=[_loop(p)]) for i, p in enumerate(statics)]
    ents.append(_entity("goal", cylinders=[{"pose": {"position": {"x": goal[0] / 100, "y": goal[1] / 100, "z": 0}},
                                            "size": {"x": 2 * tolerance / 100, "y": 2 * tolerance / 100, "z": 0.02}}]))
    put("/scene", 0, {"deletions": [], "entities": ents})
    for k in range(n):
        (x, y, h), (nx, ny, nh) = poses[k], poses[k + 1]
        put("/robot/state", k, {"step": k, "x_cm": x, "y_cm": y, "heading_deg": h, "v_cm_s": speeds[k - 1] if k else 0,
                                "next_x_cm": nx, "next_y_cm": ny, "next_heading_deg": nh, "next_v_cm_s": speeds[k],
                                "radius_cm": radius, "contact_static": contacts_static[k], "contact_dynamic": [],
                                "new_contacts": 0, "distance_to_goal_cm": 0})
        obs = (obstacles or [[]] * n)[k]
        put("/obstacles/truth", k, {"step": k, "obstacles": [
            {"id": oid, "x_cm": ox, "y_cm": oy, "vx_cm_s": 0, "vy_cm_s": 0, "radius_cm": r, "next_x_cm": qx,
             "next_y_cm": qy} for oid, ox, oy, qx, qy, r in obs]})
        put("/planner/decision", k, {"step": k, "mode": modes[k], "new_plan": False, "left_cm": 130, "front_cm": 130,
                                     "right_cm": 130, "angle_deg": 90, "dtheta_deg": 0, "v_cm_s": speeds[k],
                                     "strategy": metadata["strategy"], "planning": None, "compute_time_us": 10.0 + k})
        if truncate and k == n // 2:
            w._Writer__stream.flush()
            return path
    put("/episode", n, {"outcome": outcome, "steps": n, "time_s": float(n), "contacts": 0, "reason": ""})
    w.finish()
    return path


def rewrite_log(src: Path, dst: Path, edit) -> None:
    """Copy a complete log message by message; ``edit(topic, message_dict)`` may change a message in place."""
    from mcap.reader import make_reader

    with open(src, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        meta = list(reader.iter_metadata())
        msgs = list(reader.iter_messages())
    with open(dst, "wb") as out:
        w = Writer(out, compression=CompressionType.ZSTD)
        w.start()
        schema_ids = {sid: w.register_schema(s.name, s.encoding, s.data) for sid, s in summary.schemas.items()}
        chan_ids = {cid: w.register_channel(c.topic, c.message_encoding, schema_ids[c.schema_id])
                    for cid, c in summary.channels.items()}
        for m in meta:
            w.add_metadata(m.name, m.metadata)
        for _s, channel, message in msgs:
            payload = json.loads(message.data)
            edit(channel.topic, payload)
            w.add_message(chan_ids[channel.id], message.log_time, json.dumps(payload).encode(), message.publish_time)
        w.finish()
