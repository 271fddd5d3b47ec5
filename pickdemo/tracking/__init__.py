"""The robot's belief about its target: the tracker (a constant-velocity Kalman filter with a gate)
and the checks every estimate passes on its way in."""
