"""The documented limits (fuzzynav/params/limits.py) cover every input they should, and the checks enforce them."""

from __future__ import annotations

import dataclasses
import math
import re
import typing

import pytest

from fuzzynav.config import episode_config_from_dict
from fuzzynav.episode import EpisodeConfig
from fuzzynav.params import limits
from fuzzynav.params.checks import check_config_fields, check_name, check_number, field_name
from fuzzynav.policies.base import registered_policies
from runners.configuration.data_files import DataFileError, check_data_text
from runners.configuration.run_inputs import run_seeds


def numeric_fields(cls: type, prefix: str = "") -> list[str]:
    """Dotted names of every int/float (or tuple of them) field of a config dataclass tree."""
    out = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        hint = hints[f.name]
        name = field_name(prefix, f.name)
        if dataclasses.is_dataclass(hint):
            out += numeric_fields(hint, name)
        elif hint in (int, float) or (typing.get_origin(hint) is tuple and typing.get_args(hint)[0] in (int, float)):
            out.append(name)
    return out


def policy_ranges() -> dict[str, tuple[str, limits.Range]]:
    """``navigator.<field>`` -> (policy, range) of every registered policy's own declared ranges."""
    return {field: (name, rng) for name, policy in sorted(registered_policies().items())
            for field, rng in limits.declared_ranges(policy.config_class, "navigator").items()}


def test_every_numeric_config_field_has_a_documented_range():
    # the core configuration's ranges are in FIELD_RANGES; each policy's (the navigator section) on its own class
    core = {f for f in numeric_fields(EpisodeConfig) if not f.startswith("navigator.")}
    documented = set(limits.FIELD_RANGES) - {"seed", "episodes"}
    assert core - documented == set(), "numeric fields without a range in fuzzynav/params/limits.py"
    assert documented - core == set(), "ranges in fuzzynav/params/limits.py for fields that do not exist"
    for name, policy in registered_policies().items():
        declared = limits.declared_ranges(policy.config_class, "navigator")
        assert set(numeric_fields(policy.config_class, "navigator")) - set(declared) == set(), \
            f"policy {name}: numeric parameters without a range (limits.ranged) on {policy.config_class.__name__}"


def test_defaults_and_shipped_values_are_inside_their_ranges():
    check_config_fields(EpisodeConfig())  # raises on a default outside its range
    for policy in registered_policies().values():
        check_config_fields(policy.config_class(), "navigator")
    table = limits.markdown_table()
    for field, rng in limits.FIELD_RANGES.items():
        assert f"| `{field}` | {rng.text()}" in table
    for lim in limits.SIZE_LIMITS:
        assert f"| {lim.field} | {lim.value:,} |" in table


@pytest.mark.parametrize("field", sorted(set(limits.FIELD_RANGES) - {"seed", "episodes"}) + sorted(policy_ranges()))
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_no_field_accepts_a_non_finite_number(field, bad):
    section, _, key = field.rpartition(".")
    data: dict = {}
    node = data
    for part in section.replace("sensors.", "").split(".") if section else []:
        node = node.setdefault(part, {})
    value: typing.Any = [bad, bad] if field in limits.FIELD_MAX_ITEMS else bad
    node[key] = value
    if section == "navigator":  # the policy whose parameter it is (the fuzzy policy would call it unknown)
        node["policy"] = policy_ranges()[field][0]
    with pytest.raises(ValueError, match=rf"^{re.escape(field)}(\[0\])?: "):
        episode_config_from_dict(data)


@pytest.mark.parametrize("value, problem", [
    (math.nan, "must be finite"), (True, "expected a number"), ("1", "expected a number"), (-1, "must be in"),
    (61, "must be in"), (0, "must be in [0.001, 60] s"), (1e-300, "must be in [0.001, 60] s")])
def test_check_number_names_the_field_and_the_range(value, problem):
    with pytest.raises(ValueError, match=r"^dt: ") as err:
        check_number(value, "dt", limits.FIELD_RANGES["dt"])
    assert problem in str(err.value)
    assert check_number(60, "dt", limits.FIELD_RANGES["dt"]) == 60.0


@pytest.mark.parametrize("name", ["../x", "a/b", ".hidden", "", "x" * 65, "a\x00b", "a\nb", "é", 5, None])
def test_unsafe_names_are_refused(name):
    with pytest.raises(ValueError, match=r"^name: "):
        check_name(name, "name")


@pytest.mark.parametrize("name", ["head_on", "a" * 64, "v1.2-b_c", "-x", "X"])
def test_safe_names_pass(name):
    assert check_name(name, "name") == name


def test_seeds_of_a_run():
    assert run_seeds({"seed": 5, "episodes": 3}) == [5, 6, 7]
    for cfg, problem in [({"episodes": 0}, "episodes: must be in"), ({"episodes": 10_001}, "episodes: must be in"),
                         ({"seed": -1}, "seed: must be in"), ({"seed": 1.5}, "seed: expected an integer"),
                         ({"seed": limits.MAX_SEED, "episodes": 2}, "seed: seed + episodes - 1")]:
        with pytest.raises(ValueError, match=re.escape(problem)):
            run_seeds(cfg)


@pytest.mark.parametrize("text, problem", [
    ("a: &a [x, x]\nb: [*a, *a]\n", None),  # aliases are fine when small (listing.yaml shares its terms)
    ("a: !!binary AAAA\n", "x.yaml:1: a: YAML tag 'tag:yaml.org,2002:binary' is not allowed"),
    ("a: {b: '${oc.env:HOME}'}\n", "x.yaml:1: a.b: interpolation '${oc.env:HOME}' is not allowed"),
    ("a: &a [1, *a]\n", "x.yaml:1: a[1]: recursive alias"),
    ("a: 1\n---\nb: 2\n", "x.yaml:2: top level: more than one YAML document"),
    ("- 1\n", "x.yaml:1: top level: expected a mapping"),
    ("a: [" * 33 + "]" * 33 + "\n", "nested deeper than the limit of 32 levels"),
    ("a: [1, 2\nb: 3\n", "x.yaml:1:4: YAML error: while parsing a flow sequence"),
    (b"a: \xff\n", "x.yaml: not UTF-8 text (byte 3)"),
])
def test_data_text(text, problem):
    if problem is None:
        check_data_text(text, "x.yaml")
        return
    with pytest.raises(DataFileError) as err:
        check_data_text(text, "x.yaml")
    assert problem in str(err.value) and "\n" not in str(err.value)


def test_alias_expansion_is_counted_exactly():
    # 1 mapping + key/value pairs: a0 = 1 seq + w scalars; a_d = 1 + w * size(a_{d-1})
    width, depth = 10, 4
    sizes = [1 + width]
    for _ in range(1, depth):
        sizes.append(1 + width * sizes[-1])
    total = 1 + sum(1 + s for s in sizes)  # the top mapping, each key and each value
    text = "a0: &a0 [" + ", ".join(["x"] * width) + "]\n" + "".join(
        f"a{d}: &a{d} [" + ", ".join([f"*a{d - 1}"] * width) + "]\n" for d in range(1, depth))
    assert total > limits.MAX_YAML_NODES > total - sizes[-1] - 1
    with pytest.raises(DataFileError, match=f"a{depth - 1}: more than 10,000 YAML nodes"):
        check_data_text(text, "x.yaml")
    check_data_text(text.rsplit("\n", 2)[0] + "\n", "x.yaml")  # without the last level: 1,237 nodes
