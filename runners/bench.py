"""Benchmarks (speed is measured here, never asserted in unit tests).

    python -m runners.bench            # full run
    python -m runners.bench --quick    # reduced repetitions (CI)

Section 1 (fuzzy decision): the fast numpy evaluator vs scikit-fuzzy's ControlSystemSimulation.compute()
on the same definition and the same seeded inputs — time per single decision for both, their ratio,
batch throughput and the largest disagreement. Each time is the median of several repetitions after a
warm-up. Writes ``bench.json`` (path with ``--out``).
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
import warnings
from pathlib import Path

import numpy as np
import yaml

from fuzzynav.fuzzy_fast import FastEvaluator
from fuzzynav.fuzzy_reference import SkfuzzyEvaluator
from fuzzynav.fuzzy_spec import ControllerSpec

CONF = Path(__file__).resolve().parents[1] / "conf"


def _inputs(spec: ControllerSpec, n: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {v.name: rng.uniform(v.universe[0], v.universe[1], n) for v in spec.inputs}


def _median_time(fn, reps: int) -> float:
    fn()  # warm-up
    times = []
    for _ in range(reps):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def bench_fuzzy(name: str, n_single: int, n_ref: int, batch: int, reps: int) -> dict:
    """Single-decision time of both evaluators, batch throughput, and the largest disagreement."""
    with open(CONF / "controller" / f"{name}.yaml") as f:
        spec = ControllerSpec.from_dict(yaml.safe_load(f))
    fast, ref = FastEvaluator(spec), SkfuzzyEvaluator(spec)
    inputs = _inputs(spec, n_single, seed=1)
    rows = [{k: float(v[i]) for k, v in inputs.items()} for i in range(n_single)]
    fast_s = _median_time(lambda: [fast.evaluate(r) for r in rows], reps) / n_single
    ref_rows = rows[:n_ref]
    ref_s = _median_time(lambda: [ref.evaluate(r) for r in ref_rows], max(1, reps // 2)) / n_ref
    big = _inputs(spec, batch, seed=2)
    batch_s = _median_time(lambda: fast.evaluate(big), reps)
    a = fast.evaluate(inputs)
    b = ref.evaluate(inputs)
    return {"controller": name, "fast_us_per_decision": fast_s * 1e6, "skfuzzy_us_per_decision": ref_s * 1e6,
            "ratio": ref_s / fast_s, "batch_size": batch, "batch_decisions_per_s": batch / batch_s,
            "max_disagreement_dtheta_deg": float(np.max(np.abs(a[0] - b[0]))),
            "max_disagreement_v_cm_s": float(np.max(np.abs(a[1] - b[1]))), "inputs_compared": n_single}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (about 20 s)")
    parser.add_argument("--out", default="bench.json", help="where to write the results (JSON)")
    args = parser.parse_args(argv)
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    n_single, n_ref, reps = (200, 20, 3) if args.quick else (1000, 200, 7)
    results = {"machine": {"python": platform.python_version(), "processor": platform.processor() or platform.machine(),
                           "system": platform.platform()},
               "quick": args.quick, "fuzzy": [bench_fuzzy(n, n_single, n_ref, 10_000, reps)
                                              for n in ("table1", "listing")]}
    print("fuzzy decision (median of repetitions, after warm-up)")
    print(f"{'controller':<10} {'fast µs':>9} {'skfuzzy µs':>11} {'ratio':>7} {'batch/s':>10} "
          f"{'max |Δθ|':>10} {'max |Δv|':>10}")
    for r in results["fuzzy"]:
        print(f"{r['controller']:<10} {r['fast_us_per_decision']:9.1f} {r['skfuzzy_us_per_decision']:11.0f} "
              f"{r['ratio']:7.0f} {r['batch_decisions_per_s']:10.0f} {r['max_disagreement_dtheta_deg']:10.2e} "
              f"{r['max_disagreement_v_cm_s']:10.2e}")
    Path(args.out).write_text(json.dumps(results, indent=2))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
