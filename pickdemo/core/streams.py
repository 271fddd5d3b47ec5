"""The seed's random streams: one independent ``numpy.random.Generator`` per stage.

Shared by an episode, ``perceive`` and ``bench``: one seed makes one episode, bit for bit, whatever
runs it. Streams are spawned from the seed in the order of :data:`RNG_STREAMS`; a new stream is
appended, never inserted, so the draws of the existing ones stay as they were.
"""

from __future__ import annotations

import numpy as np

#: Order in which the seed's generators are spawned. Append only: reordering changes every episode.
RNG_STREAMS = (
    "layout",
    "camera",
    "ik",
    "camera_pose",
    "disturbance",
    "calibration",
    "place",
    "objects",
    "clear",
    "wrist_camera",
    "hand_eye",
    "grasps",
    "planning",
)


def spawn_rngs(seed: int) -> dict[str, np.random.Generator]:
    """One independent generator per stage, spawned from the seed."""
    children = np.random.SeedSequence(seed).spawn(len(RNG_STREAMS))
    return {name: np.random.default_rng(s) for name, s in zip(RNG_STREAMS, children, strict=True)}
