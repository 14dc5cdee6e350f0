"""``python -m fuzzynav.policies``: every registered policy (fuzzynav's own and other packages') with its
parameters' defaults and documented ranges, as Markdown tables (the ``navigator`` section's keys)."""

from __future__ import annotations

import dataclasses
import sys

from fuzzynav.params.limits import declared_ranges, range_table
from fuzzynav.policies.base import registered_policies


def policy_tables() -> str:
    """One section per policy: its config class, its parameters' defaults, and their ranges."""
    parts = []
    for name, factory in sorted(registered_policies().items()):
        config_class = getattr(factory, "config_class", None)
        if config_class is None:
            parts.append(f"## `{name}`\n\nno declared parameters ({factory.__module__}.{factory.__qualname__})")
            continue
        defaults = ", ".join(f"`{f.name}={f.default!r}`" for f in dataclasses.fields(config_class)
                             if f.default is not dataclasses.MISSING)
        ranges = declared_ranges(config_class, "navigator")
        parts.append(f"## `{name}` ({config_class.__module__}.{config_class.__qualname__})\n\n"
                     f"defaults: {defaults or 'none'}\n\n" + (range_table(ranges) if ranges else ""))
    return "\n\n".join(parts)


if __name__ == "__main__":
    try:
        print(policy_tables())
    except ValueError as err:  # a broken plug-in of another package: one line naming its entry point
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)
