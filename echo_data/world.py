"""One simulated episode world: the SAPIEN scene of a floor plan, the robot, and the clock.

`World` is what experts and the rollout drive: `step(action)` applies one control action and
advances physics by physics_hz / control_hz sub-steps; `observe()` renders the robot cameras.
One `sapien.render.RenderSystem` stays alive for the whole process so the pipeline build
(3.5-30 s on lavapipe) is paid once, not per episode.

Door grasps are a rule of the world, not of an expert: a gripper commanded closed whose two
fingers both press on a door leaf (its handle bar) holds the leaf with a stiff drive, as a
firm hand would (a heavy leaf slips out of a purely frictional two-finger grasp); the hold ends
as soon as the gripper is commanded open. So the 12-float action is all it takes to replay an
episode: nothing an expert does outside its actions changes the physics.

Object grasps are physical (finger friction alone) unless the recipe says `robot.grasp: magic`:
then Habitat's rule holds (Szot et al. 2021, Habitat 2.0, as used by M3 and by the paper's skills):
while the gripper is commanded closed and holds nothing, the object whose centre is nearest the
tool-centre point attaches when that centre is within MAGIC_GRASP_DIST of it. habitat-lab's
`MagicGraspAction._grasp` (habitat/tasks/rearrange/actions/grip_actions.py) compares the
end-effector position with the objects' positions against `grasp_thresh_dist`, 0.15 m by default
(`ArmActionConfig`, habitat/config/default_structured_configs.py), and releases when the grip
action opens. Habitat snaps the object into the hand; here it is held where it is (the same stiff
drive as a door leaf): no teleport, so physics stays continuous and a replay stays exact.
Habitat's rule covers articulated handles the same way (its grasp action snaps to a handle
marker within the same distance), so under `robot.grasp: magic` a closing gripper also holds
the door leaf whose swing-side handle bar centre is within MAGIC_GRASP_DIST of the TCP: the
paper-comparable OpenDoor.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import sapien

from echo_data.episode import EpisodeSpec
from echo_data.floorplan import FloorPlan
from echo_data.recipe import Recipe
from echo_data.robot.robot import Robot

if TYPE_CHECKING:
    from echo_data.robot.planner import ArmPlanner
    from echo_data.scene.build import SceneHandles
    from echo_data.scene.nav import NavGrid

_RENDER_KEEPALIVE: list[Any] = []  # one RenderSystem per process, never freed
# A gripper commanded to open less than this (m) is closing on what it touches.
GRIP_CLOSED = 0.02
MAGIC_GRASP_DIST = 0.15  # m: Habitat's grasp_thresh_dist (see the module docstring)

# Builds the plan's SAPIEN bodies into a scene (default `echo_data.scene.build.build_scene`).
SceneBuilder = Callable[[sapien.Scene, FloorPlan, Recipe], "SceneHandles"]


def keep_render_alive() -> None:
    """Hold one RenderSystem so later scenes reuse the Vulkan device and compiled pipelines."""
    if not _RENDER_KEEPALIVE:
        _RENDER_KEEPALIVE.append(sapien.render.RenderSystem())


def _default_builder(scene: sapien.Scene, plan: FloorPlan, recipe: Recipe) -> SceneHandles:
    from echo_data.scene.build import build_scene

    return build_scene(scene, plan, recipe)


class World:
    """The SAPIEN world of one episode: every field is declared here and read directly by the
    experts, the environment and the success tests.

    `builder` replaces `build_scene` (tests add bodies to the default scene). After `close()`
    the scene, robot and handles are released (reading them raises AttributeError).
    """

    spec: EpisodeSpec
    """The sampled episode: plan, start pose, chain of skill calls, sound events, seeds."""
    recipe: Recipe
    """The recipe the episode was sampled from (robot rates, cameras, step limits)."""
    plan: FloorPlan
    """`spec.plan`: rooms, walls, doors, furniture, faucets, objects at their initial poses."""
    render: bool
    """Whether the scene has a render system (cameras observe); physics alone otherwise."""
    scene: sapien.Scene
    """The SAPIEN scene holding the apartment and the robot."""
    control_hz: int
    """Control steps per second (one `step` applies one action)."""
    substeps: int
    """Physics steps per control step (physics_hz // control_hz)."""
    handles: SceneHandles
    """The scene's bodies by role: objects by name, door and faucet articulations by index, water, statics."""
    robot: Robot
    """The mobile manipulator, placed at `spec.start`."""
    steps: int
    """Control steps taken so far."""
    receptacles: dict[str, int]
    """Object name -> furniture index it rests on now: the plan's at the start, updated by Place."""
    arm_planner: ArmPlanner | None
    """The episode's arm motion planner, made on first use by `echo_data.skills.arm.arm_planner`."""
    closed: bool
    """`close()` has released the scene."""
    handover_stops: dict[int, tuple[float, float, float] | None]
    """Chain index -> the base pose the Navigate expert of that entry stops at instead of its own
    goal (`build --handover-from`: a learner's recorded hand-over); the expert sets an entry to
    None when its pose is no usable cell (and keeps its own goal). Empty: none given."""

    def __init__(self, spec: EpisodeSpec, recipe: Recipe, render: bool = True, builder: SceneBuilder | None = None) -> None:
        self.closed = False
        self.spec = spec
        self.recipe = recipe
        self.plan = spec.plan
        cams = (recipe.robot.head_camera, recipe.robot.wrist_camera)
        render = render and any(c.rgb or c.depth for c in cams)  # no camera: no render system, no lights (the URDF loader still wants a Vulkan device)
        self.render = render
        if render:
            keep_render_alive()
            self.scene = sapien.Scene()
        else:
            self.scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
        cfg = recipe.robot
        self.control_hz = cfg.control_hz
        self.substeps = cfg.physics_hz // cfg.control_hz
        self.scene.set_timestep(1.0 / cfg.physics_hz)
        if render:
            from echo_data.scene.lighting import add_lights

            add_lights(self.scene, self.plan, flat=recipe.scene.look == "flat")
        self.handles = (builder or _default_builder)(self.scene, self.plan, recipe)
        self.robot = Robot(self.scene, cfg)
        self.robot.set_base_pose(*spec.start)
        self._nav: NavGrid | None = None
        self.arm_planner = None
        self._door_hold: Any = None  # the drive (a PhysxDriveComponent) holding a door leaf in the gripper
        self._object_hold: Any = None  # the drive holding an object by the magic grasp (robot.grasp: magic)
        self.magic_grasp = cfg.grasp == "magic"
        self.steps = 0
        # Where each object rests now (furniture index); Place updates it after a success.
        self.receptacles: dict[str, int] = {o.name: o.receptacle for o in self.plan.objects}
        self.handover_stops = {}

    # ------------------------------------------------------------------ simulation
    def step(self, action: np.ndarray) -> None:
        """Apply one control action and advance physics by one control period."""
        self.robot.apply(action)
        if self._door_hold is not None and not self._gripper_closed():
            detach(self._door_hold)
            self._door_hold = None
        if self._object_hold is not None and not self._gripper_closed():
            detach(self._object_hold)
            self._object_hold = None
            self.robot.attached = None
        for _ in range(self.substeps):
            self.robot.before_substep()
            self.scene.step()
        self.handles.update()
        if self._door_hold is None and self._gripper_closed():
            self._grasp_door()
        if self.magic_grasp and self._object_hold is None and self._gripper_closed():
            self._grasp_magic()
        self.steps += 1

    def _gripper_closed(self) -> bool:
        return float(self.robot.applied_action()[11]) < GRIP_CLOSED  # the drives' command, noise included

    def _grasp_door(self) -> None:
        """Hold a door leaf both fingers press on, or under the magic grasp the leaf whose
        swing-side handle bar centre is within MAGIC_GRASP_DIST of the TCP (module docstring)."""
        if not self.handles.doors:
            return
        left, right = self.robot.finger_contacts()
        for i, art in enumerate(self.handles.doors):
            leaf = art.links[1]
            if (leaf.entity in left and leaf.entity in right) or (self.magic_grasp and self._handle_in_reach(i)):
                self._door_hold = attach(self.scene, self.robot.ee_link, leaf)
                return

    def _handle_in_reach(self, i: int) -> bool:
        """Door i's swing-side handle bar centre lies within MAGIC_GRASP_DIST of the TCP."""
        from echo_data.scene.door_handle import door_handle_world

        door = self.plan.doors[i]
        bar = door_handle_world(door, float(self.handles.doors[i].get_qpos()[0]), door.open_sign)
        return float(np.linalg.norm(bar - np.asarray(self.robot.ee_pose().p, dtype=np.float64))) < MAGIC_GRASP_DIST

    def _grasp_magic(self) -> None:
        """Attach the object nearest the TCP if its centre is within MAGIC_GRASP_DIST (module docstring)."""
        tcp = np.asarray(self.robot.ee_pose().p, dtype=np.float64)
        best: tuple[float, str] | None = None
        for name, entity in self.handles.objects.items():
            d = float(np.linalg.norm(np.asarray(entity.pose.p, dtype=np.float64) - tcp))
            if best is None or d < best[0]:
                best = (d, name)
        if best is None or best[0] >= MAGIC_GRASP_DIST:
            return
        body = self.handles.objects[best[1]].find_component_by_type(sapien.physx.PhysxRigidDynamicComponent)
        if body is None:
            return
        self._object_hold = attach(self.scene, self.robot.ee_link, body)
        self.robot.attached = best[1]

    @property
    def holding_door(self) -> bool:
        """A door leaf is held in the gripper now."""
        return self._door_hold is not None

    def observe(self) -> dict[str, np.ndarray]:
        """Robot camera images (see `Robot.observe`); empty without rendering."""
        return self.robot.observe()

    def settle(self, steps: int = 10) -> None:
        """Hold still for a few control steps (objects come to rest); not recorded."""
        for _ in range(steps):
            self.step(self.robot.rest_action())

    # ------------------------------------------------------------------ queries
    @property
    def nav(self) -> NavGrid:
        """NavGrid of the plan (doors at their initial angles), built lazily."""
        if self._nav is None:
            from echo_data.scene.nav import NavGrid

            self._nav = NavGrid.from_plan(self.plan)
        return self._nav

    def object_entity(self, name: str) -> sapien.Entity:
        return self.handles.objects[name]

    def object_pose(self, name: str) -> sapien.Pose:
        return self.handles.objects[name].pose

    def door_angles(self) -> dict[int, float]:
        """Current hinge angle of every door."""
        return self.handles.door_angles()

    def close(self) -> None:
        """Free the scene (entities, physics); the process-wide render system stays."""
        if self.closed:
            return
        for e in list(self.scene.entities):
            self.scene.remove_entity(e)
        self.closed = True
        self._door_hold = None
        self._object_hold = None
        self.arm_planner = None
        del self.handles, self.robot, self.scene

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def attach(scene: sapien.Scene, ee_link: Any, body: Any) -> Any:
    """A stiff drive that holds `body` where it is relative to the gripper (a firm grasp)."""
    rel = body.entity_pose.inv() * ee_link.entity_pose
    drive = scene.create_drive(ee_link.entity, sapien.Pose(), body.entity, rel)
    for set_axis in (drive.set_drive_property_x, drive.set_drive_property_y, drive.set_drive_property_z):
        set_axis(2.0e4, 2.0e2, 1.0e4)
    drive.set_drive_property_slerp(2.0e2, 2.0e1, 1.0e3)
    drive.set_drive_target(sapien.Pose())
    return drive


def detach(drive: Any) -> None:
    """Remove a drive made by `attach` (a no-op when it is gone already)."""
    entity = drive.entity
    if entity is not None:
        entity.remove_component(drive)
