"""fuzzynav's runners: experiment entry points (``python -m runners.<entry>``) and what they share."""

import sys

if sys.argv[:1] == ["-m"]:  # `python -m runners.<entry>`: runpy imports this package before the entry module
    from analysis import interrupts

    interrupts.guard_startup()
