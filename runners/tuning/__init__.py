"""The optimisation studies of ``python -m runners.tune`` (issue #39): search space, study file, trials."""
