"""What the robot does, as controllers called once per control tick (the ``Controller``
protocol, :mod:`pickdemo.skills.controller`): the pick skill (a machine, its states and its parts),
a clear round that sequences picks, and the actions they drive (a move of the hand, a grip, a scale)."""
