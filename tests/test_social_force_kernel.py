"""The compiled social-force kernel (fuzzynav/pedestrians/_social_force.c) gives the numpy path's bits: one substep's
forces
on random crowds and worlds (coincident points, zero velocities, pedestrians on walls and at circle centres,
huge and tiny distances), its exp on the whole range, and whole crowd episodes with and without it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import fuzzynav.pedestrians.social_force as sf
from fuzzynav.numerics import compiled
from fuzzynav.numerics.portable_math import exp_array, sin_cos_deg
from tests.conftest import require_compiled

require_compiled(compiled.load("fuzzynav.pedestrians._social_force"), "_social_force")


def assert_same_bits(got: np.ndarray, want: np.ndarray) -> None:
    """Bitwise equality (``==`` would equate -0.0 and 0.0, and never NaN with NaN)."""
    assert got.shape == want.shape and got.dtype == want.dtype == np.float64
    bad = np.flatnonzero(got.view(np.int64).ravel() != want.view(np.int64).ravel())
    assert bad.size == 0, f"{bad.size} values differ, first at {bad[0]}: {got.ravel()[bad[0]]!r} vs " \
                          f"{want.ravel()[bad[0]]!r}"


def kernel_exp(x: np.ndarray) -> np.ndarray:
    out = np.empty_like(x)
    sf._kernel.exp(x, out)
    return out


def test_exp_same_bits_as_exp_array() -> None:
    """Every branch of exp: NaN, ±inf, the cut-offs at -746 and 710, the subnormal results below -708 (where
    ldexp rounds), signed zeros and exact ties of x / ln 2's rounding; plus random values and random bit
    patterns."""
    rng = np.random.default_rng(0)
    ln2 = math.log(2.0)
    special = [math.nan, -math.nan, math.inf, -math.inf, 0.0, -0.0, 5e-324, -5e-324, 1e-300, -1e-300, -746.0,
               np.nextafter(-746.0, 0.0), -745.2, -745.1, -740.0, -709.0, -708.5, -708.0, np.nextafter(-708.0, -1.0),
               709.0, np.nextafter(709.0, 710.0), 709.7, 709.8, 710.0, np.nextafter(710.0, 711.0), 0.5 * ln2,
               -0.5 * ln2, 1.5 * ln2, -2.5 * ln2, 1e-20, -1e-20]
    x = np.concatenate([np.array(special), rng.uniform(-800.0, 800.0, 20_000), rng.uniform(-1.0, 1.0, 5_000),
                        -rng.exponential(30.0, 5_000), rng.integers(0, 2**64, 20_000, dtype=np.uint64).view(float)])
    with np.errstate(all="ignore"):
        want = exp_array(x)
    assert_same_bits(kernel_exp(x), want)


CONFIG_FIELDS = {  # each field's valid range (SocialForceConfig.__post_init__)
    "relaxation_s": (0.01, 60.0), "agent_strength_cm2_s2": (0.0, 1e9), "agent_range_cm": (1.0, 10_000.0),
    "step_time_s": (0.0, 60.0), "wall_strength_cm2_s2": (0.0, 1e9), "wall_range_cm": (1.0, 10_000.0),
    "fov_deg": (0.0, 180.0), "fov_weight": (0.0, 1.0),
}


@st.composite
def configs(draw: st.DrawFn) -> sf.SocialForceConfig:
    """The paper's defaults, or random valid values (bounds included; integers too, as YAML gives them); either
    reading of the step ahead."""
    step_ahead = draw(st.sampled_from(sf.STEP_AHEAD))
    if draw(st.booleans()):
        return sf.SocialForceConfig(step_ahead=step_ahead)
    values = {}
    for name, (lo, hi) in CONFIG_FIELDS.items():
        values[name] = draw(st.one_of(st.sampled_from([lo, hi]), st.floats(lo, hi),
                                      st.integers(math.ceil(lo), math.floor(hi))))
    return sf.SocialForceConfig(**values, step_ahead=step_ahead)


def messy(lo: float, hi: float) -> st.SearchStrategy[float]:
    """Floats in [lo, hi] with all 53 bits used (Hypothesis prefers short ones such as 2.5, whose sums are
    exact: they would hide a change in the order of operations)."""
    return st.integers(0, 2**53).map(lambda k: lo + (hi - lo) * (k / 2**53))


@st.composite
def coordinates(draw: st.DrawFn, scale: float) -> float:
    """A coordinate (cm) or velocity component (cm/s): usually within ±scale, sometimes 0, ±0.0, tiny
    (subnormal) or huge (1e100: far enough that nothing overflows)."""
    return draw(st.one_of(st.floats(-scale, scale), messy(-scale, scale), messy(-scale, scale),
                          st.sampled_from([0.0, -0.0, 5e-324, -1e-310, 1e-200, 1e100, -1e100, 3e99]),
                          st.floats(-1e100, 1e100)))


def points(draw: st.DrawFn, count: int, scale: float, pool: list[tuple[float, float]]) -> np.ndarray:
    """``count`` (x, y) rows; some copied from ``pool`` (positions that already exist: coincident points)."""
    rows = []
    for _ in range(count):
        if pool and draw(st.integers(0, 3)) == 0:
            rows.append(draw(st.sampled_from(pool)))
        else:
            rows.append((draw(coordinates(scale)), draw(coordinates(scale))))
    return np.array(rows, dtype=float).reshape(-1, 2)


@st.composite
def substep_inputs(draw: st.DrawFn) -> tuple:
    """The arguments of one substep's force: a group of n pedestrians and k other obstacles, walls (some of
    zero length) and circles, with pedestrians on a wall, at a circle's centre, at another's position, or
    standing."""
    scale = draw(st.sampled_from([1e3, 1e3, 1e6, 1e-3]))
    segments = np.array([[draw(coordinates(scale)) for _ in range(4)]
                         for _ in range(draw(st.integers(0, 5)))], dtype=float).reshape(-1, 4)
    if len(segments) and draw(st.booleans()):
        segments[0, 2:] = segments[0, :2]  # a zero-length wall
    circles = np.array([[draw(coordinates(scale)), draw(coordinates(scale)),
                         draw(st.one_of(st.just(0.0), st.floats(0.0, 300.0), messy(0.0, 300.0)))]
                        for _ in range(draw(st.integers(0, 4)))], dtype=float).reshape(-1, 3)
    # places a pedestrian can stand: wall ends, points along walls, circle centres, an axis-aligned wall's
    # exact inner point
    pool = [tuple(p) for p in segments[:, :2]] + [tuple(p) for p in segments[:, 2:]]
    pool += [tuple(p) for p in circles[:, :2]]
    for a, b in zip(segments[:, :2], segments[:, 2:], strict=True):
        t = draw(st.floats(0.0, 1.0))
        pool.append(tuple(a + t * (b - a)))
    pool.append((37.0, 0.0))
    # and places within the walls' and circles' reach (their forces are then not negligible in the sum)
    for cx, cy, rc in circles:
        pool.append((cx + rc + draw(messy(-50.0, 50.0)), cy + draw(messy(-50.0, 50.0))))
    for x0, y0, x1, y1 in segments:
        pool.append((0.5 * (x0 + x1) + draw(messy(-50.0, 50.0)), 0.5 * (y0 + y1) + draw(messy(-50.0, 50.0))))
    segments = np.vstack([segments, [[0.0, 0.0, 100.0, 0.0]]]) if draw(st.booleans()) else segments
    n = draw(st.integers(1, 25))
    x = points(draw, n, scale, pool)
    pool += [tuple(p) for p in x]
    k = draw(st.integers(0, 6))
    o_pos0 = points(draw, k, scale, pool)
    speed = draw(st.sampled_from([0.0, 150.0, 150.0, 1e4]))
    v = points(draw, n, speed, [(0.0, 0.0)])
    o_vel = points(draw, k, speed, [(0.0, 0.0)])
    # pref = v: no driving force, so the other terms (signed zeros included) show alone
    pref = v.copy() if draw(st.integers(0, 3)) == 0 else points(draw, n, speed, [(0.0, 0.0), (-0.0, 0.0)])
    radii = np.array([draw(st.one_of(st.sampled_from([0.0, 25.0, 30.0, 1e-3, 500.0]), messy(0.0, 60.0)))
                      for _ in range(n)], dtype=float)
    tau = draw(st.sampled_from([0.0, 0.25, 0.5, 0.75, 7.0]))
    config = draw(configs())
    cos_fov = sin_cos_deg(config.fov_deg)[1]
    return x, v, pref, o_pos0, o_vel, tau, radii, segments, circles, config, cos_fov


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(substep_inputs())
def test_substep_force_same_bits(args: tuple) -> None:
    """The kernel's forces equal the numpy path's bit for bit."""
    with np.errstate(all="ignore"):  # the numpy path divides where np.where discards the result
        want = sf._substep_force_numpy(*args)
    got = sf._substep_force_kernel(*args)
    assert_same_bits(got, want)


def random_scene(rng: np.random.Generator) -> tuple:
    """One substep's arguments in a 10 m room like the scenarios': pedestrians and others walking among walls
    and pillars, often within reach of each other and of the walls (so every term shows in the sum)."""
    n, k = int(rng.integers(1, 26)), int(rng.integers(0, 6))
    x = rng.uniform(0.0, 1000.0, (n, 2))
    o_pos0 = rng.uniform(0.0, 1000.0, (k, 2))
    v, o_vel = rng.normal(0.0, 100.0, (n, 2)), rng.normal(0.0, 100.0, (k, 2))
    pref = v.copy() if rng.random() < 0.2 else rng.normal(0.0, 130.0, (n, 2))
    a = rng.uniform(0.0, 1000.0, (int(rng.integers(0, 7)), 2))
    segments = np.hstack([a, a + rng.normal(0.0, 300.0, a.shape)])
    n_circles = int(rng.integers(0, 5))
    circles = np.column_stack([rng.uniform(0.0, 1000.0, (n_circles, 2)), rng.uniform(0.0, 150.0, n_circles)])
    # some pedestrians just outside a pillar or beside a wall
    for i in range(n):
        if len(circles) and rng.random() < 0.3:
            cx, cy, rc = circles[rng.integers(len(circles))]
            angle, gap = rng.uniform(0.0, 2 * np.pi), rng.uniform(0.0, 80.0)
            x[i] = (cx + (rc + gap) * np.cos(angle), cy + (rc + gap) * np.sin(angle))
        elif len(segments) and rng.random() < 0.3:
            x0, y0, x1, y1 = segments[rng.integers(len(segments))]
            t = rng.uniform(0.0, 1.0)
            x[i] = (x0 + t * (x1 - x0) + rng.normal(0.0, 40.0), y0 + t * (y1 - y0) + rng.normal(0.0, 40.0))
    radii = rng.uniform(15.0, 35.0, n)
    step_ahead = str(rng.choice(sf.STEP_AHEAD))
    if rng.random() < 0.5:
        config = sf.SocialForceConfig(step_ahead=step_ahead)
    else:
        config = sf.SocialForceConfig(**{name: float(rng.uniform(lo, min(hi, 100 * max(lo, 1.0))))
                                         for name, (lo, hi) in CONFIG_FIELDS.items()}, step_ahead=step_ahead)
    tau = float(rng.choice([0.0, 0.25, 0.5, 0.75]))
    return x, v, pref, o_pos0, o_vel, tau, radii, segments, circles, config, sin_cos_deg(config.fov_deg)[1]


def test_substep_force_same_bits_random_scenes() -> None:
    """The kernel's forces equal the numpy path's bit for bit in 1,000 random rooms (full-precision values:
    every rounding of every term shows)."""
    rng = np.random.default_rng(20261202)
    for _ in range(1000):
        args = random_scene(rng)
        assert_same_bits(sf._substep_force_kernel(*args), sf._substep_force_numpy(*args))


def test_substep_force_handmade_cases() -> None:
    """Cases a random draw rarely makes exactly: two pedestrians at one place, a pedestrian on a wall's line, on
    a wall's end, at a circle's centre, on another's path Δt ahead (b = 0), standing with no preferred
    velocity, moving across its preferred velocity; no walls or circles at all; an empty group; both readings
    of the step ahead."""
    cos_fov = sin_cos_deg(sf.SocialForceConfig().fov_deg)[1]
    x = np.array([[0.0, 0.0], [0.0, 0.0], [50.0, 0.0], [100.0, 0.0], [300.0, 300.0], [-0.0, 200.0],
                  [10.0, 100.0]])
    v = np.array([[0.0, 0.0], [100.0, 0.0], [-0.0, 0.0], [0.0, -50.0], [0.0, 0.0], [1.0, 1.0], [5.0, 0.0]])
    pref = np.array([[0.0, 0.0], [130.0, 0.0], [0.0, -0.0], [-100.0, 0.0], [0.0, 0.0], [0.0, 100.0],
                     [100.0, 0.0]])
    o_pos0 = np.array([[10.0, 0.0], [300.0, 300.0], [0.0, 100.0]])
    o_vel = np.array([[0.0, 0.0], [0.0, 0.0], [5.0, 0.0]])  # the last reaches x[6] Δt = 2 s ahead
    radii = np.array([25.0, 25.0, 0.0, 30.0, 25.0, 25.0, 25.0])
    segments = np.array([[0.0, 0.0, 100.0, 0.0], [100.0, 0.0, 100.0, 0.0], [-0.0, 200.0, -0.0, 400.0]])
    circles = np.array([[300.0, 300.0, 40.0], [0.0, 0.0, 0.0]])
    cases = [(segments, circles), (segments[:0], circles), (segments, circles[:0]), (segments[:0], circles[:0])]
    for c in (sf.SocialForceConfig(step_ahead=reading) for reading in sf.STEP_AHEAD):
        for segs, circs in cases:
            for tau in (0.0, 0.5):
                for group in (slice(None), slice(0, 1), slice(0, 0)):
                    args = (x[group], v[group], pref[group], o_pos0, o_vel, tau, radii[group], segs, circs, c,
                            cos_fov)
                    with np.errstate(all="ignore"):
                        want = sf._substep_force_numpy(*args)
                    assert_same_bits(sf._substep_force_kernel(*args), want)


@pytest.mark.parametrize("step_ahead", sf.STEP_AHEAD)
def test_non_finite_inputs_give_nan_where_numpy_does(step_ahead: str) -> None:
    """An infinite or NaN position makes NaN or infinite forces in both paths, at the same places (the NaNs'
    payloads are the CPU's, so only their places are compared; every other value bitwise)."""
    c = sf.SocialForceConfig(step_ahead=step_ahead)
    cos_fov = sin_cos_deg(c.fov_deg)[1]
    x = np.array([[0.0, 0.0], [math.inf, 0.0], [10.0, math.nan], [1e200, -1e200], [40.0, 40.0]])
    v = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [0.0, 0.0], [math.inf, 0.0]])
    pref = np.array([[0.0, 100.0], [100.0, 0.0], [0.0, 0.0], [0.0, 1.0], [1.0, 0.0]])
    o_pos0, o_vel = np.array([[5.0, 5.0]]), np.array([[1e300, 0.0]])
    radii = np.full(5, 25.0)
    segments, circles = np.array([[0.0, -50.0, 100.0, -50.0]]), np.array([[60.0, 60.0, 10.0]])
    args = (x, v, pref, o_pos0, o_vel, 0.25, radii, segments, circles, c, cos_fov)
    with np.errstate(all="ignore"):
        want = sf._substep_force_numpy(*args)
    got = sf._substep_force_kernel(*args)
    assert np.array_equal(np.isnan(got), np.isnan(want))
    finite = ~np.isnan(want)
    assert_same_bits(got[finite], want[finite])


def test_kernel_rejects_wrong_buffers() -> None:
    """Wrong shapes or dtypes are refused (ValueError), not read out of bounds."""
    c = sf.SocialForceConfig()
    good = [np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((1, 2)), np.zeros((1, 2)), 0.0,
            np.zeros(2), np.zeros((1, 4)), np.zeros((0, 3))]
    floats = [c.relaxation_s, c.agent_strength_cm2_s2, c.agent_range_cm, c.step_time_s, c.wall_strength_cm2_s2,
              c.wall_range_cm, 0.5, c.fov_weight, False]
    sf._kernel.forces(*good, *floats, np.zeros((2, 2)))
    for i, bad in [(0, np.zeros((3, 2))), (2, np.zeros((2, 2), dtype=np.float32)), (4, np.zeros((2, 2))),
                   (6, np.zeros(3)), (7, np.zeros((1, 3))), (3, np.zeros((4, 2))[::2])]:
        args = list(good)
        args[i] = bad
        with pytest.raises(ValueError):
            sf._kernel.forces(*args, *floats, np.zeros((2, 2)))
    with pytest.raises(ValueError):
        sf._kernel.forces(*good, *floats, np.zeros((3, 2)))


def _crowd_run(model: str, seed: int, n: int, steps: int) -> tuple[dict, list[bytes]]:
    """One crowd_crossing episode with ``n`` pedestrians of ``model`` (no log): its result and every
    social-force step's returned positions and velocities (as bytes)."""
    import runners.benchmarks.crowd as bench_crowd
    from runners.run import episode_config, load_evaluator, load_scenario, run_episode

    base = bench_crowd._inputs(model, n)
    base["scenario"]["params"]["max_steps"] = steps
    trajectory: list[bytes] = []
    step = sf.SocialForceModel.step

    def recording(self, view, indices, dt):
        x, v = step(self, view, indices, dt)
        trajectory.append(x.tobytes() + v.tobytes())
        return x, v

    sf.SocialForceModel.step = recording
    try:
        result = run_episode(load_scenario(base, seed), load_evaluator(base), episode_config(base), seed, None, "")
    finally:
        sf.SocialForceModel.step = step
    return result, trajectory


class _CountingKernel:
    """The kernel module with a count of its ``forces`` calls (to show the episodes used it)."""

    def __init__(self, kernel) -> None:
        self.kernel, self.calls = kernel, 0

    def forces(self, *args) -> None:
        self.calls += 1
        self.kernel.forces(*args)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_crowd_episodes_same_with_and_without_kernel(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """crowd_crossing with 12 social-force pedestrians: the same pedestrian trajectories (bitwise) and the same
    episode result with the kernel and with FUZZYNAV_KERNEL=python."""
    counting = _CountingKernel(sf._kernel)
    monkeypatch.setattr(sf, "_kernel", counting)
    monkeypatch.delenv(compiled.KERNEL_ENV, raising=False)
    with_kernel, traj_kernel = _crowd_run("social_force", seed, 12, 40)
    assert counting.calls > 0
    calls = counting.calls
    monkeypatch.setenv(compiled.KERNEL_ENV, "python")
    with_numpy, traj_numpy = _crowd_run("social_force", seed, 12, 40)
    assert counting.calls == calls  # switched off: the numpy path ran
    assert with_kernel["outcome"] != "error", with_kernel
    assert with_kernel == with_numpy
    assert len(traj_kernel) == len(traj_numpy) > 10
    assert traj_kernel == traj_numpy
