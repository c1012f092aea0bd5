"""SAPIEN articulations for the floor plan's hinged doors and sink faucets, and the water stream.

Conventions (the `Door` / `Faucet` docstrings in `echo_data.floorplan`):
- a door is a leaf on a vertical revolute hinge at `Door.hinge`; joint 0 is the hinge angle
  q >= 0 and the leaf's yaw is `closed_yaw + open_sign * q`, so `Door.free_edge(q)` is where
  the leaf's free edge is in the world;
- a faucet lever turns about the vertical axis through `Faucet.pivot`; joint 0 is the lever
  angle a in [0, open_angle], 0 = closed, and the lever points along yaw `Faucet.yaw + a`
  (counter-clockwise opens). The water flows while a > `closed_tolerance`.

Everything here is independent of the robot: it builds bodies from plan data only. In a
physics-only scene (no render system) the visual shapes are skipped, so the same code serves
fast solvability checks and rendered rollouts.
"""

from __future__ import annotations

import math

import numpy as np
import sapien

from echo_data.floorplan import Door, Faucet, Furniture
from echo_data.scene.door_handle import HANDLE_BAR, HANDLE_POST, HANDLE_STANDOFF, door_handle_local

# Door leaf: door opening was measured with a ≈22 kg leaf (docs/SIMULATION_NOTES.md#door-opening).
DOOR_MASS = 22.0  # kg
DOOR_FLOOR_GAP = 0.012  # m between the leaf and the floor (>= 1 cm, or the joint jams)
DOOR_HINGE_GAP = 0.01  # m between the hinge axis and the leaf's hinge-side edge
DOOR_DAMPING = 6.0  # N m s / rad: a released door slows within a second
DOOR_FRICTION = 0.03  # PhysX joint friction coefficient (scales the hinge load): a door stays where left

# Faucet lever.
LEVER_SECTION = 0.02  # m, square cross-section of the lever bar
LEVER_MASS = 0.25  # kg
LEVER_DAMPING = 0.05  # N m s / rad
LEVER_FRICTION = 0.05  # N m: the lever stays where it is left
STATIC_CLEARANCE = 0.01  # m between the lever and any static shape (joints jam: docs/SIMULATION_NOTES.md#articulations)
COLUMN_RADIUS = 0.022  # m, faucet body below the lever hub

# Water stream.
STREAM_MAX_RADIUS = 0.009  # m, fully open
STREAM_MIN_RADIUS = 0.002  # m, barely open
STREAM_LEVELS = 5  # discrete radii (render shapes cannot be rescaled in place)
HIDDEN_Z = -50.0  # where hidden visuals are parked

WOOD = (0.55, 0.38, 0.22)
METAL = (0.75, 0.76, 0.78)
WATER = (0.55, 0.75, 0.95)


def has_render(scene: sapien.Scene) -> bool:
    """True when the scene has a render system (visual shapes can be added)."""
    try:
        scene.get_system("render")
    except RuntimeError:
        return False
    return True


def _quat_z(yaw: float) -> np.ndarray:
    """Quaternion (w, x, y, z) of a rotation by `yaw` about +z."""
    return np.array([math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)])


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def _x_to_z(sign: float) -> np.ndarray:
    """Quaternion that maps the joint's x axis (SAPIEN revolute axis) to sign * z."""
    # rotation about y by -sign*pi/2 takes +x to sign*+z
    a = -sign * math.pi / 2.0
    return np.array([math.cos(a / 2.0), 0.0, math.sin(a / 2.0), 0.0])


def _vertical_revolute(
    link: sapien.wrapper.articulation_builder.LinkBuilder,
    yaw0: float,
    sign: float,
    limits: tuple[float, float],
    damping: float,
) -> None:
    """Make `link`'s joint a revolute about sign * z whose child frame has yaw `yaw0` at q = 0.

    The child frame sits at the parent frame's origin; its x axis points along yaw0 + sign*q.
    """
    axis = _x_to_z(sign)
    link.set_joint_properties(
        "revolute",
        limits=[[limits[0], limits[1]]],
        pose_in_parent=sapien.Pose(q=_quat_mul(_quat_z(yaw0), axis)),
        pose_in_child=sapien.Pose(q=axis),
        damping=damping,
    )


def _fixed_root(builder: sapien.ArticulationBuilder, name: str) -> sapien.wrapper.articulation_builder.LinkBuilder:
    root = builder.create_link_builder()
    root.set_name(name)
    # a shapeless root needs explicit mass properties; it is fixed anyway
    root.set_mass_and_inertia(1.0, sapien.Pose(), [1e-3, 1e-3, 1e-3])
    return root


def build_door(scene: sapien.Scene, door: Door) -> sapien.physx.PhysxArticulation:
    """A door leaf with pull handles on both faces, on a vertical revolute hinge at `door.hinge`.

    The root is fixed at the hinge (z = 0); joint 0 is the hinge angle q in [0, max_angle] with
    the leaf at yaw `closed_yaw + open_sign * q`. Joint damping and friction keep a released
    door where it is. Starts at q = `door.angle`.
    """
    visual = has_render(scene)
    builder = scene.create_articulation_builder()
    root = _fixed_root(builder, f"door_{door.index}_frame")

    leaf = builder.create_link_builder(root)
    leaf.set_name(f"door_{door.index}_leaf")
    leaf.set_joint_name(f"door_{door.index}_hinge")
    _vertical_revolute(leaf, door.closed_yaw, door.open_sign, (0.0, door.max_angle), DOOR_DAMPING)

    length = door.width - DOOR_HINGE_GAP
    height = door.height - DOOR_FLOOR_GAP
    half = np.array([length / 2.0, door.thickness / 2.0, height / 2.0])
    leaf_pose = sapien.Pose([DOOR_HINGE_GAP + length / 2.0, 0.0, DOOR_FLOOR_GAP + height / 2.0])
    density = DOOR_MASS / (length * door.thickness * height)
    leaf.add_box_collision(pose=leaf_pose, half_size=half, density=density)
    if visual:
        leaf.add_box_visual(pose=leaf_pose, half_size=half, material=WOOD, name="leaf")

    bar_half = np.array(HANDLE_BAR) / 2.0
    for face in (1.0, -1.0):
        centre = door_handle_local(door, face)
        leaf.add_box_collision(pose=sapien.Pose(centre), half_size=bar_half, density=2000.0)
        if visual:
            leaf.add_box_visual(pose=sapien.Pose(centre), half_size=bar_half, material=METAL, name="handle")
        # two posts join the bar to the face
        post_len = HANDLE_STANDOFF - bar_half[1]
        post_half = np.array([HANDLE_POST / 2.0, post_len / 2.0, HANDLE_POST / 2.0])
        y_post = face * (door.thickness / 2.0 + post_len / 2.0)
        for dz in (bar_half[2] - HANDLE_POST / 2.0, -bar_half[2] + HANDLE_POST / 2.0):
            pose = sapien.Pose([centre[0], y_post, centre[2] + dz])
            leaf.add_box_collision(pose=pose, half_size=post_half, density=2000.0)
            if visual:
                leaf.add_box_visual(pose=pose, half_size=post_half, material=METAL, name="handle_post")

    builder.set_initial_pose(sapien.Pose([door.hinge[0], door.hinge[1], 0.0]))
    art = builder.build(fix_root_link=True)
    art.name = f"door_{door.index}"
    art.active_joints[0].set_friction(DOOR_FRICTION)
    art.set_root_pose(sapien.Pose([door.hinge[0], door.hinge[1], 0.0]))
    art.set_qpos(np.array([door.angle], dtype=np.float32))
    art.set_qvel(np.zeros(1, dtype=np.float32))
    return art


def lever_tip_world(faucet: Faucet, angle: float) -> np.ndarray:
    """World position of the lever's tip at lever angle `angle` (pure geometry)."""
    yaw = faucet.yaw + angle
    return np.array(
        [
            faucet.pivot[0] + faucet.lever_length * math.cos(yaw),
            faucet.pivot[1] + faucet.lever_length * math.sin(yaw),
            faucet.pivot[2],
        ]
    )


def build_faucet(scene: sapien.Scene, faucet: Faucet, cabinet: Furniture) -> sapien.physx.PhysxArticulation:
    """A faucet: a fixed body (column on the counter, spout) and a lever on a vertical revolute
    joint at `faucet.pivot`, 0 = closed .. `open_angle`; starts at `faucet.angle`.

    Raises ValueError when the lever would pass closer than `STATIC_CLEARANCE` to the counter
    top (a jammed joint makes CloseSink impossible; better to reject the plan).
    """
    lever_bottom = faucet.pivot[2] - LEVER_SECTION / 2.0
    if lever_bottom - cabinet.top_z < STATIC_CLEARANCE:
        raise ValueError(
            f"faucet {faucet.index}: lever bottom {lever_bottom:.3f} m is closer than "
            f"{STATIC_CLEARANCE} m to the counter top {cabinet.top_z:.3f} m"
        )
    visual = has_render(scene)
    builder = scene.create_articulation_builder()
    root = _fixed_root(builder, f"faucet_{faucet.index}_body")
    # root frame at the pivot; the body hangs below it, clear of the lever's sweep
    column_top = -LEVER_SECTION / 2.0 - STATIC_CLEARANCE
    column_len = faucet.pivot[2] + column_top - cabinet.top_z
    if column_len > 0.005:
        column_pose = sapien.Pose([0.0, 0.0, column_top - column_len / 2.0])
        column_half = np.array([COLUMN_RADIUS, COLUMN_RADIUS, column_len / 2.0])
        root.add_box_collision(pose=column_pose, half_size=column_half)
        if visual:
            root.add_box_visual(pose=column_pose, half_size=column_half, material=METAL, name="column")
    if visual:
        # spout: a visual arm from the column to above the spout and a short nozzle
        dx, dy = faucet.spout[0] - faucet.pivot[0], faucet.spout[1] - faucet.pivot[1]
        reach = math.hypot(dx, dy)
        arm_z = min(faucet.spout[2] + 0.03, faucet.pivot[2] + column_top - 0.01) - faucet.pivot[2]
        if reach > 1e-3:
            arm_pose = sapien.Pose([dx / 2.0, dy / 2.0, arm_z], _quat_z(math.atan2(dy, dx)))
            root.add_box_visual(pose=arm_pose, half_size=[reach / 2.0, 0.012, 0.012], material=METAL, name="spout")
        nozzle_h = max(arm_z - (faucet.spout[2] - faucet.pivot[2]), 0.01)
        nozzle_pose = sapien.Pose([dx, dy, arm_z - nozzle_h / 2.0])
        root.add_box_visual(pose=nozzle_pose, half_size=[0.012, 0.012, nozzle_h / 2.0], material=METAL, name="nozzle")

    lever = builder.create_link_builder(root)
    lever.set_name(f"faucet_{faucet.index}_lever")
    lever.set_joint_name(f"faucet_{faucet.index}_joint")
    _vertical_revolute(lever, faucet.yaw, 1.0, (0.0, faucet.open_angle), LEVER_DAMPING)
    bar_half = np.array([faucet.lever_length / 2.0, LEVER_SECTION / 2.0, LEVER_SECTION / 2.0])
    bar_pose = sapien.Pose([faucet.lever_length / 2.0, 0.0, 0.0])
    density = LEVER_MASS / (faucet.lever_length * LEVER_SECTION**2)
    lever.add_box_collision(pose=bar_pose, half_size=bar_half, density=density)
    if visual:
        lever.add_box_visual(pose=bar_pose, half_size=bar_half, material=METAL, name="lever")
        lever.add_cylinder_visual(
            pose=sapien.Pose(q=_x_to_z(1.0)), radius=COLUMN_RADIUS, half_length=LEVER_SECTION / 2.0,
            material=METAL, name="hub",
        )

    pivot_pose = sapien.Pose(list(faucet.pivot))
    builder.set_initial_pose(pivot_pose)
    art = builder.build(fix_root_link=True)
    art.name = f"faucet_{faucet.index}"
    art.active_joints[0].set_friction(LEVER_FRICTION)
    art.set_root_pose(pivot_pose)
    art.set_qpos(np.array([faucet.angle], dtype=np.float32))
    art.set_qvel(np.zeros(1, dtype=np.float32))
    return art


class WaterStream:
    """The visible water column under a faucet's spout; its radius follows the lever angle.

    Visual only (no collision shapes), so it never disturbs physics. Render shapes cannot be
    rescaled in place, so `STREAM_LEVELS` cylinders of increasing radius are built and the
    one closest to the current flow is moved under the spout; the others are parked out of
    sight. In a scene without a render system only the state (`flowing`, `flow`, `radius`)
    is tracked.
    """

    def __init__(self, scene: sapien.Scene, faucet: Faucet, bottom_z: float | None = None) -> None:
        """`bottom_z`: where the stream ends (the basin / counter top); default 0.25 m below the spout."""
        self.faucet = faucet
        self.top_z = float(faucet.spout[2])
        self.bottom_z = float(max(0.0, self.top_z - 0.25) if bottom_z is None else bottom_z)
        if self.bottom_z >= self.top_z:
            raise ValueError(f"faucet {faucet.index}: stream bottom {self.bottom_z} is not below the spout")
        self.radii = np.linspace(STREAM_MIN_RADIUS, STREAM_MAX_RADIUS, STREAM_LEVELS)
        self._entities: list[sapien.Entity] = []
        if has_render(scene):
            half_len = (self.top_z - self.bottom_z) / 2.0
            material = sapien.render.RenderMaterial(base_color=(*WATER, 1.0), roughness=0.1, metallic=0.0)
            for k, r in enumerate(self.radii):
                body = sapien.render.RenderBodyComponent()
                shape = sapien.render.RenderShapeCylinder(float(r), half_len, material)
                shape.local_pose = sapien.Pose(q=_x_to_z(1.0))  # cylinder axis x -> vertical
                body.attach(shape)
                entity = sapien.Entity()
                entity.name = f"water_{faucet.index}_{k}"
                entity.add_component(body)
                entity.set_pose(sapien.Pose([0.0, 0.0, HIDDEN_Z]))
                scene.add_entity(entity)
                self._entities.append(entity)
        self.angle = float("nan")
        self.flow = 0.0
        self.level = -1
        self.update(faucet.angle)

    @property
    def flowing(self) -> bool:
        """True while the lever is open beyond the closed tolerance."""
        return self.angle > self.faucet.closed_tolerance

    @property
    def radius(self) -> float:
        """Radius of the shown stream (0 when off)."""
        return float(self.radii[self.level]) if self.level >= 0 else 0.0

    def update(self, angle: float) -> None:
        """Follow the lever: flow fraction 0..1 over (closed_tolerance, open_angle]."""
        self.angle = float(angle)
        tol, full = self.faucet.closed_tolerance, self.faucet.open_angle
        if self.flowing:
            self.flow = float(np.clip((self.angle - tol) / max(full - tol, 1e-6), 0.0, 1.0))
            level = int(round(self.flow * (STREAM_LEVELS - 1)))
        else:
            self.flow = 0.0
            level = -1
        if level == self.level:
            return
        self.level = level
        centre = [self.faucet.spout[0], self.faucet.spout[1], (self.top_z + self.bottom_z) / 2.0]
        for k, entity in enumerate(self._entities):
            entity.set_pose(sapien.Pose(centre if k == level else [0.0, 0.0, HIDDEN_Z]))

    def visible_extent(self) -> tuple[np.ndarray, np.ndarray] | None:
        """World AABB (min, max) of the shown stream, or None when off / not rendered."""
        if self.level < 0 or not self._entities:
            return None
        body = self._entities[self.level].find_component_by_type(sapien.render.RenderBodyComponent)
        lo, hi = body.compute_global_aabb_tight()
        return np.asarray(lo), np.asarray(hi)
