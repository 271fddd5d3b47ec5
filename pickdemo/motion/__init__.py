"""How the hand and the arm move: online Ruckig in Cartesian and joint space, and the choice of IK
goals a transfer goes to."""
