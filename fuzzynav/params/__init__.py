"""Run parameters: every documented limit and range (:mod:`.limits`), the checks that enforce them
(:mod:`.checks`), frozen dataclasses from plain data (:mod:`.parsing`) and the names of policies, modes and
pedestrian models with the defaults of a run that names none (:mod:`.names`)."""
