"""A run's inputs checked before anything runs: the configuration schema, the data files (scenario and controller
YAML), the pre-checks of a composition, the output directory, and other packages' config folders."""
