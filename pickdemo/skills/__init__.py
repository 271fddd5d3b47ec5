"""What the robot does, as controllers called once per control tick: the pick skill (a state
machine and its parts), the clearing sequencer, and the actions they drive (a move of the hand, a
grip, a scale)."""
