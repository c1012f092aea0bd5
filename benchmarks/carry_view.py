"""How much of the head camera's view the arm and a held object cover in a carry pose.

    python benchmarks/carry_view.py                       # READY and Place's CARRY_DRIVE_GROUP
    python benchmarks/carry_view.py --group 0.386,1.134,-0.888,-2.298,2.032,0.491,1.601,1.868

Renders the head camera (the recipe default: 128 x 128, 70 deg, tilted HEAD_TILT) of the robot
alone on a floor with the torso and arm at each group (torso, 7 arm joints) and each object
category's box hanging from the pads as Pick holds it (echo_data.robot.head_view), and prints the
share of pixels showing a robot link or the box (smallest and largest over the categories), the
TCP in the base frame, and the largest horizontal distance of an arm link origin from the base
axis (what a turn in place sweeps).

The groups are joint shapes: CARRY_DRIVE_GROUP is the former joint-space experts' carry pose.
The closed-loop experts hold the hand at its TCP (`skills.pick.APPROACH_TCP`) with the ee map's
own arm shape, which is not this one (docs/manipulation_experts.md); pass that shape with
`--group` to measure what they show the head camera.
"""

from __future__ import annotations

import argparse

import numpy as np

from echo_data.robot.head_view import HeadView, arm_reach, set_group
from echo_data.skills import arm
from echo_data.skills.place import CARRY_DRIVE_GROUP


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--group", action="append", default=[], help="torso and 7 arm joints, comma-separated")
    a = ap.parse_args()
    groups = {"READY": arm.READY_GROUP, "CARRY_DRIVE": CARRY_DRIVE_GROUP}
    groups.update({f"group{i}": np.array([float(v) for v in g.split(",")]) for i, g in enumerate(a.group)})
    view = HeadView()
    for name, g in groups.items():
        covered = {c: view.covered(g, c) for c in view.held}
        lo, hi = min(covered, key=covered.__getitem__), max(covered, key=covered.__getitem__)
        tcp = set_group(view.robot, g)
        print(
            f"{name:12s} head view covered {covered[lo]:6.1%} ({lo}) .. {covered[hi]:6.1%} ({hi})"
            f"  TCP {np.round(tcp.p, 3).tolist()}  arm reach {arm_reach(view.robot):.3f} m"
        )


if __name__ == "__main__":
    main()
