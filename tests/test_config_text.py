"""runners.logs.yaml_text.config_text writes the same text as OmegaConf.to_yaml: on every config option (with and
without Hydra's node, resolved or not) and on random configs, by libyaml where they are plain, by PyYAML elsewhere."""

from __future__ import annotations

import pytest
import yaml
from hydra import compose, initialize_config_dir
from hypothesis import given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from fuzzynav.conf import CONF_DIR
from runners.configuration import schema
from runners.logs import yaml_text

GROUPS = ("scenario", "planner", "navigator", "controller", "perception", "robot", "sensors", "sweep")


def options() -> list[tuple[str, str]]:
    return [(g, p.stem) for g in GROUPS for p in sorted((CONF_DIR / g).glob("*.yaml"))]


@pytest.mark.parametrize(("group", "option"), options())
def test_every_config_option_same_text_as_omegaconf(group: str, option: str) -> None:
    schema.register()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose("config", overrides=[f"{group}={option}"], return_hydra_config=True)
    task = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    for node, resolve in ((cfg, False), (task, False), (task, True), (cfg.hydra, False)):
        assert yaml_text.config_text(node, resolve=resolve) == OmegaConf.to_yaml(node, resolve=resolve)
    if getattr(yaml, "CDumper", None) is not None:  # the fast path is the one taken for a run's config
        assert yaml_text.plain(OmegaConf.to_container(task, resolve=True))


KEYS = st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126), min_size=1, max_size=64)
WORDS = st.sampled_from(["yes", "no", "on", "null", "~", "1e3", "0x1F", "- a", "a: b", "#c", "'q'", '"d"', " lead",
                         "trail ", "1.0", ".inf", "True", "@x", "*y", "&z", "!t", "%p", "`b", "??", "[a]", "{b: 1}"])
PLAIN = st.recursive(
    st.one_of(st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=126), min_size=1, max_size=300),
              st.text(alphabet="ab :-#'\"", min_size=70, max_size=1000), WORDS,
              st.floats(), st.integers(), st.booleans(), st.none()),
    lambda ch: st.one_of(st.lists(ch, max_size=4), st.dictionaries(KEYS, ch, max_size=4)), max_leaves=30)
ANY = st.recursive(
    st.one_of(st.text(), st.floats(), st.integers(), st.booleans(), st.none(), WORDS,
              st.text(alphabet=" ab:#-\n'\"\t\u00e9\u2028", max_size=200)),
    lambda ch: st.one_of(st.lists(ch, max_size=4), st.dictionaries(st.text(max_size=10), ch, max_size=4)),
    max_leaves=20)


@settings(max_examples=1500, deadline=None)
@given(st.dictionaries(KEYS, PLAIN, max_size=6))
def test_plain_configs_same_text(data: dict) -> None:
    same_text_or_error(data)


def same_text_or_error(data: dict) -> None:
    """The same text as OmegaConf's, or the same error (a malformed ``${...}`` interpolation)."""
    try:
        expected = OmegaConf.to_yaml(OmegaConf.create(data))
    except Exception as err:
        with pytest.raises(type(err)):
            yaml_text.config_text(data)
        return
    assert yaml_text.config_text(data) == expected


@settings(max_examples=500, deadline=None)
@given(st.dictionaries(st.text(max_size=12), ANY, max_size=5))
def test_any_config_same_text(data: dict) -> None:
    same_text_or_error(data)
