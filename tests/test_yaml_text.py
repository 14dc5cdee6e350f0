"""runners.logs.yaml_text: libyaml's text where it is PyYAML's, PyYAML's elsewhere (the same text either way)."""

from __future__ import annotations

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from runners.logs import yaml_text

LIBYAML = pytest.mark.skipif(getattr(yaml, "CSafeDumper", None) is None, reason="PyYAML without libyaml")

_WORDS = st.sampled_from(["yes", "no", "null", "~", "1e5", "0x1F", "-", "- a", ": b", "#c", "'q'", '"d"', "[e]",
                          "{f: 1}", "&g", "*h", "!i", "|", ">", "%j", "@k", "`l", "?", " lead", "trail ", "a  b",
                          ".inf", "-.nan", "2026-12-03", "12:30", "0o17", "+1", ".5", "=", "<<"])
_ASCII = st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), min_size=1, max_size=200)
_STRINGS = _ASCII | _WORDS | st.lists(_WORDS | _ASCII, min_size=1, max_size=30).map(" ".join)
_SCALARS = (st.none() | st.booleans() | st.integers() | st.integers(-2**70, 2**70)
            | st.floats() | st.sampled_from([0.0, -0.0, 1e300, 5e-324, 1e16, 0.1, 123456789.125]) | _STRINGS)
_KEYS = (_WORDS | st.text(st.characters(min_codepoint=0x20, max_codepoint=0x7E), min_size=1, max_size=64)
         | st.sampled_from(["robot", "model_params", "x" * 64, " k", "k ", "a: b", "- c"]))
_PLAIN = st.recursive(_SCALARS, lambda inner: st.lists(inner, max_size=5)
                      | st.dictionaries(_KEYS, inner, max_size=5), max_leaves=40)


@LIBYAML
@settings(max_examples=3000, deadline=None)
@given(st.lists(_PLAIN, max_size=5) | st.dictionaries(_KEYS, _PLAIN, max_size=5))
def test_libyaml_writes_pyyamls_text_for_plain_data(data):
    assert yaml_text.plain(data)
    fast = yaml.dump(data, Dumper=yaml.CSafeDumper, sort_keys=False)
    assert fast == yaml.safe_dump(data, sort_keys=False)
    assert yaml_text.dump(data) == fast


@pytest.mark.parametrize("data", [{"description": "tab\there"}, {"": 1}, {"name": ""}, ["caf\u00e9"],
                                  {"a": ["\U0001F600" * 50]}, {"k" * 65: 1},
                                  {1: "int key"}, {"long": "x\\" * 100 + "\u2028"}, "text", 1.5, None])
def test_other_strings_and_lone_scalars_take_pyyaml(data):
    assert not yaml_text.plain(data) or type(data) not in (dict, list)
    assert yaml_text.dump(data) == yaml.safe_dump(data, sort_keys=False)


def test_every_configured_scenario_is_written_as_pyyaml_writes_it():
    from runners.benchmarks.crowd import _inputs
    from runners.run import load_scenario, scenario_data, scenario_yaml
    from tests.conftest import ROOT

    for path in sorted((ROOT / "conf" / "scenario").glob("*.yaml")):
        base = _inputs("social_force", 20)
        base["scenario"] = yaml.safe_load(path.read_text())
        try:
            scenario = load_scenario(base, 3)
        except Exception:  # a scenario that needs other inputs: its own tests load it
            continue
        data = scenario_data(scenario)
        assert scenario_yaml(scenario) == yaml.safe_dump(data, sort_keys=False), path.name



def test_data_holding_a_list_or_mapping_twice_takes_pyyaml_at_once():
    looped: list = []
    looped.append(looped)
    mapping: dict = {}
    mapping["a"] = mapping
    shared = [1]
    for _ in range(40):  # 2**40 paths through the same lists
        shared = [shared, shared]
    for data in (looped, mapping, shared, {"a": [1], "b": None}):
        assert yaml_text.dump(data) == yaml.safe_dump(data, sort_keys=False)
    assert not yaml_text.plain(shared) and yaml_text.plain({"a": [1], "b": None})
