"""The checks every input goes through, with the limits of :mod:`fuzzynav.params.limits`: one function per kind of
value, each raising ``error(f"{field}: {problem}")`` — one line, starting with the dotted field.

Used by the scenario and controller parsers (with their own error classes) and, through
:func:`check_config_fields`, by :class:`fuzzynav.episode.EpisodeConfig` for every numeric field of the run
configuration (so NaN or inf cannot pass a ``< 0`` test anywhere).
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any

from fuzzynav.params import limits
from fuzzynav.params.limits import Range

#: EpisodeConfig attributes whose command-line name differs (they live in the ``sensors`` group)
_SECTIONS = {"sonar": "sensors.sonar", "laser": "sensors.laser"}


def check_number(value: Any, field: str, rng: Range | None = None, error: type[Exception] = ValueError) -> float:
    """``value`` as a float: a real number (not bool), finite, inside ``rng`` (and an integer if it says so)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise error(f"{field}: expected {'an integer' if rng and rng.integer else 'a number'}, got {show(value)}")
    if isinstance(value, float) and not math.isfinite(value):
        raise error(f"{field}: must be finite, got {value!r}")
    if rng is not None:
        if rng.integer and not isinstance(value, int):
            raise error(f"{field}: expected an integer, got {value!r}")
        if not rng.contains(value):
            raise error(f"{field}: must be in {rng.text()}, got {value!r}")
    return float(value)


def check_finite_range(value: Any, field: str, lo: float, hi: float, error: type[Exception] = ValueError,
                       unit: str = "") -> float:
    """:func:`check_number` with a closed interval ``[lo, hi]``."""
    return check_number(value, field, Range(lo, hi, unit), error)


def check_count(n: int, field: str, limit: int, error: type[Exception] = ValueError, what: str = "items") -> None:
    """At most ``limit`` items (a size limit of :mod:`fuzzynav.params.limits`)."""
    if n > limit:
        raise error(f"{field}: {n:,} {what}, more than the limit of {limit:,}")


def check_name(value: Any, field: str, error: type[Exception] = ValueError) -> str:
    """A name that becomes part of a file name: :data:`fuzzynav.params.limits.NAME_PATTERN` (letters, digits, ``_-.``,
    at most 64 characters, not starting with ``.``)."""
    if not isinstance(value, str):
        raise error(f"{field}: expected a name (string), got {show(value)}")
    if not limits.NAME_PATTERN.fullmatch(value):
        raise error(f"{field}: {show(value)} is not a valid name (letters, digits, _ - . only, at most "
                    f"{limits.NAME_MAX_CHARS} characters, not starting with '.')")
    return value


def check_text(value: Any, field: str, error: type[Exception] = ValueError) -> str:
    """A free-text string of at most :data:`fuzzynav.params.limits.MAX_TEXT_CHARS` characters, without NUL."""
    if not isinstance(value, str):
        raise error(f"{field}: expected a string, got {show(value)}")
    check_count(len(value), field, limits.MAX_TEXT_CHARS, error, "characters")
    if "\x00" in value:
        raise error(f"{field}: contains a NUL character")
    return value


def check_key(key: Any, field: str, error: type[Exception] = ValueError) -> str:
    """A mapping key must be a string. YAML 1.1 reads unquoted ``on``/``off``/``yes``/``no`` as booleans."""
    if isinstance(key, str):
        return key
    hint = " (YAML reads unquoted on/off/yes/no/true/false as booleans: quote the key)" if isinstance(key, bool) \
        else ""
    raise error(f"{field or 'top level'}: key {show(key)} is not a string{hint}")


_PLAIN_KEY = re.compile(r"[A-Za-z0-9_.-]{1,64}", re.ASCII)


def key_text(key: Any) -> str:
    """A user's mapping key as it appears in a field path: as is when plain, else quoted and cut, so that a key
    holding a newline or 10,000 characters cannot break the one-line message."""
    return key if isinstance(key, str) and _PLAIN_KEY.fullmatch(key) else show(key)


def kind_of(value: Any) -> str:
    """What a YAML value is, in YAML's words (``null``, not ``NoneType``)."""
    if value is None:
        return "null (an empty value)"
    if isinstance(value, bool):
        return f"{str(value).lower()} (a boolean)"
    if isinstance(value, int | float):
        return f"{show(value)} (a number)"
    if isinstance(value, str):
        return f"{show(value)} (a string)"
    if isinstance(value, list | tuple):
        return "a list"
    if isinstance(value, dict):
        return "a mapping"
    return type(value).__name__


def show(value: Any) -> str:
    """``repr`` cut to 60 characters (a user's value in a message: one line stays one readable line)."""
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:57]}..."


def field_name(prefix: str, attribute: str) -> str:
    """The dotted command-line name of a config attribute (``laser`` of EpisodeConfig is ``sensors.laser``)."""
    name = key_text(attribute)
    return f"{prefix}.{name}" if prefix else _SECTIONS.get(name, name)


def check_sonar_sectors(sonar: Any, field: str) -> None:
    """The right, front and left sectors follow each other counter-clockwise without overlapping (they may touch).
    The sonar builds its three wedges as one array of polygons, so they must also be sampled with the same
    number of arc points: equally wide, to the arc step (``fuzzynav.sensing.sonar.Sonar``)."""
    (r_lo, r_hi), (f_lo, f_hi), (l_lo, l_hi) = sonar.right, sonar.front, sonar.left
    if not (r_hi <= f_lo and f_hi <= l_lo and l_hi - r_lo <= 360):
        # the controller's rules read Left, Front and Right as three different directions: a sector that
        # overlaps another (or repeats it) makes one obstacle count for two inputs, and swapped sectors mirror
        # every steering rule
        raise ValueError(f"{field}: the sectors must follow each other counter-clockwise without overlapping "
                         "(right, front, left; they may touch; together at most 360 degrees), got right "
                         f"[{r_lo:g}, {r_hi:g}], front [{f_lo:g}, {f_hi:g}], left [{l_lo:g}, {l_hi:g}] degrees")
    points = [max(2, math.ceil((hi - lo) / sonar.arc_step_deg) + 1) for lo, hi in (sonar.left, sonar.front,
                                                                                 sonar.right)]
    if len(set(points)) > 1:
        widths = ", ".join(f"{hi - lo:g}" for lo, hi in (sonar.left, sonar.front, sonar.right))
        raise ValueError(f"{field}: the left, front and right sectors must be equally wide (to the arc step "
                         f"{sonar.arc_step_deg:g} degrees), got widths {widths} degrees")


#: checks across the fields of one config section, run after its numbers are checked
_SECTION_CHECKS = {"sensors.sonar": check_sonar_sectors}


def check_config_fields(config: Any, prefix: str = "") -> None:
    """Check every numeric field of a config dataclass tree against its range (:func:`~.limits.field_range`)
    (finite always; the documented range where one is listed; sequences item by item and in length), then the
    checks across fields of a section (:data:`_SECTION_CHECKS`)."""
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        field = field_name(prefix, f.name)
        if dataclasses.is_dataclass(value):
            check_config_fields(value, field)
            if field in _SECTION_CHECKS:
                _SECTION_CHECKS[field](value, field)
        elif isinstance(value, tuple):
            check_count(len(value), field, limits.FIELD_MAX_ITEMS.get(field, 1_000))
            for i, item in enumerate(value):
                check_number(item, f"{field}[{i}]", limits.field_range(f, field))
        elif isinstance(value, int | float) and not isinstance(value, bool):
            check_number(value, field, limits.field_range(f, field))
