"""The episode log (MCAP) and what it holds: the writer, the 3-D scene, the fields of each message (their schemas
are :mod:`analysis.log_format`, shared with the analysis), the run's provenance, and the comparison of two logs."""
