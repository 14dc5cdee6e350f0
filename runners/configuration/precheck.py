"""Check the configuration once before Hydra runs, so a bad override or config file is one clear line.

Hydra reports composition errors on several lines; researchers launching thousands of episodes want
``error: config: planner.h_wiat: Key 'h_wiat' not in 'PlannerConfigSchema'`` and a non-zero exit before
anything starts. Three stages, each stopping at the first problem:

1. the scenario and controller files the overrides select are checked as data (:mod:`runners.configuration.data_files`:
   size, tags, aliases, interpolations) before Hydra's YAML loader sees them, since that loader can hang;
2. the config is composed (Hydra: unknown keys, wrong types);
3. the composed config is loaded and validated like a job does (:func:`runners.configuration.run_inputs.load_run`:
ranges,
   the controller, the scenario for the first seed, the launcher's ``n_jobs``).

For a sweep, every value of a swept override is composed once (the other swept keys at their first value), one
per type for numbers, as numbers of one type compose alike. With ``--debug`` or ``HYDRA_FULL_ERROR=1`` the
check is skipped and Hydra's full report is shown.
"""

from __future__ import annotations

import contextlib
import importlib
import inspect
import itertools
import math
import os
import re
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import yaml
from hydra import compose, initialize_config_dir
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import ChoiceSweep, Glob, Override, ValueType
from omegaconf import DictConfig, OmegaConf

from analysis import interrupts
from fuzzynav.conf import CONF_DIR as CONF
from fuzzynav.params.limits import MAX_SWEEP_JOBS
from runners.configuration import hydra_paths, schema
from runners.configuration import plugins as config_plugins
from runners.configuration.data_files import (
    CONFIG_FILE,
    SAFE_LOADER,
    SCENARIO_OR_CONTROLLER,
    DataFileError,
    DataKind,
    check_data_file,
)
from runners.configuration.run_inputs import DATA_GROUPS, ConfigFileError, load_run
from runners.configuration.sweep_size import sweep_size


def _value_kind(value: object) -> object:
    """What composing a value depends on: the type for finite numbers, booleans and null; the value otherwise (nan
    and inf too: among finite values they were never composed, and a sweep ran its jobs until the nan one failed)."""
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
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


def one_line(err: BaseException) -> str:
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
        dirs = [CONF, *(folder for _, folder in config_plugins.plugin_config_dirs())]
        options = sorted({p.stem for d in dirs if (d / group).is_dir() for p in (d / group).glob("*.yaml")})
        hint = f" (available: {', '.join(options)})" if options else ""
        return f"config: no config '{missing.group(1)}'{hint}"
    return f"config: {texts[0].splitlines()[0]}"


def _unavailable_search_path(caught: Sequence[warnings.WarningMessage]) -> str | None:
    """Hydra only warns (on stderr, beside its error) when a ``hydra.searchpath`` entry does not exist."""
    for w in caught:
        found = re.search(r"provider=hydra\.searchpath in command-line, path=(.+) is not available", str(w.message))
        if found:
            return f"config: hydra.searchpath: {found.group(1)[:120]} is not available (no such directory or package)"
    return None


def _search_dirs(parsed: Sequence[Override]) -> list[Path]:
    """Config directories in Hydra's order: ``conf/``, the ``file://`` entries of ``hydra.searchpath``, then other
    packages' config folders (:mod:`runners.configuration.plugins`)."""
    dirs = [CONF]
    for o in parsed:
        if o.get_key_element() == "hydra.searchpath" and isinstance(o.value(), list):
            dirs += [Path(str(p)[len("file://"):]) for p in o.value() if str(p).startswith("file://")]
    return dirs + [folder for _, folder in config_plugins.plugin_config_dirs()]


def _options(value: object, group: str, dirs: Sequence[Path]) -> set[str]:
    """Option names of a group override's value: one, a choice sweep, or a glob over the existing files."""
    if isinstance(value, str):
        return {value}
    if isinstance(value, ChoiceSweep):
        return {str(v) for v in value.list}
    if isinstance(value, Glob):
        names = {p.stem for d in dirs if (d / group).is_dir() for p in (d / group).glob("*.yaml")}
        return set(value.filter(sorted(names)))
    return set()


def _group_of(key: str) -> str:
    """The config group a defaults-list key or group override names (``override /hydra/launcher@x``:
    ``hydra/launcher``)."""
    key = key.strip()
    key = key.removeprefix("override ").strip().lstrip("+~").lstrip("/")
    return key.partition("@")[0]


def _defaults_of(path: Path) -> list[tuple[str, str]]:
    """(group, option) pairs of a config file's defaults list; nothing for a file that does not load (Hydra or
    the check of the file as text reports it)."""
    try:
        loaded = yaml.load(path.read_text(encoding="utf-8"), Loader=SAFE_LOADER)  # checked as text first: bounded
    except Exception:
        return []
    pairs = []
    items = loaded.get("defaults", []) if isinstance(loaded, dict) else []
    for item in items if isinstance(items, list) else []:
        if isinstance(item, dict):
            for key, name in item.items():
                names = name if isinstance(name, list) else [name]
                pairs += [(_group_of(str(key)), str(n)) for n in names if isinstance(n, str)]
    return pairs


def selected_config_files(overrides: Sequence[str]) -> list[Path]:
    """Every YAML file these overrides make Hydra compose: ``config.yaml``, the options its defaults list, the
    command line and the ``hydra.sweeper.params`` of a ``sweep=`` preset select, and those their own defaults
    lists select; each as Hydra would find it, in the first config directory that has it."""
    parser = OverridesParser.create()
    parsed = parser.parse_overrides(list(overrides))
    dirs = _search_dirs(parsed)

    def find(group: str, name: str) -> Path | None:
        return next((d / group / f"{name}.yaml" for d in dirs if (d / group / f"{name}.yaml").is_file()), None)

    wanted: list[tuple[str, str]] = []
    for o in parsed:
        group = _group_of(o.get_key_element())
        if "." not in group and any((d / group).is_dir() for d in dirs):
            wanted += [(group, name) for name in sorted(_options(o.value(), group, dirs))]
    files: list[Path] = [CONF / "config.yaml"]
    queue = [*_defaults_of(CONF / "config.yaml"), *wanted]
    seen: set[tuple[str, str]] = set()
    while queue:
        group, name = queue.pop(0)
        if (group, name) in seen or name in ("null", "None", "_self_"):
            continue
        seen.add((group, name))
        path = find(group, name)
        if path is None:  # a missing option: composing reports it
            continue
        files.append(path)
        queue += _defaults_of(path) if _checked(path) else []
        if group == "sweep":  # a preset's swept groups
            with contextlib.suppress(Exception):
                params = (yaml.load(path.read_text(encoding="utf-8"), Loader=SAFE_LOADER)
                          or {})["hydra"]["sweeper"]["params"]
                for key, value in params.items():
                    sub = _group_of(str(key))
                    if "." not in sub and any((d / sub).is_dir() for d in dirs):
                        (swept,) = parser.parse_overrides([f"{key}={value}"])
                        queue += [(sub, n) for n in sorted(_options(swept.value(), sub, dirs))]
    return list(dict.fromkeys(files))




def _kind(path: Path) -> DataKind:
    return SCENARIO_OR_CONTROLLER if path.parent.name in DATA_GROUPS else CONFIG_FILE


def _checked(path: Path) -> bool:
    """Whether ``path`` passes the text check (only then is it loaded to read its defaults list)."""
    try:
        check_data_file(path, _kind(path))
    except DataFileError:
        return False
    return True


def check_selected_files(overrides: Sequence[str]) -> str | None:
    """Stage 1: the first problem of the selected files as text (scenario and controller files as data, the
    others as config files), or None."""
    try:
        files = selected_config_files(overrides)
    except Exception:  # overrides that do not parse: composing them reports it
        return None
    for path in files:
        try:
            check_data_file(path, _kind(path))
        except DataFileError as err:
            return str(err)
    return None


def check_callbacks(cfg: DictConfig) -> tuple[str, str] | None:
    """The first ``hydra.callbacks`` entry Hydra could not instantiate (a target that does not import, a key its
    class does not take) as (its key, the problem), or None: Hydra reported it on five lines (``Error in call to
    target ...``)."""
    callbacks = cfg.hydra.get("callbacks") if "hydra" in cfg else None
    for name, spec in (callbacks or {}).items():
        key = f"hydra.callbacks.{name}"
        if not isinstance(spec, DictConfig) or not isinstance(spec.get("_target_"), str):
            return key, "expected a mapping with a _target_"
        try:
            target = _locate(spec["_target_"])
        except Exception as err:
            return f"{key}._target_", f"cannot import {spec['_target_'][:80]!r} ({type(err).__name__})"
        try:
            inspect.signature(target).bind(**{str(k): None for k in spec if not str(k).startswith("_")})
        except TypeError as err:
            return key, str(err)
        except ValueError:  # a callable without a signature: Hydra's to try
            continue
    return None


def check_plugins(cfg: DictConfig) -> tuple[str, str] | None:
    """The sweeper's or launcher's settings that its class does not take (``+hydra.launcher.bogus=1``) as (its key,
    the problem), or None: Hydra reported them on several lines once the sweep had started."""
    for key in ("hydra.launcher", "hydra.sweeper"):
        spec = OmegaConf.select(cfg, key, default=None)
        if not isinstance(spec, DictConfig) or not isinstance(spec.get("_target_"), str):
            continue
        try:
            target = _locate(spec["_target_"])
            inspect.signature(target).bind(**{str(k): None for k in spec if not str(k).startswith("_")})
        except TypeError as err:
            return key, str(err)
        except Exception:  # a target that does not import or has no signature: Hydra's to report
            continue
    return None


def file_setting(overrides: Sequence[str], key: str) -> Path | None:
    """The last of the files the overrides compose that sets the dotted ``key`` at its top level (a ``_global_``
    file: sweep presets, ``config.yaml``), or None."""
    found = None
    with contextlib.suppress(Exception):
        for path in selected_config_files(overrides):
            node: Any = yaml.load(path.read_text(encoding="utf-8"), Loader=SAFE_LOADER)  # checked as text: bounded
            *parents, last = key.split(".")
            for part in parents:
                node = node.get(part) if isinstance(node, dict) else None
            if isinstance(node, dict) and last in node:
                found = path
    return found


def _locate(path: str) -> Any:
    """The object a dotted path names (a module, then attributes), as Hydra's ``_target_`` does, without Hydra's
    logging of a failure on stderr."""
    parts = path.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            obj = getattr(obj, attr)
        return obj
    raise ImportError(path)


def check_composed(cfg: DictConfig) -> str | None:
    """Stage 3: load and validate a composed config (with Hydra's node) as a job would, or say why not."""
    try:
        load_run(cfg, cfg.hydra.runtime if "hydra" in cfg else None, all_seeds=False)
    except ConfigFileError as err:
        return str(err)
    except ValueError as err:
        return f"config: {err}"
    return None


def _unreadable(parser: OverridesParser, overrides: list[str], err: Exception) -> str:
    """The first override that does not parse, named with its key (Hydra's message names neither: ``planner=auto,``
    was ``mismatched input '<EOF>' expecting ...``)."""
    for text in overrides:
        try:
            parser.parse_overrides([text])
        except Exception as one:
            key = text.partition("=")[0] or text
            return f"config: {key[:80]}: cannot read {text[:80]!r}: {str(one).splitlines()[0]}"
    return f"config: cannot read the overrides: {str(err).splitlines()[0]}"


def _new_top_level_key(added: Sequence[Override], overrides: list[str], primary: str) -> str | None:
    """One line for the first ``+key=value`` that adds a top-level key the run's config does not have (nothing
    reads it: ``+episode=5`` ran one episode, and the log recorded ``episode: 5``), or None."""
    import difflib

    without = [t for t in overrides if t not in {o.input_line for o in added}]
    try:
        known = set(compose(primary, overrides=without))
    except Exception:  # the config without them does not compose: composing with them reported it
        return None
    for o in added:
        key = o.key_or_group
        if key not in known:
            close = difflib.get_close_matches(key, sorted(known), n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            return (f"config: {key[:80]}: no such setting{hint}; '+' adds a key the run does not read "
                    "(settings: python -m runners.run --cfg job)")
    return None


def _numeric_ends(values: list[str]) -> list[str]:
    """The smallest and the largest of ``key=value`` overrides whose values are all numbers (none otherwise)."""
    numbers = []
    for text in values:
        raw = text.partition("=")[2]
        try:
            numbers.append((float(raw), text))
        except ValueError:
            return []
    if len(numbers) < 2:
        return []
    return list(dict.fromkeys([min(numbers)[1], max(numbers)[1]]))


def _in_one_job(problem: str, job: list[str], base: list[str], swept: set[str]) -> str:
    """``problem`` of one job of a sweep, said as such where a plain override sets a key that
    only some options of a swept group have (``navigator=custom,dwa navigator._target_=my.Policy``: Hydra said
    "Key '_target_' is not in struct")."""
    found = re.match(r"config: ([\w.]+): Key '[^']+' is not in struct", problem)
    if not found:
        return problem
    key = found.group(1)
    group = key.split(".")[0]
    if group not in swept:
        return problem
    choice = next((t for t in job if t not in base and t.partition("=")[0].lstrip("+") == group), None)
    if choice is None:
        return problem
    text = (f"config: {key}: the override applies to every job of the sweep, and {choice} has no such key")
    if key == f"{group}._target_":
        target = next((t.partition("=")[2] for t in base if t.partition("=")[0].lstrip("+") == key), "my.Policy")
        return (f"{text}: give your policy its own {group} option (my_conf/{group}/mine.yaml holding "
                f"'_target_: {target[:80]}', with hydra.searchpath=[file://$PWD/my_conf]) and sweep "
                f"{group}=mine,{choice.partition('=')[2]} (docs/tutorials/policy.md, section 2)")
    return f"{text}: sweep the options that have it in a sweep of their own, or give each its own {group} YAML"


def _base_problem(base: list[str], swept: set[str], primary: str) -> str | None:
    """Hydra composes a sweep's own config with the command line's plain overrides and every swept group at its
    default (``scenario=a,b scenario.params.n=4`` sets ``params`` in the default scenario, which has none): one
    line, with the override that adds or sets a key wherever it applies (``++``)."""
    try:
        compose(primary, overrides=base)
    except Exception as err:
        interrupt = interrupts.interrupt_in_chain(err)
        if interrupt is not None:
            raise interrupt from None
        culprits = [t for t in base if "." in (key := t.lstrip("+~").partition("=")[0]) and key.split(".")[0] in swept]
        hint = (f"; write ++{culprits[0].lstrip('+')} to set it in every job where it applies" if culprits else "")
        return f"{one_line(err)} (the sweep's own config, with each swept group at its default){hint}"
    return None


def precheck(args: list[str], on_config: Callable[[DictConfig], None] | None = None,
             multirun: bool = False, config_dir: str | None = None, config_name: str | None = None) -> str | None:
    """One-line description of why these command-line overrides cannot be composed, or None.

    ``on_config`` is called with the first composed config, Hydra's node included (the sweep uses it to start
    its worker processes while the rest is checked and Hydra starts). ``config_dir``, ``config_name``: the command
    line's ``--config-dir`` (its configs are composed from there too: ``scenario=mine`` of a user's folder was
    refused as no config) and ``--config-name``."""
    primary = (config_name or "config").removesuffix(".yaml")
    if not (CONF / f"{primary}.yaml").is_file():  # a primary config of the user's folder: checked against ours
        primary = "config"
    if config_dir is not None and not any(a.lstrip("+").startswith("hydra.searchpath=") for a in args):
        # after conf/ where Hydra puts it before: the same configs, but for one of the same name in both
        args = [f"hydra.searchpath=[file://{Path(config_dir).expanduser().resolve()}]", *args]
    try:  # other packages' config folders: a broken entry point is one line here, not a traceback inside Hydra
        config_plugins.plugin_config_dirs()
    except config_plugins.PluginConfigError as err:
        return f"config: {err}"
    overrides = [a for a in args if not a.startswith("-")]
    parser = OverridesParser.create()
    try:
        parsed = parser.parse_overrides(overrides)
    except Exception as err:
        return _unreadable(parser, overrides, err)
    base, variants = [], []
    jobs = 1  # of the command line's sweeps (the preset's own are counted by the sweeper)
    for o in parsed:
        if o.is_delete() and "." not in o.key_or_group and any((d / o.key_or_group).is_dir()
                                                                for d in _search_dirs(parsed)):
            # Hydra then composes the group's default, whatever else the command line chose (~planner planner=wait
            # ran auto): every run needs one option of each group
            return (f"config: {o.input_line[:80]}: deletes the choice of the config group {o.key_or_group!r}, which a "
                    f"run needs; choose an option instead ({o.key_or_group}=<name>)")
        swept = o.key_or_group.removeprefix("hydra.sweeper.params.")
        if swept != o.key_or_group and "." in swept:  # Hydra nests it ({planner: {h_wait: ...}}): 4 lines of grammar
            value = o.input_line.partition("=")[2].strip("'\"")
            return (f"config: {o.key_or_group[:80]}: a swept setting with dots cannot be added to the preset's params "
                    f"on the command line; sweep it directly: {swept[:60]}={value[:60]}")
        if not o.is_sweep_override():
            base.append(o.input_line)
            continue
        if o.key_or_group.startswith("hydra.") or o.key_or_group.startswith("hydra/"):
            return (f"config: {o.key_or_group[:80]}: Hydra's own settings cannot be swept (one value per sweep: run "
                    "one sweep per value)")
        if o.value_type == ValueType.GLOB_CHOICE_SWEEP:  # globs only select existing options ...
            if not _options(o.value(), o.key_or_group, _search_dirs(parsed)):  # ... but may select none
                return (f"config: {o.get_key_element()}: {o.input_line.partition('=')[2][:60]} selects no option "
                        "(an empty sweep)")
            continue
        if o.value_type == ValueType.INTERVAL_SWEEP:  # Hydra's basic sweeper cannot list it: a traceback later
            return (f"config: {o.get_key_element()}: {o.input_line.partition('=')[2][:60]} is a continuous range "
                    "(for an optimiser's sweeper); a sweep runs listed values: a list (0.5,0.75,1) or range()")
        size = sweep_size(o)
        if size is None:  # range(0,4,0)
            return (f"config: {o.get_key_element()}: {o.input_line.partition('=')[2][:60]} cannot be listed (a "
                    "range's step must be a finite number other than 0)")
        if size == 0:  # range(5,0): a sweep of no job, exit 0
            return f"config: {o.get_key_element()}: {o.input_line.partition('=')[2]} selects no value (an empty sweep)"
        jobs *= size
        if jobs > MAX_SWEEP_JOBS:
            return (f"config: {o.get_key_element()}: {o.input_line.partition('=')[2][:60]}: the sweep has more than "
                    f"{MAX_SWEEP_JOBS:,} jobs; batch seeds into longer jobs (episodes=K seed='range(0,N,K)')")
        if o.value_type == ValueType.RANGE_SWEEP:  # numbers of one type: the first stands for all (not listed)
            values = list(itertools.islice(o.sweep_string_iterator(), 1))
        else:
            values = list(o.sweep_string_iterator())
        prefix = "+" if o.is_add() else ""
        variants.append([f"{prefix}{o.get_key_element()}={v}" for v in values])
    firsts = [v[0] for v in variants if v]
    trials = [base + firsts]
    for i, values in enumerate(variants):  # every other value of each swept key, the rest at their first value
        for value in values[1:]:
            trials.append([*base, *firsts[:i], value, *firsts[i + 1:]])
    with contextlib.suppress(Exception):  # an override that does not parse: composing it below reports it
        trials = representative_jobs(trials)  # one value of each kind per key is enough to compose ...
    for i, values in enumerate(variants):  # ... but a range is checked at its ends (n=0,2000: 2000 > the limit)
        for value in _numeric_ends(values):
            trial = [*base, *firsts[:i], value, *firsts[i + 1:]]
            if trial not in trials:
                trials.append(trial)
    swept_keys = {o.get_key_element() for o in parsed if o.is_sweep_override()}
    problem = check_selected_files(overrides)
    if problem:
        return problem
    added = [o for o in parsed if (o.is_add() or o.is_force_add()) and "." not in o.key_or_group
             and not any((d / o.key_or_group).is_dir() for d in _search_dirs(parsed))]
    schema.register()
    config_plugins.register()  # other packages' config folders (entry points)
    # job_name: hydra.job.name as Hydra gives it to runners.run's jobs (the task function's file, run.py): a single
    # run is run from the config composed here (runners.run.run_composed)
    sweep_dirs: dict[str, list[str]] = {}  # a sweep's folder, resolved for each job composed: one in all
    first: DictConfig | None = None
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3", job_name="run"):
        for k, overrides in enumerate(trials):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    cfg = compose(primary, overrides=overrides, return_hydra_config=True)
                except Exception as err:
                    interrupt = interrupts.interrupt_in_chain(err)
                    if interrupt is not None:  # a signal inside OmegaConf's clean-up: not a config problem
                        raise interrupt from None
                    cfg, problem = None, one_line(err)
                    problem = _in_one_job(problem, overrides, base, swept_keys)
            unavailable = _unavailable_search_path(caught)
            if unavailable:  # a typo in hydra.searchpath: the config it should have provided is "missing"
                return unavailable
            if cfg is None:
                return problem
            plugin = check_plugins(cfg)
            if plugin:
                return f"config: {plugin[0]}: {plugin[1]}"
            callback = check_callbacks(cfg)
            if callback:
                where = file_setting(overrides, callback[0].removesuffix("._target_"))
                return f"{where if where else 'config'}: {callback[0]}: {callback[1]}"
            problem = check_composed(cfg) or hydra_paths.run_paths_problem(cfg)
            if problem:
                return problem
            if multirun:
                if first is None:
                    first = cfg
                else:  # ${now:...} as the first resolved it (the sweeper gives every job the sweep's cache)
                    OmegaConf.copy_cache(from_config=first, to_config=cfg)
                paths = hydra_paths.sweep_paths(cfg)
                if isinstance(paths, str):
                    return paths
                sweep_dirs.setdefault(paths[0], overrides)
            if k == 0 and added:
                problem = _new_top_level_key(added, overrides, primary)
                if problem:
                    return problem
            if k == 0 and on_config is not None:
                on_config(cfg)
        problem = hydra_paths.one_sweep_dir(sweep_dirs)
        if problem:
            return problem
        if multirun and variants:
            problem = _base_problem(base, {o.get_key_element() for o in parsed if o.is_sweep_override()}, primary)
            if problem:
                return problem
    return None
