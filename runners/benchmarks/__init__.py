"""The benchmarks (``python -m runners.bench``): the peer engines, crowds, the sweep's memory, the side-by-side
baseline, the targets, the stage timers and the performance page."""
