"""How many values a sweep override lists (``seed=range(0,20)``: 20), counted without listing a long range."""

from __future__ import annotations

import math
from collections.abc import Sequence

from hydra.core.override_parser.types import Override, RangeSweep, ValueType

from fuzzynav.params.limits import MAX_SWEEP_JOBS


def sweep_size(override: Override) -> int | None:
    """How many values a sweep override lists, without listing a range (``range(0,100000000)`` was a hundred million
    strings); None when it cannot be listed (``range(0,4,0)``)."""
    value = override.value()
    try:
        if isinstance(value, RangeSweep):
            bounds = (value.start, value.stop, value.step)
            if all(isinstance(x, int) for x in bounds):
                return len(range(*bounds))  # type: ignore[arg-type]
            start, stop, step = (float(x) for x in bounds)  # type: ignore[arg-type]
            if step == 0 or not all(math.isfinite(x) for x in (start, stop, step)):
                return None
            if (stop - start) / step > 2 * MAX_SWEEP_JOBS:  # more than a sweep may have: the size is enough
                return math.ceil((stop - start) / step)
        return sum(1 for _ in override.sweep_string_iterator())  # (Hydra's own float steps, counted exactly)
    except (ValueError, TypeError, OverflowError):
        return None


def sweep_problem(parsed: Sequence[Override]) -> str | None:
    """One line about the sweep of these overrides (a preset's ``hydra.sweeper.params`` and the command line's, in
    Hydra's order: a later plain value replaces an earlier sweep of its key) when a sweep cannot be listed, lists no
    value, or the jobs are more than :data:`~fuzzynav.params.limits.MAX_SWEEP_JOBS`; None otherwise (a glob is
    counted as one: the check of its options is the command line's)."""
    sizes: dict[str, int] = {}
    for o in parsed:
        key = o.get_key_element()
        if not o.is_sweep_override() or o.value_type == ValueType.GLOB_CHOICE_SWEEP:
            sizes[key] = 1
            continue
        size = sweep_size(o)
        value = o.input_line.partition("=")[2][:60]
        if size is None:
            return f"{key}: {value} cannot be listed (a range's step must be a finite number other than 0)"
        if size == 0:
            return f"{key}: {value} selects no value (an empty sweep)"
        sizes[key] = size
    if math.prod(sizes.values()) > MAX_SWEEP_JOBS:
        return (f"the sweep has {math.prod(sizes.values()):,} jobs, more than {MAX_SWEEP_JOBS:,}; batch seeds into "
                "longer jobs (episodes=K seed='range(0,N,K)')")
    return None
