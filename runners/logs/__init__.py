"""The episode log (MCAP) and what it holds: the writer, the Foxglove and fuzzynav message schemas, the 3-D scene, the
fields of each message, the run's provenance, and the comparison of two logs."""
