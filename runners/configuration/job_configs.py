"""Each job's config of a sweep (or each episode's of a dataset's verification), composed by Hydra once per swept
value instead of once per job.

Used by the sweep's launcher (:mod:`hydra_plugins.fuzzynav_sweeper.launcher`, with Hydra's ``load_sweep_config``)
and by ``runners.dataset verify`` (:mod:`runners.datasets.episode_recording`, with ``hydra.compose``).

Hydra composes a job's config from its overrides in about 0.1 s (defaults lists, YAML files, merges): in the default
sweep more than its five episodes cost. A sweep is a product of swept keys, and most of its jobs differ from a
composed one in one or two keys. :class:`JobConfigs` composes (with Hydra's own ``load_sweep_config``) the first job
of the sweep (the *reference*) and, for each config group that the sweep varies, the reference with only that
group changed; every other job is *assembled* from those. Jobs whose overrides set other keys (a dataset's variants
``navigator=dwa`` and ``[navigator=fuzzy_tpt, planner=auto_h4]``) have their own reference, the first job with the
same keys in the same order:

* a config group's option (``scenario=head_on``) contributes the top-level nodes in which its composition differs
  from the reference's (its *delta*), and its entry in ``hydra.runtime.choices``;
* a plain value (``seed=7``, ``planner.h_wait=3``) is applied as Hydra applies a value override after composing
  (``OmegaConf.update(cfg, key, value, merge=True)``); a mapping (``scenario.params={n: 4}``) only where it is the
  reference's own (merged onto the reference's, another mapping would keep the reference's keys);
* ``hydra.overrides.task`` and ``hydra.job.override_dirname`` are the job's, as Hydra computes them.

Assembly is used only where it is the same as composing: every override a plain ``key=value`` (no ``+``, ``~``,
``@package``), and the deltas of the swept groups in different top-level nodes and nowhere else in Hydra's node. An
option whose delta is more than its own nodes (a navigator also chooses the planner group) is composed once: a job
with the same options that differs in plain values is made from that composition (its *sibling*), its values
applied as above. Anything else (or any error while assembling) is composed by Hydra, which also reports a bad value
in its own words. ``tests/test_job_configs.py`` compares assembled and composed configs
over the sweep presets and random products of every config group's options.
"""

from __future__ import annotations

import copy
import pickle
from collections.abc import Sequence
from typing import Any

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Override
from omegaconf import DictConfig, OmegaConf, open_dict, read_write

# hydra's node: the fields that follow a job's overrides (everything else must be the reference's)
_TASK_FIELDS = (("overrides", "task"), ("job", "override_dirname"), ("runtime", "choices"))


class JobConfigs:
    """The configs of one sweep's jobs. ``compose(overrides)`` must return what Hydra's
    ``config_loader.load_sweep_config(master, overrides)`` returns (it is that call, or a cache of it)."""

    def __init__(self, master: DictConfig, compose: Any) -> None:
        self._master = master
        self._compose = compose
        self._parser = OverridesParser.create()
        self._parsed: tuple[tuple[str, ...] | None, list[Override]] = (None, [])  # the last job's parsed overrides
        self._composed: dict[tuple[str, ...], DictConfig] = {}
        self._pickled: dict[tuple[str, ...], bytes] = {}  # composed configs' bytes, for new copies (_fresh)
        # the reference of each shape of overrides (their keys in order): the first job of that shape
        self._references: dict[tuple[Any, ...], tuple[tuple[str, ...], list[Override]]] = {}
        # (reference, group, option) -> delta, or None where it is not separable
        self._deltas: dict[tuple[tuple[str, ...], str, str], dict[str, Any] | None] = {}
        # a composed config's overrides -> ((their shape, their config group options), parsed) (:meth:`_sibling`)
        self._signatures: dict[tuple[str, ...], tuple[tuple[Any, ...], list[Override]]] = {}
        self.composed = 0  # how many configs Hydra composed (for the log and the tests)
        self.assembled = 0

    def add_composed(self, overrides: Sequence[str], config: DictConfig | bytes) -> None:
        """A config Hydra has composed elsewhere (the sweeper's check of each swept value): the object, or its
        pickled bytes when a worker process composed it. Bytes are unpickled only where a config is needed (the
        launching process needs none: it unpickled the default sweep's ten configs only to pickle them again for
        the workers, while they waited for their first job)."""
        key = tuple(overrides)
        if key in self._composed or key in self._pickled:
            return
        if isinstance(config, bytes):
            self._pickled[key] = config
        else:
            self._composed[key] = config

    def __getstate__(self) -> dict[str, Any]:
        """Sent to the workers (the launch's state) without the configs that travel as bytes anyway."""
        state = self.__dict__.copy()
        state["_composed"] = {k: v for k, v in self._composed.items() if k not in self._pickled}
        state["_parsed"] = (None, [])
        state["_signatures"] = {}  # (remade where needed)
        return state

    def config(self, overrides: Sequence[str]) -> DictConfig:
        """The job's config, a new object the caller may change (its ``hydra.job.num`` and ``id``)."""
        key = tuple(overrides)
        if key == self._reference_of(key)[0] and key not in self._pickled:
            self._full(key)
        if key in self._composed or key in self._pickled:
            return self._fresh(key)
        try:
            assembled = self._assemble(key)
        except Exception:  # Hydra composes it and says what is wrong in its own words
            assembled = None
        if assembled is not None:
            self.assembled += 1
            return assembled
        self._full(key)
        return self._fresh(key)

    def to_compose(self, jobs: Sequence[Sequence[str]]) -> list[tuple[str, ...]]:
        """The configs that assembling ``jobs`` needs and this object does not have: the reference of each shape of
        overrides (the first job of that shape) but the first job's, and, for each config group option of a job
        that is not its reference's, the reference with only that option changed; in ``jobs``' order, each once.
        Composed elsewhere (in parallel) and given back with :meth:`add_composed`, they spare every later
        :meth:`config` a composition. The first job's config is composed here: its ``hydra.runtime.choices`` tell
        config groups from values (for every shape here; :meth:`config` uses each job's own reference's)."""
        keys = [tuple(j) for j in jobs]
        if not keys:
            return []
        choices = self._full(self._reference_of(keys[0])[0]).hydra.runtime.choices
        wanted: list[tuple[str, ...]] = []
        for key in keys:
            ref_key, ref_parsed = self._reference_of(key)
            wanted.append(ref_key)
            differences = _differences(self._parse(key), ref_parsed, choices)
            if differences is not None:  # (else composed whole where it is needed, as :meth:`config` would)
                wanted.extend(_varied_key(ref_key, i, o) for i, o in differences[0])
        have = set(self._composed) | set(self._pickled)
        return [k for k in dict.fromkeys(wanted) if k not in have]

    def _reference_of(self, key: tuple[str, ...]) -> tuple[tuple[str, ...], list[Override]]:
        """(overrides, parsed) of the reference of ``key``'s shape: the first job seen with the same keys in the
        same order (a sweep has one shape; a dataset's variants may set different keys)."""
        parsed = self._parse(key)
        shape = tuple(o.get_key_element() for o in parsed)
        reference = self._references.get(shape)
        if reference is None:
            reference = self._references[shape] = (key, list(parsed))
        return reference

    def _fresh(self, key: tuple[str, ...]) -> DictConfig:
        """A new copy of the composed config of ``key``: unpickled from its bytes, pickled once (a quarter of a
        deep copy's time: ~2 ms instead of ~8 for a run's config; cloudpickle, as the schema's dataclasses are made
        at run time)."""
        data = self._pickled.get(key)
        if data is None:
            import cloudpickle

            data = self._pickled[key] = cloudpickle.dumps(self._composed[key], protocol=pickle.HIGHEST_PROTOCOL)
        fresh = pickle.loads(data)  # this object's own bytes
        assert isinstance(fresh, DictConfig)
        return fresh

    def _full(self, key: tuple[str, ...]) -> DictConfig:
        config = self._composed.get(key)
        if config is None and key in self._pickled:
            config = self._composed[key] = pickle.loads(self._pickled[key])  # this sweep's own bytes
        if config is None:
            config = self._compose(list(key))
            self.composed += 1
            self._composed[key] = config
        return config

    def _parse(self, key: tuple[str, ...]) -> list[Override]:
        """The job's overrides as Hydra parses them (~1.5 ms): once per job, for its assembly and its folder name."""
        if self._parsed[0] != key:
            self._parsed = (key, self._parser.parse_overrides(list(key)))
        return self._parsed[1]

    def _match(self, key: tuple[str, ...]) -> tuple[list[tuple[int, Override]], list[Override]] | None:
        """How the job of ``key`` differs from its reference, where assembling it is the same as composing it
        (:func:`_differences`, with the reference's config groups)."""
        ref_key, ref_parsed = self._reference_of(key)
        return _differences(self._parse(key), ref_parsed, self._full(ref_key).hydra.runtime.choices)

    def _assemble(self, key: tuple[str, ...]) -> DictConfig | None:
        match = self._match(key)
        if match is None:
            return None
        groups, values = match
        base = self._reference_of(key)[0]
        deltas: list[dict[str, Any]] | None = []
        touched: set[str] = set()
        for i, o in groups:
            delta = self._delta(base, i, o)
            if delta is None or touched & set(delta["nodes"]):
                deltas = None
                break
            touched |= set(delta["nodes"])
            deltas.append(delta)
        if deltas is None:  # an option that changes more than its own nodes (a navigator choosing the planner)
            sibling = self._sibling(key)
            if sibling is None:
                return None
            base, deltas = sibling, []
        config = self._fresh(base)
        with read_write(config), open_dict(config):
            for delta in deltas:
                for name, node in delta["nodes"].items():
                    config[name] = node  # OmegaConf copies it (a deepcopy of a child node would copy its parents)
                config.hydra.runtime.choices[delta["group"]] = delta["choice"]
        for o in values:  # as Hydra applies a value override once the config is composed (struct flags kept)
            OmegaConf.update(config, o.key_or_group, o.value(), merge=True)
        with read_write(config), open_dict(config):
            config.hydra.overrides.task = list(key)
            config.hydra.job.override_dirname = self._override_dirname(key, base)
        OmegaConf.copy_cache(from_config=self._master, to_config=config)
        return config

    def _sibling(self, key: tuple[str, ...]) -> tuple[str, ...] | None:
        """A composed config whose overrides have ``key``'s shape and config group options and differ from it in
        plain values only, each mapping value the same (Hydra merges a mapping onto the composed default): the
        job is that config with its own values applied. None where there is none yet."""
        wanted = self._signature(key)[0]
        parsed = self._parse(key)
        for other in [*self._composed, *self._pickled]:
            signature, other_parsed = self._signature(other)
            if other != key and signature == wanted:
                choices = self._full(other).hydra.runtime.choices
                differences = _differences(parsed, other_parsed, choices)
                if differences is not None and not differences[0]:
                    return other
        return None

    def _signature(self, key: tuple[str, ...]) -> tuple[tuple[Any, ...], list[Override]]:
        """((shape, config group options), parsed overrides) of ``key``: its keys in order, and the value of each
        override that chooses a config group (by its shape's reference's groups; None for a value)."""
        known = self._signatures.get(key)
        if known is None:
            parsed = self._parser.parse_overrides(list(key))
            shape = tuple(o.get_key_element() for o in parsed)
            reference = self._references.get(shape)
            choices = self._full(reference[0]).hydra.runtime.choices if reference is not None else {}
            options = tuple(str(o.value()) if o.key_or_group in choices else None for o in parsed)
            known = self._signatures[key] = ((shape, options), parsed)
        return known

    def _override_dirname(self, key: tuple[str, ...], ref_key: tuple[str, ...]) -> str:
        """``hydra.job.override_dirname`` as Hydra's documentation defines it: the job's overrides but the excluded
        keys, sorted, joined by ``item_sep``, each ``=`` written as ``kv_sep``."""
        od = self._full(ref_key).hydra.job.config.override_dirname
        excluded = set(od.exclude_keys)
        lines = sorted(o.input_line or "" for o in self._parse(key) if o.key_or_group not in excluded)
        return str(od.item_sep).join(lines).replace("=", str(od.kv_sep))

    def _delta(self, ref_key: tuple[str, ...], index: int, override: Override) -> dict[str, Any] | None:
        """What choosing ``override``'s option of its group changes against the reference: the top-level nodes
        (outside Hydra's) that differ, or None where it changes anything else of Hydra's node than the choice."""
        group, option = override.key_or_group, str(override.value())
        if (ref_key, group, option) in self._deltas:
            return self._deltas[(ref_key, group, option)]
        reference = self._full(ref_key)
        varied = self._full(_varied_key(ref_key, index, override))
        delta: dict[str, Any] | None = {"group": group, "choice": varied.hydra.runtime.choices.get(group),
                                        "nodes": {}}
        ref_plain = OmegaConf.to_container(reference, resolve=False)
        var_plain = OmegaConf.to_container(varied, resolve=False)
        assert isinstance(ref_plain, dict) and isinstance(var_plain, dict) and delta is not None
        if list(ref_plain) != list(var_plain):  # a node added or dropped: its place in the config could differ
            delta = None
        else:
            for name in var_plain:
                if name != "hydra" and ref_plain[name] != var_plain[name]:
                    delta["nodes"][name] = varied[name]
            if _hydra_without_task(ref_plain["hydra"], group) != _hydra_without_task(var_plain["hydra"], group):
                delta = None
        self._deltas[(ref_key, group, option)] = delta
        return delta


def _differences(parsed: list[Override], ref_parsed: list[Override], choices: Any
                 ) -> tuple[list[tuple[int, Override]], list[Override]] | None:
    """How a job's overrides differ from its reference's (the same keys in the same order), where assembling it is
    the same as composing it: (its config group options that are not the reference's, each with its place among the
    overrides; its value overrides). ``choices``: the reference's ``hydra.runtime.choices`` (its config groups).
    None where it is composed whole: an override that is not plain, a key set twice (Hydra keeps the last; a delta
    is one option at one place), a key of Hydra's own node (Hydra files it under ``hydra.overrides.hydra``, not the
    task's), a group given a non-string value, or a mapping value other than the reference's (key order included:
    filling a null node, Hydra keeps the job's order)."""
    keys = [o.key_or_group for o in parsed]
    if len(set(keys)) != len(keys) or any(k == "hydra" or k.startswith(("hydra.", "hydra/")) for k in keys):
        return None
    groups: list[tuple[int, Override]] = []
    values: list[Override] = []
    for i, (o, r) in enumerate(zip(parsed, ref_parsed, strict=True)):
        if not _plain(o) or not _plain(r):
            return None
        if o.key_or_group in choices:
            if not isinstance(o.value(), str):
                return None
            if o.value() != r.value():
                groups.append((i, o))
        elif isinstance(o.value(), dict) and repr(o.value()) != repr(r.value()):
            # Hydra merges a mapping onto the composed default; here it would merge onto the reference's own
            # mapping (scenario.params={n:4}, then ={max_steps:100}: n stayed 4)
            return None
        else:
            values.append(o)
    return groups, values


def _varied_key(ref_key: tuple[str, ...], index: int, override: Override) -> tuple[str, ...]:
    """The reference's overrides with the one at ``index`` replaced by ``override`` (a group's other option): the
    composition a delta is taken from."""
    varied = list(ref_key)
    varied[index] = override.input_line or f"{override.key_or_group}={override.value()}"
    return tuple(varied)


def _plain(o: Override) -> bool:
    """A ``key=value`` override of one value (no ``+``/``++``/``~``, no ``@package``, not a sweep)."""
    return (o.package is None and not o.is_add() and not o.is_force_add() and not o.is_delete()
            and not o.is_sweep_override())


def _hydra_without_task(hydra: dict[str, Any], group: str) -> dict[str, Any]:
    """Hydra's node without the fields a job's overrides set (and without ``group``'s choice)."""
    out = copy.deepcopy(hydra)
    for parent, field in _TASK_FIELDS:
        node = out.get(parent)
        if isinstance(node, dict):
            if field == "choices":
                choices = node.get(field)
                if isinstance(choices, dict):
                    choices.pop(group, None)
            else:
                node.pop(field, None)
    return out
