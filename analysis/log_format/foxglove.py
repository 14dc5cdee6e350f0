"""JSON schemas of the Foxglove message types fuzzynav writes, from Foxglove's published schema docs.

Written for fuzzynav (not copied): the fields, types and required lists follow the documented
``foxglove.SceneUpdate``, ``foxglove.PoseInFrame``, ``foxglove.LaserScan`` and ``foxglove.Log``. They are
embedded in every MCAP log (encoding ``jsonschema``) and used by the tests to validate our messages.
Foxglove's own units apply: metres, radians, seconds.
"""

from __future__ import annotations

from typing import Any


def _num(desc: str) -> dict:
    return {"type": "number", "description": desc}


def _obj(title: str, desc: str, props: dict[str, Any], required: list[str] | None = None) -> dict:
    return {"title": title, "description": desc, "type": "object", "properties": props,
            "required": list(props) if required is None else required}


def time_schema(desc: str) -> dict:
    return {"type": "object", "title": "time", "description": desc,
            "properties": {"sec": {"type": "integer", "minimum": 0},
                           "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
            "required": ["sec", "nsec"]}


def _duration(desc: str) -> dict:
    return {"type": "object", "title": "duration", "description": desc,
            "properties": {"sec": {"type": "integer"},
                           "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
            "required": ["sec", "nsec"]}


def _vector3(desc: str) -> dict:
    return _obj("foxglove.Vector3", desc, {k: _num(f"{k} coordinate length") for k in "xyz"})


def _point3(desc: str) -> dict:
    return _obj("foxglove.Point3", desc, {k: _num(f"{k} coordinate position") for k in "xyz"})


def _quaternion() -> dict:
    return _obj("foxglove.Quaternion", "Quaternion denoting orientation in 3D space",
                {k: _num(f"{k} value") for k in "xyzw"})


def _pose(desc: str) -> dict:
    return _obj("foxglove.Pose", desc, {"position": _vector3("Point denoting position in 3D space"),
                                        "orientation": _quaternion()})


def _color(desc: str) -> dict:
    return _obj("foxglove.Color", desc, {c: _num(f"{name} value between 0 and 1") for c, name in
                                         (("r", "Red"), ("g", "Green"), ("b", "Blue"), ("a", "Alpha"))})


def _enum(title: str, desc: str, values: list[tuple[str, int, str]]) -> dict:
    return {"title": title, "description": desc,
            "oneOf": [{"title": t, "const": c, "description": d} for t, c, d in values]}


def _array(items: dict, desc: str) -> dict:
    return {"type": "array", "items": items, "description": desc}


def _primitives() -> dict[str, dict]:
    color = _color("Color")
    colors = _array(_color("A color in RGBA format"), "Per-vertex colors")
    indices = _array({"type": "integer", "minimum": 0}, "Indices into the points and colors arrays")
    return {
        "arrows": _obj("foxglove.ArrowPrimitive", "A primitive representing an arrow", {
            "pose": _pose("Position of the arrow's tail and orientation of the arrow"),
            "shaft_length": _num("Length of the arrow shaft"), "shaft_diameter": _num("Diameter of the shaft"),
            "head_length": _num("Length of the arrow head"), "head_diameter": _num("Diameter of the head"),
            "color": color}),
        "cubes": _obj("foxglove.CubePrimitive", "A primitive representing a cube or rectangular prism", {
            "pose": _pose("Position of the center of the cube"), "size": _vector3("Size along each axis"),
            "color": color}),
        "spheres": _obj("foxglove.SpherePrimitive", "A primitive representing a sphere or ellipsoid", {
            "pose": _pose("Position of the center of the sphere"), "size": _vector3("Size along each axis"),
            "color": color}),
        "cylinders": _obj("foxglove.CylinderPrimitive", "A primitive representing a cylinder", {
            "pose": _pose("Position of the center of the cylinder"),
            "size": _vector3("Size of the cylinder's bounding box"),
            "bottom_scale": _num("0-1, ratio of the bottom face diameter to the bounding box"),
            "top_scale": _num("0-1, ratio of the top face diameter to the bounding box"), "color": color}),
        "lines": _obj("foxglove.LinePrimitive", "A primitive representing a series of points connected by lines", {
            "type": _enum("foxglove.LineType", "Drawing primitive to use for lines", [
                ("LINE_STRIP", 0, "Connected line segments"), ("LINE_LOOP", 1, "Closed polygon"),
                ("LINE_LIST", 2, "Individual line segments")]),
            "pose": _pose("Origin of lines relative to reference frame"), "thickness": _num("Line thickness"),
            "scale_invariant": {"type": "boolean", "description": "Thickness in screen pixels (true) or world units"},
            "points": _array(_point3("A point"), "Points along the line"), "color": color, "colors": colors,
            "indices": indices}),
        "triangles": _obj("foxglove.TriangleListPrimitive", "A primitive representing a set of triangles", {
            "pose": _pose("Origin of triangles relative to reference frame"),
            "points": _array(_point3("A vertex"), "Vertices"), "color": color, "colors": colors,
            "indices": indices}),
        "texts": _obj("foxglove.TextPrimitive", "A primitive representing a text label", {
            "pose": _pose("Position of the center of the text box"),
            "billboard": {"type": "boolean", "description": "Whether the text always faces the camera"},
            "font_size": _num("Font size (height of one line of text)"),
            "scale_invariant": {"type": "boolean", "description": "Font size in screen pixels (true)"},
            "color": color, "text": {"type": "string", "description": "Text"}}),
        "models": _obj("foxglove.ModelPrimitive", "A primitive representing a 3D model file", {
            "pose": _pose("Origin of model"), "scale": _vector3("Scale factor"), "color": color,
            "override_color": {"type": "boolean", "description": "Use color instead of embedded materials"},
            "url": {"type": "string", "description": "URL pointing to model file"},
            "media_type": {"type": "string", "description": "Media type of embedded model"},
            "data": {"type": "string", "contentEncoding": "base64", "description": "Embedded model"}}),
    }


def scene_update() -> dict:
    entity_props = {
        "timestamp": time_schema("Timestamp of the entity"),
        "frame_id": {"type": "string", "description": "Frame of reference"},
        "id": {"type": "string", "description": "Identifier; replaces any prior entity with the same id"},
        "lifetime": _duration("Time after which the entity is removed; zero means until replaced or deleted"),
        "frame_locked": {"type": "boolean", "description": "Whether the entity follows frame_id as it moves"},
        "metadata": _array(_obj("foxglove.KeyValuePair", "A key with its associated value", {
            "key": {"type": "string", "description": "Key"},
            "value": {"type": "string", "description": "Value"}}), "Additional metadata"),
    }
    entity_props.update({k: _array(v, f"{k} primitives") for k, v in _primitives().items()})
    deletion = _obj("foxglove.SceneEntityDeletion", "Command to remove previously published entities", {
        "timestamp": time_schema("Only matching entities earlier than this timestamp are deleted"),
        "type": _enum("foxglove.SceneEntityDeletionType", "Type of deletion action to perform", [
            ("MATCHING_ID", 0, "Delete the entity with the given id"), ("ALL", 1, "Delete all entities")]),
        "id": {"type": "string", "description": "Identifier which must match if type is MATCHING_ID"}})
    schema = _obj("foxglove.SceneUpdate", "An update to the entities displayed in a 3D scene", {
        "deletions": _array(deletion, "Scene entities to delete"),
        "entities": _array(_obj("foxglove.SceneEntity", "A visual element in a 3D scene", entity_props),
                           "Scene entities to add or replace")})
    return schema


def pose_in_frame() -> dict:
    return _obj("foxglove.PoseInFrame", "A timestamped pose for an object or reference frame in 3D space", {
        "timestamp": time_schema("Timestamp of pose"),
        "frame_id": {"type": "string", "description": "Frame of reference for pose position and orientation"},
        "pose": _pose("Pose in 3D space")})


def laser_scan() -> dict:
    return _obj("foxglove.LaserScan", "A single scan from a planar laser range-finder", {
        "timestamp": time_schema("Timestamp of scan"),
        "frame_id": {"type": "string", "description": "Frame of reference"},
        "pose": _pose("Origin of scan relative to frame of reference"),
        "start_angle": _num("Bearing of first point, in radians"),
        "end_angle": _num("Bearing of last point, in radians"),
        "ranges": _array({"type": "number"}, "Distance of detections from origin"),
        "intensities": _array({"type": "number"}, "Intensity of detections")})


def log() -> dict:
    return _obj("foxglove.Log", "A log message", {
        "timestamp": time_schema("Timestamp of log message"),
        "level": _enum("foxglove.LogLevel", "Log level", [
            ("UNKNOWN", 0, "Unknown log level"), ("DEBUG", 1, "Debug log level"), ("INFO", 2, "Info log level"),
            ("WARNING", 3, "Warning log level"), ("ERROR", 4, "Error log level"), ("FATAL", 5, "Fatal log level")]),
        "message": {"type": "string", "description": "Log message"},
        "name": {"type": "string", "description": "Process or node name"},
        "file": {"type": "string", "description": "Filename"},
        "line": {"type": "integer", "minimum": 0, "description": "Line number in the file"}})


FOXGLOVE_SCHEMAS = {
    "foxglove.SceneUpdate": scene_update,
    "foxglove.PoseInFrame": pose_in_frame,
    "foxglove.LaserScan": laser_scan,
    "foxglove.Log": log,
}
