"""Scenarios and the world: scenario data and its validation, the static world (walls, obstacles, contact)
and the scenario-generator seam with its generators."""
