"""The launcher's job configs (runners/configuration/job_configs.py): every assembled config is the config Hydra
composes for the same overrides, to the last character of its YAML (Hydra's node included), over the sweep
presets and random products of the config groups' options and values."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from fuzzynav.conf import CONF_DIR
from runners.configuration import schema
from runners.configuration.job_configs import JobConfigs

CONF = Path(CONF_DIR)


def _options(group: str) -> list[str]:
    return sorted(p.stem for p in (CONF / group).glob("*.yaml"))


@pytest.fixture(scope="module")
def hydra_loader():
    schema.register()
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        master = compose("config", overrides=["sweep=default"], return_hydra_config=True)
        loader = GlobalHydra.instance().config_loader()
        cache: dict[tuple[str, ...], object] = {}

        def composed(overrides: list[str]):
            key = tuple(overrides)
            if key not in cache:
                cache[key] = loader.load_sweep_config(master, list(overrides))
            return cache[key]

        yield master, composed


def _yaml(config) -> str:
    return OmegaConf.to_yaml(config)


def _check(master, composed, jobs: list[list[str]]) -> JobConfigs:
    """Each job's config from a fresh JobConfigs (composing through a counting wrapper) against Hydra's."""
    calls: list[tuple[str, ...]] = []

    def compose_job(overrides: list[str]):
        config = composed(overrides)
        calls.append(tuple(overrides))  # composed without an error
        return config

    configs = JobConfigs(master, compose_job)
    for job in jobs:
        try:
            expected = _yaml(composed(job))
        except Exception:  # Hydra refuses the job: so must JobConfigs (it composes it, and Hydra raises)
            with pytest.raises(Exception):  # noqa: B017
                configs.config(job)
            continue
        got = configs.config(job)
        assert _yaml(got) == expected, job
        got.seed = 12345  # a job's config is its own: changing it changes no other job's
    assert configs.composed == len(set(calls))
    return configs


def test_the_default_sweep_composes_one_config_per_swept_value(hydra_loader):
    master, composed = hydra_loader
    scenarios = ["paper_fig5", "head_on", "cyclist_crossing"]
    planners = ["auto_h1", "auto_h2", "auto_h3", "auto_h4", "wait", "detour", "none"]
    jobs = [[f"scenario={s}", f"planner={p}"] for s, p in itertools.product(scenarios, planners)]
    configs = _check(master, composed, jobs)
    assert configs.composed == 1 + 2 + 6  # the first job, the other scenarios, the other planners
    assert configs.assembled == len(jobs) - 1  # the varied ones too, once their option's delta is known


def test_configs_the_sweepers_check_composed_are_not_composed_again(hydra_loader):
    master, composed = hydra_loader
    jobs = [[f"scenario={s}", f"planner={p}"] for s in ("head_on", "corridor") for p in ("wait", "detour", "none")]
    calls: list[tuple[str, ...]] = []
    configs = JobConfigs(master, lambda overrides: calls.append(tuple(overrides)) or composed(overrides))
    for job in (jobs[0], jobs[1], jobs[2], jobs[3]):  # the sweeper's representatives: one per swept value
        configs.add_composed(job, composed(job))
    assert [_yaml(configs.config(job)) for job in jobs] == [_yaml(composed(job)) for job in jobs]
    assert calls == [] and configs.assembled == 2


def test_configs_composed_in_workers_travel_as_bytes_and_are_unpickled_only_where_used(hydra_loader):
    # the sweeper's check composes in the workers and hands the launching process pickled configs: the launching
    # process sets the reference and pickles the launch's state without unpickling any; a worker assembles from them
    import pickle

    import cloudpickle

    master, composed = hydra_loader
    jobs = [[f"scenario={s}", f"planner={p}"] for s in ("head_on", "corridor") for p in ("wait", "detour", "none")]
    calls: list[tuple[str, ...]] = []
    parent = JobConfigs(master, lambda overrides: calls.append(tuple(overrides)) or composed(overrides))
    for job in (jobs[0], jobs[1], jobs[2], jobs[3]):
        parent.add_composed(job, cloudpickle.dumps(composed(job)))
    parent.config(jobs[0])  # the launcher's reference
    assert parent._composed == {}  # nothing unpickled in the launching process
    worker = pickle.loads(cloudpickle.dumps(parent))
    assert [_yaml(worker.config(job)) for job in jobs] == [_yaml(composed(job)) for job in jobs]
    assert calls == [] and worker.assembled == 2 and worker.composed == 0


def test_to_compose_lists_what_assembly_needs_and_nothing_is_composed_after(hydra_loader):
    # a dataset's verification: the reference and each other scenario's and variant's config are composed up front
    # (in parallel, elsewhere); then no job, whatever its seed, is composed again
    master, composed = hydra_loader
    jobs = [[f"scenario={s}", f"planner={p}", f"seed={k}"] for s in ("head_on", "corridor", "doorway")
            for p in ("auto", "wait", "none") for k in (0, 3)]
    calls: list[tuple[str, ...]] = []
    configs = JobConfigs(master, lambda overrides: calls.append(tuple(overrides)) or composed(overrides))
    needed = configs.to_compose(jobs)
    assert calls == [tuple(jobs[0])]  # the reference, to tell config groups from values
    assert needed == [("scenario=head_on", "planner=wait", "seed=0"), ("scenario=head_on", "planner=none", "seed=0"),
                      ("scenario=corridor", "planner=auto", "seed=0"), ("scenario=doorway", "planner=auto", "seed=0")]
    for key in needed:
        configs.add_composed(key, composed(list(key)))
    assert configs.to_compose(jobs) == []
    assert [_yaml(configs.config(job)) for job in jobs] == [_yaml(composed(job)) for job in jobs]
    assert calls == [tuple(jobs[0])] and configs.assembled == len(jobs) - 1 - len(needed)
    # jobs whose overrides set other keys have their own reference (listed; composed here when it comes first, as
    # it tells groups from values), and their own options' deltas
    other = [["scenario=corridor", "planner=auto", "navigator=dwa", "seed=0"],
             ["scenario=head_on", "planner=auto", "navigator=dwa", "seed=3"]]
    assert configs.to_compose([jobs[0], *other]) == [tuple(other[0]), ("scenario=head_on", "planner=auto",
                                                                       "navigator=dwa", "seed=0")]


def test_variants_that_set_other_keys_have_their_own_reference(hydra_loader):
    # a dataset's manifest (suite_v3): a variant of one override beside variants of two; each shape of overrides is
    # assembled from its own first job, not composed whole
    master, composed = hydra_loader
    variants = [["navigator=dwa"], ["navigator=fuzzy_tpt", "planner=auto_h4"], ["navigator=apf"],
                ["navigator=fuzzy_tpt", "planner=auto_h2"]]
    jobs = [[f"scenario={s}", *v, f"seed={k}"] for s in ("head_on", "corridor", "crowd_crossing") for v in variants
            for k in (0, 1)]
    configs = _check(master, composed, jobs)
    # two references, their other scenarios (2 each), navigator=apf and planner=auto_h2
    assert configs.composed == 2 + 2 * 2 + 1 + 1 and configs.assembled == len(jobs) - 2


def test_to_compose_lists_only_what_an_assembled_job_uses(hydra_loader):
    # a job composed whole where it runs (a mapping value other than the reference's; an override that is not
    # plain) needs no delta: listing its group's option would compose a config that no job uses
    master, composed = hydra_loader
    jobs = [["scenario=crowd_crossing", "scenario.params={n:4}"],
            ["scenario=random_walkers", "scenario.params={max_steps:100}"],
            ["scenario=corridor_flow", "scenario.params={n:4}"]]
    configs = JobConfigs(master, composed)
    assert configs.to_compose(jobs) == [("scenario=corridor_flow", "scenario.params={n:4}")]
    odd = ["+scenario.extra=1", "scenario.params={n:4}"]  # a shape of its own, composed whole: no delta
    assert configs.to_compose([*jobs, odd]) == [("scenario=corridor_flow", "scenario.params={n:4}"), tuple(odd)]
    # what is listed is exactly what the jobs' assembly then composes
    calls: list[tuple[str, ...]] = []
    configs = JobConfigs(master, lambda overrides: calls.append(tuple(overrides)) or composed(overrides))
    needed = configs.to_compose(jobs)
    assert [_yaml(configs.config(job)) for job in jobs] == [_yaml(composed(job)) for job in jobs]
    assert set(needed) <= set(calls) and configs.assembled == 1


def test_seeds_and_numbers_are_applied_without_composing(hydra_loader):
    master, composed = hydra_loader
    jobs = [[f"seed={s}", f"planner.safety_margin_cm={m}", "episodes=3"] for s in range(0, 100, 10)
            for m in (5, 15.5)]
    configs = _check(master, composed, jobs)
    assert configs.composed == 1 and configs.assembled == len(jobs) - 1


def test_every_policy_with_its_own_planner_default(hydra_loader):
    """Navigator options choose other groups' options (their planner): composed where assembling could differ."""
    master, composed = hydra_loader
    jobs = [[f"navigator={n}", f"scenario={s}"] for n in _options("navigator") if n != "custom"
            for s in ("head_on", "crowd_crossing", "corridor")]
    _check(master, composed, jobs)


def test_an_option_that_is_not_separable_is_composed_once_then_its_seeds_assembled(hydra_loader):
    """A navigator chooses its planner too (its delta is more than its own nodes): its first job is composed, and
    jobs with the same options that differ in plain values are made from that one. A mapping value other than the
    composed job's is composed (merged onto the other's, it would keep that one's keys)."""
    master, composed = hydra_loader
    jobs = [[f"navigator={n}", f"scenario={s}", f"seed={k}"] for n in ("fuzzy_tpt", "dwa", "orca")
            for s in ("head_on", "corridor") for k in (0, 1, 2)]
    configs = _check(master, composed, jobs)
    # the reference, corridor's delta, the first job of each other navigator and scenario; the rest assembled
    assert configs.composed == 1 + 1 + 2 * 2 and configs.assembled == len(jobs) - 1 - 2 * 2
    crowd = [["navigator=fuzzy_tpt", "scenario=crowd_crossing", "scenario.params={n:4}", "seed=0"],
             ["navigator=dwa", "scenario=crowd_crossing", "scenario.params={n:4}", "seed=0"],
             ["navigator=dwa", "scenario=crowd_crossing", "scenario.params={n:4}", "seed=1"],
             ["navigator=dwa", "scenario=crowd_crossing", "scenario.params={max_steps:9}", "seed=2"]]
    configs = _check(master, composed, crowd)
    assert configs.composed == 3 and configs.assembled == 1


def test_a_key_set_twice_and_keys_of_hydras_node_are_composed(hydra_loader):
    """Found by a hostile test: the delta of a group set twice was taken for the wrong place (Hydra keeps the last:
    [planner=auto, planner=wait] came out auto), and a ``hydra.*`` key was filed under the task's overrides and in
    the folder name (Hydra files it under hydra.overrides.hydra)."""
    master, composed = hydra_loader
    twice = [["planner=auto", "planner=auto"], ["planner=wait", "planner=auto"], ["planner=auto", "planner=wait"],
             ["scenario=head_on", "scenario=corridor"], ["scenario=corridor", "scenario=head_on"]]
    _check(master, composed, twice)
    hydra_keys = [["seed=0", "hydra.job.chdir=false"], ["seed=1", "hydra.job.chdir=true"],
                  ["seed=2", "hydra.job.chdir=false"]]
    assert _check(master, composed, hydra_keys).assembled == 0


def test_a_mapping_in_another_key_order_is_composed():
    """Filling a null node, Hydra keeps the job's key order (and the config's text, hence its hash, follows it):
    {start, goal} and {goal, start} are not the same override."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from runners.configuration.job_configs import _differences

    parse = OverridesParser.create().parse_overrides
    a = parse(["scenario.robot={start: [100, 250], goal: [1100, 250]}"])
    b = parse(["scenario.robot={goal: [1100, 250], start: [100, 250]}"])
    assert _differences(a, a, {}) == ([], a)
    assert _differences(b, a, {}) is None


GROUPS = {g: _options(g) for g in ("scenario", "planner", "controller", "perception", "robot")}
GROUPS["navigator"] = [n for n in _options("navigator") if n != "custom"]  # (custom needs a policy of the user's)
VALUES = {"seed": st.integers(0, 10**6), "episodes": st.integers(1, 9),
          "planner.safety_margin_cm": st.floats(0, 50, allow_nan=False).map(lambda x: round(x, 3)),
          "planner.h_wait": st.integers(0, 6), "dt": st.sampled_from([0.5, 1.0, 1]),
          "terminate_on_collision": st.booleans(), "robot.v_max": st.floats(20, 60).map(lambda x: round(x, 1)),
          # a mapping: Hydra merges it onto the composed default
          "scenario.robot": st.sampled_from(["{start: [100, 250]}", "{goal: [1100, 250]}", "{radius: 25}"])}


@st.composite
def sweeps(draw):
    """A product of 1-3 swept keys (groups and values) with 1-3 values each, in a random key order."""
    keys = draw(st.lists(st.sampled_from([*GROUPS, *VALUES]), min_size=1, max_size=3, unique=True))
    swept = []
    for key in keys:
        pool = st.sampled_from(GROUPS[key]) if key in GROUPS else VALUES[key]
        swept.append([f"{key}={v}" for v in draw(st.lists(pool, min_size=1, max_size=3, unique=True))])
    return [list(job) for job in itertools.product(*swept)]


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(jobs=sweeps())
def test_random_sweeps_are_assembled_as_hydra_composes_them(hydra_loader, jobs):
    master, composed = hydra_loader
    _check(master, composed, jobs)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(parts=st.lists(sweeps(), min_size=2, max_size=3), order=st.randoms(use_true_random=False))
def test_jobs_of_several_shapes_in_any_order_are_assembled_as_hydra_composes_them(hydra_loader, parts, order):
    """A manifest's episodes: products over different keys, mixed (each shape has its own reference)."""
    master, composed = hydra_loader
    jobs = [job for part in parts for job in part]
    order.shuffle(jobs)
    configs = JobConfigs(master, composed)
    needed = configs.to_compose(jobs)
    assert len(needed) == len(set(needed))
    _check(master, composed, jobs)


def test_a_mapping_value_is_merged_onto_the_default_not_onto_another_jobs_mapping(hydra_loader):
    """Found by a hostile test of dataset verification: variants scenario.params={n:4} and ={max_steps:100} were
    assembled with n=4 in both (merged onto the first job's mapping), where Hydra gives the second the default n."""
    master, composed = hydra_loader
    jobs = [["scenario=crowd_crossing", "scenario.params={n:4}"],
            ["scenario=crowd_crossing", "scenario.params={max_steps:100}"],
            ["scenario=head_on", "scenario.robot={start: [100, 250]}"],
            ["scenario=head_on", "scenario.robot={goal: [1100, 250]}"]]
    _check(master, composed, jobs[:2])
    _check(master, composed, jobs[2:])
    configs = _check(master, composed, [jobs[2], ["scenario=corridor", "scenario.robot={start: [100, 250]}"]])
    assert configs.assembled == 1  # the reference's own mapping: merged again onto its own, the same


def test_overrides_of_another_form_are_composed(hydra_loader):
    master, composed = hydra_loader
    jobs = [["scenario=head_on", "+extra=1"], ["scenario=corridor", "+extra=2"], ["scenario=head_on", "~resume"],
            ["scenario=corridor", "~resume"], ["scenario=head_on", "planner.no_such_key=3"]]
    configs = _check(master, composed, jobs[:2])
    assert configs.assembled == 0
    _check(master, composed, jobs[2:])
