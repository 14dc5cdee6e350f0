"""Compose the configuration once before Hydra runs, so a bad override or config file is one clear line.

Hydra reports composition errors on several lines; researchers launching thousands of episodes want
``error: config: planner.h_wiat: Key 'h_wiat' not in 'PlannerConfigSchema'`` and a non-zero exit before
anything starts. For a sweep, every value of a swept override is composed once (the other swept keys at their
first value), one per type for numbers, as numbers of one type compose alike. With ``--debug`` or
``HYDRA_FULL_ERROR=1`` the check is skipped and Hydra's full report is shown.
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Callable, Sequence
from pathlib import Path

from hydra import compose, initialize_config_dir
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import ValueType
from omegaconf import DictConfig

from runners import schema

CONF = Path(__file__).resolve().parents[1] / "conf"


def _value_kind(value: object) -> object:
    """What composing a value depends on: the type for numbers, booleans and null; the value otherwise."""
    if value is None or isinstance(value, bool | int | float):
        return type(value).__name__
    return repr(value)


def representative_jobs(batch: Sequence[Sequence[str]]) -> list[Sequence[str]]:
    """The jobs of ``batch`` (each a list of ``key=value`` overrides), in order, that first bring a new
    (key, value kind) pair: composing them tries every swept value (see :func:`_value_kind`). Used by the
    command-line check below and by fuzzynav's Hydra sweeper (``runners/hydra_sweeper/``)."""
    parser = OverridesParser.create()
    seen: set[tuple[str, object]] = set()
    picked = []
    for job in batch:
        pairs = {(o.get_key_element(), _value_kind(o.value())) for o in parser.parse_overrides(list(job))}
        if not pairs <= seen:
            seen |= pairs
            picked.append(job)
    return picked


def debug_requested(argv: list[str]) -> bool:
    return "--debug" in argv or os.environ.get("HYDRA_FULL_ERROR") == "1"


def _one_line(err: BaseException) -> str:
    """The most useful single line of a (possibly chained) composition error."""
    texts = [str(e) for e in (err, err.__cause__, err.__context__) if e is not None and str(e)]
    full = "\n".join(texts)
    key = re.search(r"full_key: (\S+)", full)
    where = re.search(r'in "([^"]+)", line (\d+), column (\d+)', full)
    if where:  # YAML syntax: name the file and the position
        problem = [ln.strip() for ln in full.splitlines() if ln.strip() and not ln.strip().startswith("in ")]
        return f"{where.group(1)}:{where.group(2)}:{where.group(3)}: YAML error: {problem[-1]}"
    if key:
        detail = texts[-1].splitlines()[0]
        return f"config: {key.group(1)}: {detail}"
    missing = re.search(r"Could not find '([^']+)'", full)
    if missing:
        group = missing.group(1).split("/")[0]
        options = sorted(p.stem for p in (CONF / group).glob("*.yaml")) if (CONF / group).is_dir() else []
        hint = f" (available: {', '.join(options)})" if options else ""
        return f"config: no config '{missing.group(1)}'{hint}"
    return f"config: {texts[0].splitlines()[0]}"


def precheck(args: list[str], on_config: Callable[[DictConfig], None] | None = None) -> str | None:
    """One-line description of why these command-line overrides cannot be composed, or None.

    ``on_config`` is called with the first composed config, Hydra's node included (the sweep uses it to start
    its worker processes while the rest is checked and Hydra starts)."""
    overrides = [a for a in args if not a.startswith("-")]
    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except Exception as err:
        return f"config: cannot read the overrides: {str(err).splitlines()[0]}"
    base, variants = [], []
    for o in parsed:
        if not o.is_sweep_override():
            base.append(o.input_line)
            continue
        if o.value_type == ValueType.GLOB_CHOICE_SWEEP:
            continue  # globs only select existing options
        values = list(o.sweep_string_iterator())
        if o.value_type in (ValueType.RANGE_SWEEP, ValueType.INTERVAL_SWEEP):
            values = values[:1]  # numbers of one type: the first stands for all (without listing them all)
        prefix = "+" if o.is_add() else ""
        variants.append([f"{prefix}{o.get_key_element()}={v}" for v in values])
    firsts = [v[0] for v in variants if v]
    trials = [base + firsts]
    for i, values in enumerate(variants):  # every other value of each swept key, the rest at their first value
        for value in values[1:]:
            trials.append([*base, *firsts[:i], value, *firsts[i + 1:]])
    with contextlib.suppress(Exception):  # an override that does not parse: composing it below reports it
        trials = representative_jobs(trials)  # one value of each kind per key is enough
    schema.register()
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        for k, overrides in enumerate(trials):
            try:
                cfg = compose("config", overrides=overrides, return_hydra_config=k == 0 and on_config is not None)
            except Exception as err:
                return _one_line(err)
            if k == 0 and on_config is not None:
                on_config(cfg)
    return None
