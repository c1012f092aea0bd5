"""Arm planning for the Fetch-like robot with mplib on the fixed-base variant.

Why a wrapper: mplib refuses the mobile URDF's continuous yaw joint, so planning happens on
`fetchlike_arm.urdf` with `set_base_pose`; its joint order differs from SAPIEN's; and plan
results must be reproducible. So IK here is mplib's pinocchio CLIK restarted from seeds of a
seeded numpy generator (limits and collisions checked with mplib), and paths are straight
joint-space segments checked for collisions, with RRTConnect only when a segment collides.

Full planner configuration order (`PlanQ`): torso, head pan, head tilt, 7 arm joints, 2 fingers.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sapien

from echo_data.robot import urdf as U


# A box obstacle in the world: centre, full size, yaw about z.
@dataclass(frozen=True)
class Box:
    name: str
    center: tuple[float, float, float]
    size: tuple[float, float, float]
    yaw: float = 0.0


def _mp_pose(p: sapien.Pose) -> Any:  # an mplib.Pose (mplib has no type information)
    import mplib

    return mplib.Pose(np.asarray(p.p, dtype=np.float64), np.asarray(p.q, dtype=np.float64))


def base_link_pose(x: float, y: float, yaw: float) -> sapien.Pose:
    """World pose of base_link for a base at (x, y, yaw) (the virtual base sits on the floor)."""
    return sapien.Pose([x, y, 0.0], [math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)])


class ArmPlanner:
    """IK and collision-checked joint paths for torso + arm in a world of boxes.

    Usage: `sync(base_pose, torso, arm, gripper)`, `set_obstacles(boxes)`, then `ik(...)` and
    `path(...)`. All configurations handed in/out are (torso, arm[7]) vectors ("group q", 8).
    """

    def __init__(self, seed: int = 0) -> None:
        import mplib

        self.mp = mplib.Planner(
            urdf=str(U.ARM_URDF_PATH),
            srdf=str(U.ARM_SRDF_PATH),
            move_group=U.EE_LINK,
            joint_vel_limits=np.ones(8),
            joint_acc_limits=np.ones(8),
        )
        names = list(self.mp.user_joint_names)
        self.names = names
        self.group = [names.index(U.TORSO_JOINT)] + [names.index(n) for n in U.ARM_JOINTS]
        self.finger = [names.index(n) for n in U.FINGER_JOINTS]
        self.head = [names.index(n) for n in U.HEAD_JOINTS]
        self.ee_index = self.mp.link_name_2_idx[U.EE_LINK]
        self.limits = np.asarray(self.mp.joint_limits, dtype=np.float64)
        self.rng = np.random.default_rng(seed)
        self.q = np.zeros(len(names))
        self._obstacles: list[str] = []
        self.base = sapien.Pose()
        self._base_inv = sapien.Pose()
        self._attached = False

    # ------------------------------------------------------------------ state
    def full(self, group_q: np.ndarray, gripper: float | None = None) -> np.ndarray:
        q = self.q.copy()
        q[self.group] = group_q
        if gripper is not None:
            q[self.finger] = gripper / 2.0
        return q

    def sync(self, base: tuple[float, float, float], group_q: np.ndarray, gripper: float, head: Sequence[float] = (0.0, 0.45)) -> None:
        """Set the planner's base pose and configuration from the robot's (call set_obstacles after)."""
        # mplib 0.2.1 places attached bodies without the base pose, so the planner works in the
        # base frame: its own base stays at the origin and obstacles / goals are transformed.
        self.base = base_link_pose(*base)
        self._base_inv = self.base.inv()
        self.q[self.group] = group_q
        self.q[self.finger] = gripper / 2.0
        self.q[self.head] = head
        self.mp.robot.set_qpos(self.q, True)

    def set_obstacles(self, boxes: Iterable[Box]) -> None:
        """Replace the world obstacles by `boxes` (give only nearby ones: planning cost grows)."""
        import mplib
        from mplib.collision_detection import fcl

        for name in self._obstacles:
            self.mp.remove_object(name)
        self._obstacles = []
        for b in boxes:
            shape = fcl.Box(np.asarray(b.size, dtype=np.float64))
            world = sapien.Pose(list(b.center), [math.cos(b.yaw / 2), 0, 0, math.sin(b.yaw / 2)])
            pose = _mp_pose(self._base_inv * world)
            obj = fcl.FCLObject(b.name, pose, [fcl.CollisionObject(shape)], [mplib.Pose()])
            self.mp.planning_world.add_object(obj)
            self._obstacles.append(b.name)

    def attach_box(self, size: Sequence[float], tcp_to_box: sapien.Pose) -> None:
        """Carry a box-shaped object in the gripper (planned paths keep it clear too)."""
        self.detach()
        self.mp.update_attached_box(list(size), _mp_pose(tcp_to_box))
        self._attached = True

    def detach(self) -> None:
        """Drop every attached body (mplib names them '<robot>_<link>_box')."""
        if self._attached:
            world = self.mp.planning_world
            for name in list(world.get_object_names()):
                if world.is_object_attached(name):
                    world.detach_object(name, True)
            self._attached = False

    # ------------------------------------------------------------------ queries
    def fk(self, group_q: np.ndarray) -> sapien.Pose:
        """World pose of the TCP at `group_q` (base as last synced)."""
        pm = self.mp.pinocchio_model
        pm.compute_forward_kinematics(self.full(group_q))
        p = pm.get_link_pose(self.ee_index)
        return self.base * sapien.Pose(np.asarray(p.p), np.asarray(p.q))

    def collisions(self, group_q: np.ndarray, gripper: float | None = None) -> list[str]:
        """Colliding pairs ('link|object') at `group_q`; empty when free."""
        res = self.mp.check_for_collision(self.mp.planning_world.check_collision, self.full(group_q, gripper))
        return [f"{c.link_name1}|{c.link_name2}" for c in res]

    def within_limits(self, group_q: np.ndarray) -> bool:
        lim = self.limits[self.group]
        return bool(np.all(group_q >= lim[:, 0] - 1e-6) and np.all(group_q <= lim[:, 1] + 1e-6))

    # ------------------------------------------------------------------ IK
    def ik(
        self,
        goal: sapien.Pose,
        start: np.ndarray,
        fix_torso: bool = True,
        tries: int = 12,
        check_collision: bool = True,
        gripper: float | None = None,
    ) -> np.ndarray | None:
        """A collision-free, within-limits group q reaching world pose `goal`, nearest to `start`.

        Seeds: `start`, then random configurations from the planner's generator (reproducible).
        """
        target = _mp_pose(self._base_inv * goal)
        pm = self.mp.pinocchio_model
        mask = [False] * len(self.names)
        for i in range(len(self.names)):
            if i not in self.group or (fix_torso and i == self.group[0]):
                mask[i] = True
        best: np.ndarray | None = None
        best_d = math.inf
        lim = self.limits
        for k in range(tries):
            seed = self.full(start, gripper)
            if k > 0:
                lo, hi = lim[self.group, 0], lim[self.group, 1]
                lo = np.maximum(lo, -math.pi)
                hi = np.minimum(hi, math.pi)
                rand = lo + (hi - lo) * self.rng.random(len(self.group))
                if fix_torso:
                    rand[0] = start[0]
                seed[self.group] = rand
            q, ok, _ = pm.compute_IK_CLIK(self.ee_index, target, seed, mask)
            if not ok:
                continue
            q = np.asarray(q, dtype=np.float64)
            g = q[self.group]
            # bring revolute joints to the representative nearest the start
            for j in range(1, len(g)):
                while g[j] - start[j] > math.pi and g[j] - 2 * math.pi >= lim[self.group[j], 0]:
                    g[j] -= 2 * math.pi
                while start[j] - g[j] > math.pi and g[j] + 2 * math.pi <= lim[self.group[j], 1]:
                    g[j] += 2 * math.pi
            if not self.within_limits(g):
                continue
            if check_collision and self.collisions(g, gripper):
                continue
            d = float(np.linalg.norm(g[1:] - start[1:]) + 3.0 * abs(g[0] - start[0]))
            if d < best_d:
                best, best_d = g.copy(), d
            if k >= 3 and best is not None:
                break
        return best

    # ------------------------------------------------------------------ paths
    def segment_free(self, a: np.ndarray, b: np.ndarray, gripper: float | None = None, step: float = 0.05) -> bool:
        n = max(2, int(math.ceil(float(np.max(np.abs(b - a))) / step)) + 1)
        return all(not self.collisions(a + (b - a) * t, gripper) for t in np.linspace(0.0, 1.0, n))

    def via_path(self, start: np.ndarray, goal: np.ndarray, gripper: float | None = None, tries: int = 150) -> list[np.ndarray] | None:
        """start -> via -> goal through one collision-free via configuration, or None.

        Vias are drawn from the planner's seeded generator, biased towards the straight
        segment's midpoint, so (unlike OMPL's clock-seeded RRT) the same episode always
        finds the same path.
        """
        lim = self.limits[self.group]
        lo, hi = np.maximum(lim[:, 0], -math.pi), np.minimum(lim[:, 1], math.pi)
        mid = (start + goal) / 2.0
        for k in range(tries):
            spread = min(1.0, 0.15 + k / tries)  # widen the search as it goes
            rand = lo + (hi - lo) * self.rng.random(len(self.group))
            via = np.clip(mid + spread * (rand - mid), lo, hi)
            if self.collisions(via, gripper):
                continue
            if self.segment_free(start, via, gripper) and self.segment_free(via, goal, gripper):
                return [start.copy(), via, goal.copy()]
        return None

    def path(self, start: np.ndarray, goal: np.ndarray, gripper: float | None = None, planning_time: float = 1.5) -> list[np.ndarray] | None:
        """Waypoints (group q) from start to goal: straight if free, else RRTConnect (simplified)."""
        if self.segment_free(start, goal, gripper):
            return [start.copy(), goal.copy()]
        via = self.via_path(start, goal, gripper)
        if via is not None:
            return via
        # Last resort: mplib's RRTConnect. OMPL seeds it from the clock, so an episode that
        # reaches this line may not repeat bit for bit (the recorded actions stay valid).
        res = self.mp.plan_qpos(
            [self.full(goal, gripper)],
            self.full(start, gripper),
            planning_time=planning_time,
            rrt_range=0.1,
            time_step=0.1,
        )
        if res.get("status") != "Success":
            return None
        pos = np.asarray(res["position"], dtype=np.float64)
        pts = [start.copy()] + [p.copy() for p in pos] + [goal.copy()]
        return pts
