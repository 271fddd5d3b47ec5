"""Which grasp: top-down grasps of a described shape, grasps from an unknown object's cloud, and
the `GraspSelector` protocol that chooses among them."""
