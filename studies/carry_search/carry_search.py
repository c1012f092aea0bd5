"""Search a carry pose out of the head camera's view that READY reaches with the hand kept down.

    python studies/carry_search/carry_search.py                  # 4000 expansions, seed 2 (found CARRY_DRIVE_GROUP)
    python studies/carry_search/carry_search.py -n 1500 --seed 1

Why a search: READY's elbow is near its flex limit, so straight TCP lines from READY towards the
side stop after a few cm, and a joint path to an IK solution elsewhere (another arm branch)
tilts the hand, which lets the object pivot in the two-finger pinch. So this grows a tree of
hand-down configurations from READY (perturb the joints of a node, project onto "TCP pointing
down" with ArmPlanner.ik seeded there), keeping an edge only if the hand stays within MAX_TILT
along its joint-space interpolation and it is free of self-collision; the nodes whose head view a
furby-sized box plus the robot covers < 1 % with arm link origins within 0.36 m of the base axis
are shortcut back to READY, and the shortest are printed with their waypoints.

What it found is a joint configuration (`skills.place.CARRY_DRIVE_GROUP`), searched for the
former joint-space experts. Today's experts are closed-loop end-effector controllers: they take
only its TCP (`skills.pick.APPROACH_TCP`), which the ee map's IK reaches with another arm shape
(docs/manipulation_experts.md). The search stays as the record of how that TCP was chosen; it
needs mplib (`pip install -e '.[planning]'`).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from echo_data.robot.planner import ArmPlanner
from echo_data.robot.robot import HEAD_TILT
from echo_data.skills import arm
from echo_data.skills.head_view import HeadView, arm_reach, set_group

MAX_TILT = 4.0  # deg between the approach axis and straight down along every move
MAX_STEP = 0.35  # rad: largest joint change of one tree edge
MIN_TCP_Z = 0.95  # m: the held object stays above receptacle tops


def tilt(planner: ArmPlanner, q: np.ndarray) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, -float(planner.fk(q).to_transformation_matrix()[2, 0])))))


def segment_ok(planner: ArmPlanner, a: np.ndarray, b: np.ndarray) -> bool:
    n = max(2, int(math.ceil(float(np.max(np.abs(b - a))) / 0.05)))
    return all(
        tilt(planner, m) <= MAX_TILT and not planner.collisions(m) for m in (a + (b - a) * t for t in np.linspace(0.0, 1.0, n + 1)[1:-1])
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=4000, help="tree expansions")
    ap.add_argument("--seed", type=int, default=2)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    planner = ArmPlanner(seed=0)
    planner.sync((0.0, 0.0, 0.0), arm.READY_GROUP, 0.0, (0.0, HEAD_TILT))
    planner.set_obstacles([])
    lim = planner.limits[planner.group]
    nodes, parent = [arm.READY_GROUP.copy()], [-1]
    for _ in range(a.n):
        i = int(rng.integers(len(nodes))) if rng.random() < 0.7 else len(nodes) - 1
        qt = nodes[i].copy()
        qt[1:] += rng.uniform(-0.3, 0.3, 7)
        qt = np.clip(qt, lim[:, 0], lim[:, 1])
        p = planner.fk(qt).p
        if p[2] < MIN_TCP_Z:
            continue
        yaw = arm.jaw_yaw(planner.fk(nodes[i])) + rng.uniform(-0.2, 0.2)
        q = planner.ik(arm.top_down_pose(float(p[0]), float(p[1]), float(p[2]), yaw), qt, tries=1)
        if q is None or np.max(np.abs(q - nodes[i])) > MAX_STEP or not segment_ok(planner, nodes[i], q):
            continue
        nodes.append(q)
        parent.append(i)
    view = HeadView()
    found = []
    for i, g in enumerate(nodes):
        set_group(view.robot, g)
        reach = arm_reach(view.robot)
        if reach > 0.36:
            continue
        covered = view.covered(g, "furby")
        if covered >= 0.01:
            continue
        chain, j = [], i
        while j >= 0:
            chain.append(nodes[j])
            j = parent[j]
        chain.reverse()
        path, k = [chain[0]], 0
        while k < len(chain) - 1:  # greedy shortcut: the farthest node reachable by one good segment
            m = len(chain) - 1
            while m > k + 1 and not segment_ok(planner, chain[k], chain[m]):
                m -= 1
            path.append(chain[m])
            k = m
        length = sum(float(np.max(np.abs(v - u))) for u, v in zip(path[:-1], path[1:]))
        found.append((length, covered, reach, planner.fk(g).p, path))
    print(f"{len(nodes)} hand-down configurations reached from READY, {len(found)} clear the head view")
    for length, covered, reach, p, path in sorted(found, key=lambda t: t[0])[:5]:
        print(f"length {length:.2f} rad  covered {covered:.1%}  reach {reach:.3f} m  TCP {np.round(p, 3).tolist()}")
        for q in path[1:]:
            print("    ", np.round(q, 3).tolist())


if __name__ == "__main__":
    main()
