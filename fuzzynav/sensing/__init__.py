"""What the robot senses: sonar (left, front, right), the laser range finder and its ray casting, the tracker
that estimates moving obstacles' speed and heading from successive frames, and perception (laser or ground truth)."""
