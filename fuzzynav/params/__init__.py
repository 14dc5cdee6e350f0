"""Run parameters: every documented limit and range (:mod:`.limits`), the checks that enforce them
(:mod:`.checks`) and frozen dataclasses from plain data (:mod:`.parsing`)."""
