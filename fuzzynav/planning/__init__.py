"""Dynamic path planning: the Trajectory Prediction Table (TPT), the wait/detour planner (``find_new_path``) and
the layer that runs them over any navigation policy."""
