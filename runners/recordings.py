"""Recorded pedestrians (ETH/BIWI, UCY and the benchmarks' 4-column files): read a user's copy, say what is in it,
and measure how well the Trajectory Prediction Table's constant-velocity prediction fits the recorded people.

    python -m runners.recordings check seq_eth/obsmat.txt zara01/obsmat.txt
    python -m runners.recordings predict seq_eth/obsmat.txt --dt 1 --n-traj 9 --csv errors.csv

The format is told by the file (``--format obsmat|xy``; default: ``obsmat`` for files named ``obsmat*.txt``,
else ``xy``); the recordings are third-party and state no licence, so fuzzynav does not ship them (docs/recordings.md
says where to get them). Every file is checked whole before anything is computed: a bad one is one line naming
the file and line, exit 2. ``predict`` prints one table per file (scenes differ: they are never pooled).
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

from analysis.cli_args import OneLineParser
from fuzzynav.scenarios.recordings import (
    ANNOTATION_HZ,
    FORMATS,
    PREDICTORS,
    PredictionErrors,
    RecordingError,
    prediction_errors,
    read_recording,
)


def _table(errors: PredictionErrors) -> list[str]:
    head = "  k  t (s)  " + "  ".join(f"{name + ' ADE':>12} {name + ' FDE':>12}" for name in PREDICTORS)
    rows = [head]
    for k in range(errors.n_traj):
        rows.append(f"{k + 1:3d} {(k + 1) * errors.dt_s:6.1f}  " + "  ".join(
            f"{errors.ade_cm[name][k]:12.1f} {errors.fde_cm[name][k]:12.1f}" for name in PREDICTORS))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="python -m runners.recordings", description=__doc__.split("\n\n")[0],
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    for name, text in (("check", "read each file and say what is in it"),
                       ("predict", "the TPT's prediction error on the recorded people (cm)")):
        p = sub.add_parser(name, help=text)
        p.add_argument("files", nargs="+", type=Path)
        p.add_argument("--format", choices=sorted(FORMATS), help="obsmat (8 columns) or xy (frame id x y)")
        p.add_argument("--annotation-hz", type=float, default=ANNOTATION_HZ,
                       help="annotations per second (2.5 in ETH and UCY)")
        p.add_argument("--max-gap", type=int, default=0,
                       help="missing annotations allowed inside a pedestrian's track (interpolated; default 0)")
        if name == "predict":
            p.add_argument("--dt", type=float, default=1.0, help="the run's time step (s), as the TPT's rows")
            p.add_argument("--n-traj", type=int, default=9, help="steps predicted (the TPT's n_traj)")
            p.add_argument("--csv", type=Path, help="also write the errors here, one row per file, predictor, k")
    args = parser.parse_args(argv)
    try:
        recordings = [read_recording(f, args.format, args.annotation_hz, args.max_gap) for f in args.files]
        results = [prediction_errors(r, args.dt, args.n_traj) for r, _ in recordings] \
            if args.command == "predict" else []
    except RecordingError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if args.command == "check":
        for (rec, digest), path in zip(recordings, args.files, strict=True):
            counts = [len(t.t_s) for t in rec.tracks]
            print(f"{path}: {len(rec.tracks)} pedestrians, {sum(counts):,} annotations every "
                  f"{rec.annotation_dt_s:g} s over {rec.duration_s:.1f} s; sha256 {digest}")
        return 0
    rows = []
    for (_, digest), path, errors in zip(recordings, args.files, results, strict=True):
        print(f"{path} (sha256 {digest[:12]}): {errors.samples:,} predictions of {errors.pedestrians} pedestrians, "
              f"dt {errors.dt_s:g} s, n_traj {errors.n_traj}")
        if errors.samples == 0:
            print(f"  no pedestrian is recorded for {errors.dt_s:g} s before and {errors.n_traj * errors.dt_s:g} s "
                  "after a step: nothing to compare")
            continue
        for line in _table(errors):
            print("  " + line)
        for name in PREDICTORS:
            for k in range(errors.n_traj):
                rows.append({"file": str(path), "sha256": digest, "predictor": name, "k": k + 1,
                             "horizon_s": (k + 1) * errors.dt_s, "ade_cm": float(errors.ade_cm[name][k]),
                             "fde_cm": float(errors.fde_cm[name][k]), "samples": errors.samples,
                             "pedestrians": errors.pedestrians})
    if args.csv is not None:
        try:
            with open(args.csv, "w", newline="") as f:
                writer = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["file"])
                writer.writeheader()
                writer.writerows(rows)
        except (OSError, ValueError) as err:
            print(f"error: --csv: {args.csv}: cannot be written ({getattr(err, 'strerror', None) or err})",
                  file=sys.stderr)
            return 1
        print(f"wrote {args.csv}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
