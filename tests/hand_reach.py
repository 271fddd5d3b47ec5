"""Measurement (not a test): where the robot's hand reaches with its approach tilted from straight down
toward a direction across the table (no simulator: the IK from home with its restarts, as the grasp
chooser asks it, for the pose and the pose turned half a turn about its approach).

    python tests/hand_reach.py [--robot panda] [--toward 1,0] [--tilts 60,75,90] [--reach 0.45,0.65]
        [--heights 0.05,0.45]

Prints, for each tilt, a map: rows the TCP's height over the table (high first), columns its distance
from the base along ``--toward`` (the hand pointing that way), every 5 cm: ``y`` reached, ``.`` not.
A grasp into a shelf's bin comes in tilted 60 to 90 deg; where the map has no ``y`` at the bin's height
for any tilt, no grasp from the front can be made there.
"""

from __future__ import annotations

import argparse

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import IKParams, kinematics_of


def tilted(toward: np.ndarray, tilt_deg: float) -> np.ndarray:
    """The hand's orientation pointing ``toward`` (a unit vector across the table), tilted ``tilt_deg``
    from straight down, its closing axis level."""
    t = np.radians(tilt_deg)
    z = np.array([toward[0] * np.sin(t), toward[1] * np.sin(t), -np.cos(t)])
    y = np.array([-toward[1], toward[0], 0.0])
    return np.column_stack([np.cross(y, z), y, z])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robot", default="panda")
    ap.add_argument("--toward", default="1,0")
    ap.add_argument("--tilts", default="60,75,90")
    ap.add_argument("--reach", default="0.45,0.65")
    ap.add_argument("--heights", default="0.05,0.45")
    a = ap.parse_args()
    kin = kinematics_of(robot_named(a.robot))
    toward = np.array([float(v) for v in a.toward.split(",")])
    toward /= np.linalg.norm(toward)
    r0, r1 = (float(v) for v in a.reach.split(","))
    z0, z1 = (float(v) for v in a.heights.split(","))
    reaches = np.arange(r0, r1 + 1e-9, 0.05)
    heights = np.arange(z1, z0 - 1e-9, -0.05)
    rng = np.random.default_rng(0)
    for tilt in (float(v) for v in a.tilts.split(",")):
        R = tilted(toward, tilt)
        turned = R @ np.diag([-1.0, -1.0, 1.0])
        print(f"tilt {tilt:.0f} deg, pointing ({toward[0]:.2f}, {toward[1]:.2f}): columns {r0:.2f}..{r1:.2f} m")
        for z in heights:
            row = ""
            for r in reaches:
                p = np.array([toward[0] * r, toward[1] * r, z])
                ok = any(kin.solve(Pose(p, rot), kin.robot.home_q, rng, IKParams()).success for rot in (R, turned))
                row += "y" if ok else "."
            print(f"  z {z:.2f}  {row}")


if __name__ == "__main__":
    main()
