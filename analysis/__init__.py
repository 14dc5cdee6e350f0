"""fuzzynav's analysis of episode logs (``python -m analysis.report``)."""

import sys

if sys.argv[:1] == ["-m"]:  # `python -m analysis.<entry>`: runpy imports this package before the entry module
    from analysis import interrupts

    interrupts.guard_startup()
