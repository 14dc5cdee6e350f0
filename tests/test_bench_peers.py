"""The benchmark's peer engines are built from our definition: when installed, each agrees with scikit-fuzzy
within its own discretisation (see runners/benchmarks/peers.py); when not, the bench prints a row, never fails."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from fuzzynav.controller.fuzzy_reference import SkfuzzyEvaluator
from runners.benchmarks import fuzzy as bench
from runners.benchmarks import peers as bench_peers

# the largest disagreement with scikit-fuzzy each peer's discretisation allows here (measured on the bench's
# inputs: ferrifuzz 0.39 / 0.040 (table1), 0.40 / 0.065 (listing); pyfuzzylite 0.019 / 0.0076, 0.15 / 0.022)
TOLERANCE = {"ferrifuzz": (0.5, 0.1), "pyfuzzylite": (0.2, 0.05)}  # (degrees, cm/s)


def _inputs(spec, n: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {v.name: rng.uniform(v.universe[0] - 5, v.universe[1] + 5, n) for v in spec.inputs}


@pytest.mark.parametrize("peer", sorted(bench_peers.PEERS))
@pytest.mark.parametrize("name", ["table1", "listing"])
def test_peer_agrees_with_skfuzzy(peer, name, table1, listing):
    spec = {"table1": table1, "listing": listing}[name]
    try:
        ev = bench_peers.PEERS[peer](spec)
    except bench_peers.PeerMissing:
        pytest.skip(f"{peer} not installed")
    inputs = _inputs(spec, 300, seed=7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        ref = np.array(SkfuzzyEvaluator(spec).evaluate(inputs))
    batch = np.array(ev.evaluate(inputs))
    single = np.array([ev.evaluate({k: float(a[i]) for k, a in inputs.items()}) for i in range(300)]).T
    tol = np.array(TOLERANCE[peer])[:, None]
    assert np.all(np.isfinite(batch)) and np.all(np.isfinite(single))
    assert np.all(np.abs(batch - ref) <= tol) and np.all(np.abs(single - ref) <= tol)
    assert np.array_equal(batch, single)  # the same engine both ways


def test_a_missing_peer_is_a_row(monkeypatch, table1):
    def missing(spec):
        raise bench_peers.PeerMissing("ferrifuzz")

    monkeypatch.setitem(bench_peers.PEERS, "ferrifuzz", missing)
    inputs = _inputs(table1, 4, seed=1)
    rows = [{k: float(v[i]) for k, v in inputs.items()} for i in range(4)]
    row = bench._peer_row("ferrifuzz", table1, rows, inputs, inputs, np.zeros((2, 4)), 1)
    assert row == {"engine": "ferrifuzz", "installed": False}
