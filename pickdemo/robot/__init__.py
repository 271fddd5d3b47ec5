"""The robot: its description (files, joints, frames, home, datasheet limits, gripper, camera
mounts), its kinematics (Pinocchio), the rate limiter every joint command passes, and the geometry
of its own links (the self-filter). Imports only `pickdemo.core`."""
