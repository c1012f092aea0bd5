"""Generate the Fetch-like mobile manipulator's URDF/SRDF from primitives.

Why generated: the robot is the project's own (no meshes, no third-party assets), and the
mobile and fixed-base variants must stay consistent. Run `python -m echo_data.robot.urdf` to
rewrite the committed files under assets/robots/:

- fetchlike.urdf        SAPIEN robot: a fixed root, a virtual planar base (x, y prismatic and a
                        continuous yaw joint on light links), base, torso lift, head pan/tilt with
                        an RGB-D camera link, 7-DOF arm, parallel gripper, wrist camera link.
- fetchlike_arm.urdf    the same robot rooted at base_link with no virtual base and no continuous
                        joint, for mplib (set the base with `planner.set_base_pose`).
- fetchlike.srdf / fetchlike_arm.srdf   disabled collision pairs: every parent/child pair
                        ("Adjacent") and pairs that overlap by design ("Default").

Dimensions and limits follow the real Fetch (base radius 0.28 m, torso 0..0.386 m, shoulder at
0.726 m + torso, head camera at about 1.06 m + torso); continuous arm rolls get +-pi.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

ASSET_DIR = Path(__file__).resolve().parents[2] / "assets" / "robots"
URDF_PATH = ASSET_DIR / "fetchlike.urdf"
SRDF_PATH = ASSET_DIR / "fetchlike.srdf"
ARM_URDF_PATH = ASSET_DIR / "fetchlike_arm.urdf"
ARM_SRDF_PATH = ASSET_DIR / "fetchlike_arm.srdf"

BASE_RADIUS = 0.28
BASE_HEIGHT = 0.36
TORSO_RANGE = (0.0, 0.386)
FINGER_RANGE = (0.0, 0.05)  # per finger; opening = sum of both (0 .. 0.1 m)

BASE_JOINTS = ("root_x_joint", "root_y_joint", "root_yaw_joint")
TORSO_JOINT = "torso_lift_joint"
HEAD_JOINTS = ("head_pan_joint", "head_tilt_joint")
ARM_JOINTS = (
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "upperarm_roll_joint",
    "elbow_flex_joint",
    "forearm_roll_joint",
    "wrist_flex_joint",
    "wrist_roll_joint",
)
FINGER_JOINTS = ("l_gripper_finger_joint", "r_gripper_finger_joint")
FINGER_LINKS = ("l_gripper_finger_link", "r_gripper_finger_link")
EE_LINK = "gripper_link"  # origin = tool centre point between the finger pads, +x = approach
HEAD_CAMERA_LINK = "head_camera_link"
WRIST_CAMERA_LINK = "wrist_camera_link"

ARM_LIMITS: dict[str, tuple[float, float]] = {
    "shoulder_pan_joint": (-1.6056, 1.6056),
    "shoulder_lift_joint": (-1.221, 1.518),
    "upperarm_roll_joint": (-math.pi, math.pi),
    "elbow_flex_joint": (-2.251, 2.251),
    "forearm_roll_joint": (-math.pi, math.pi),
    "wrist_flex_joint": (-2.16, 2.16),
    "wrist_roll_joint": (-math.pi, math.pi),
}
HEAD_LIMITS = {"head_pan_joint": (-1.57, 1.57), "head_tilt_joint": (-0.76, 1.45)}

GREY = (0.55, 0.55, 0.58)
WHITE = (0.9, 0.9, 0.9)
BLUE = (0.15, 0.3, 0.65)
DARK = (0.12, 0.12, 0.14)


@dataclass
class Shape:
    kind: str  # box | cylinder (along local z) | sphere
    xyz: tuple[float, float, float]
    dims: tuple[float, ...]  # box full sizes; cylinder (radius, length); sphere (radius,)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    color: tuple[float, float, float] = GREY
    collide: bool = True


@dataclass
class Link:
    name: str
    mass: float
    shapes: list[Shape] = field(default_factory=list)


@dataclass
class Joint:
    name: str
    kind: str  # fixed | prismatic | revolute | continuous
    parent: str
    child: str
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    limits: tuple[float, float] | None = None
    effort: float = 200.0
    velocity: float = 2.0
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


def _xcyl(x0: float, x1: float, r: float, color: tuple[float, float, float] = GREY) -> Shape:
    """A cylinder along the link's x axis from x0 to x1 (arm segments)."""
    return Shape("cylinder", ((x0 + x1) / 2.0, 0.0, 0.0), (r, x1 - x0), (0.0, math.pi / 2.0, 0.0), color)


def robot_parts() -> tuple[list[Link], list[Joint]]:
    """Links and joints of the mobile robot (base_link downwards is shared with the arm variant)."""
    links = [
        Link("root_link", 1.0),
        Link("base_x_link", 1.0),
        Link("base_y_link", 1.0),
        Link(
            "base_link",
            60.0,
            [
                Shape("cylinder", (0.0, 0.0, 0.01 + BASE_HEIGHT / 2.0), (BASE_RADIUS, BASE_HEIGHT), color=WHITE),
                Shape("box", (0.2, 0.0, 0.3), (0.1, 0.25, 0.08), color=BLUE, collide=False),
            ],
        ),
        Link(
            "torso_lift_link",
            10.0,
            [
                Shape("box", (-0.06, 0.0, 0.12), (0.24, 0.32, 0.96), color=WHITE),
                Shape("box", (0.0, 0.0, 0.585), (0.12, 0.12, 0.03), color=DARK, collide=False),
            ],
        ),
        Link("head_pan_link", 1.0, [Shape("cylinder", (0.0, 0.0, 0.03), (0.06, 0.05), color=DARK)]),
        Link("head_tilt_link", 1.5, [Shape("box", (-0.03, 0.0, 0.0), (0.14, 0.26, 0.1), color=WHITE)]),
        Link(HEAD_CAMERA_LINK, 0.05, [Shape("box", (0.0, 0.0, 0.0), (0.02, 0.18, 0.03), color=DARK, collide=False)]),
        Link("shoulder_pan_link", 2.0, [Shape("cylinder", (0.0, 0.0, 0.03), (0.06, 0.12), color=BLUE)]),
        Link("shoulder_lift_link", 2.0, [_xcyl(0.0, 0.2, 0.055)]),
        Link("upperarm_roll_link", 2.0, [_xcyl(0.0, 0.12, 0.05, BLUE)]),
        Link("elbow_flex_link", 2.0, [_xcyl(0.0, 0.18, 0.05)]),
        Link("forearm_roll_link", 1.5, [_xcyl(0.0, 0.11, 0.045, BLUE)]),
        Link("wrist_flex_link", 1.5, [_xcyl(0.0, 0.125, 0.045)]),
        Link("wrist_roll_link", 0.8, [_xcyl(0.0, 0.05, 0.045, DARK)]),
        # palm behind the pads; the link origin is the tool centre point (TCP)
        Link(EE_LINK, 0.8, [Shape("box", (-0.079, 0.0, 0.0), (0.074, 0.13, 0.06), color=DARK)]),
        Link(
            "l_gripper_finger_link",
            0.1,
            [Shape("box", (-0.017, 0.006, 0.0), (0.05, 0.012, 0.024), color=GREY)],
        ),
        Link(
            "r_gripper_finger_link",
            0.1,
            [Shape("box", (-0.017, -0.006, 0.0), (0.05, 0.012, 0.024), color=GREY)],
        ),
        Link(WRIST_CAMERA_LINK, 0.02, [Shape("box", (0.0, 0.0, 0.0), (0.02, 0.04, 0.015), color=DARK, collide=False)]),
    ]
    big = (-1000.0, 1000.0)
    joints = [
        Joint("root_x_joint", "prismatic", "root_link", "base_x_link", axis=(1, 0, 0), limits=big, effort=1e6, velocity=1.0),
        Joint("root_y_joint", "prismatic", "base_x_link", "base_y_link", axis=(0, 1, 0), limits=big, effort=1e6, velocity=1.0),
        Joint("root_yaw_joint", "continuous", "base_y_link", "base_link", axis=(0, 0, 1), effort=1e6, velocity=1.5),
        Joint(TORSO_JOINT, "prismatic", "base_link", "torso_lift_link", xyz=(-0.086875, 0.0, 0.37743), axis=(0, 0, 1), limits=TORSO_RANGE, effort=450.0, velocity=0.1),
        Joint("head_pan_joint", "revolute", "torso_lift_link", "head_pan_link", xyz=(0.053125, 0.0, 0.603001), limits=HEAD_LIMITS["head_pan_joint"], effort=0.32, velocity=1.57),
        Joint("head_tilt_joint", "revolute", "head_pan_link", "head_tilt_link", xyz=(0.14253, 0.0, 0.057999), axis=(0, 1, 0), limits=HEAD_LIMITS["head_tilt_joint"], effort=0.68, velocity=1.57),
        Joint("head_camera_joint", "fixed", "head_tilt_link", HEAD_CAMERA_LINK, xyz=(0.055, 0.0, 0.0225)),
        Joint("shoulder_pan_joint", "revolute", "torso_lift_link", "shoulder_pan_link", xyz=(0.119525, 0.0, 0.34858), limits=ARM_LIMITS["shoulder_pan_joint"], effort=33.82, velocity=1.256),
        Joint("shoulder_lift_joint", "revolute", "shoulder_pan_link", "shoulder_lift_link", xyz=(0.117, 0.0, 0.06), axis=(0, 1, 0), limits=ARM_LIMITS["shoulder_lift_joint"], effort=131.76, velocity=1.454),
        Joint("upperarm_roll_joint", "revolute", "shoulder_lift_link", "upperarm_roll_link", xyz=(0.219, 0.0, 0.0), axis=(1, 0, 0), limits=ARM_LIMITS["upperarm_roll_joint"], effort=76.94, velocity=1.571),
        Joint("elbow_flex_joint", "revolute", "upperarm_roll_link", "elbow_flex_link", xyz=(0.133, 0.0, 0.0), axis=(0, 1, 0), limits=ARM_LIMITS["elbow_flex_joint"], effort=66.18, velocity=1.521),
        Joint("forearm_roll_joint", "revolute", "elbow_flex_link", "forearm_roll_link", xyz=(0.197, 0.0, 0.0), axis=(1, 0, 0), limits=ARM_LIMITS["forearm_roll_joint"], effort=29.35, velocity=1.571),
        Joint("wrist_flex_joint", "revolute", "forearm_roll_link", "wrist_flex_link", xyz=(0.1245, 0.0, 0.0), axis=(0, 1, 0), limits=ARM_LIMITS["wrist_flex_joint"], effort=25.7, velocity=2.268),
        Joint("wrist_roll_joint", "revolute", "wrist_flex_link", "wrist_roll_link", xyz=(0.1385, 0.0, 0.0), axis=(1, 0, 0), limits=ARM_LIMITS["wrist_roll_joint"], effort=7.36, velocity=2.268),
        Joint("gripper_axis", "fixed", "wrist_roll_link", EE_LINK, xyz=(0.16645, 0.0, 0.0)),
        Joint("l_gripper_finger_joint", "prismatic", EE_LINK, "l_gripper_finger_link", axis=(0, 1, 0), limits=FINGER_RANGE, effort=100.0, velocity=0.1),
        Joint("r_gripper_finger_joint", "prismatic", EE_LINK, "r_gripper_finger_link", axis=(0, -1, 0), limits=FINGER_RANGE, effort=100.0, velocity=0.1),
        Joint("wrist_camera_joint", "fixed", EE_LINK, WRIST_CAMERA_LINK, xyz=(-0.075, 0.0, 0.045)),
    ]
    return links, joints


# Pairs that overlap or touch by construction and can never collide meaningfully.
DESIGN_PAIRS: tuple[tuple[str, str], ...] = (
    ("base_link", "shoulder_pan_link"),
    ("torso_lift_link", "shoulder_lift_link"),
    ("torso_lift_link", "head_tilt_link"),
    ("base_link", "head_pan_link"),
    ("head_pan_link", "shoulder_pan_link"),
    ("shoulder_pan_link", "upperarm_roll_link"),
    ("shoulder_lift_link", "elbow_flex_link"),
    ("upperarm_roll_link", "forearm_roll_link"),
    ("elbow_flex_link", "wrist_flex_link"),
    ("forearm_roll_link", "wrist_roll_link"),
    ("wrist_flex_link", EE_LINK),
    ("wrist_flex_link", "l_gripper_finger_link"),
    ("wrist_flex_link", "r_gripper_finger_link"),
    ("wrist_roll_link", "l_gripper_finger_link"),
    ("wrist_roll_link", "r_gripper_finger_link"),
    ("l_gripper_finger_link", "r_gripper_finger_link"),
)


def _f(v: float) -> str:
    return f"{v:.6g}"


def _vec(v: tuple[float, ...]) -> str:
    return " ".join(_f(x) for x in v)


def _geometry(s: Shape) -> str:
    if s.kind == "box":
        return f'<box size="{_vec(s.dims)}"/>'
    if s.kind == "cylinder":
        return f'<cylinder radius="{_f(s.dims[0])}" length="{_f(s.dims[1])}"/>'
    return f'<sphere radius="{_f(s.dims[0])}"/>'


def _inertia(link: Link) -> str:
    """Box-ish inertia from the first collision shape (gravity is off; it only shapes dynamics)."""
    m = link.mass
    dims = next((s for s in link.shapes if s.collide), None)
    if dims is None:
        ix = iy = iz = max(1e-4, 0.01 * m)
    else:
        if dims.kind == "box":
            a, b, c = dims.dims
        elif dims.kind == "cylinder":
            a = b = 2 * dims.dims[0]
            c = dims.dims[1]
        else:
            a = b = c = 2 * dims.dims[0]
        ix, iy, iz = m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12
    return (
        f'<inertial><origin xyz="0 0 0"/><mass value="{_f(m)}"/>'
        f'<inertia ixx="{_f(ix)}" ixy="0" ixz="0" iyy="{_f(iy)}" iyz="0" izz="{_f(iz)}"/></inertial>'
    )


def _link_xml(link: Link) -> str:
    parts = [f'  <link name="{link.name}">', "    " + _inertia(link)]
    for i, s in enumerate(link.shapes):
        origin = f'<origin xyz="{_vec(s.xyz)}" rpy="{_vec(s.rpy)}"/>'
        parts.append(
            f'    <visual>{origin}<geometry>{_geometry(s)}</geometry>'
            f'<material name="{link.name}_{i}"><color rgba="{_vec(s.color)} 1"/></material></visual>'
        )
        if s.collide:
            parts.append(f"    <collision>{origin}<geometry>{_geometry(s)}</geometry></collision>")
    parts.append("  </link>")
    return "\n".join(parts)


def _joint_xml(j: Joint) -> str:
    s = [f'  <joint name="{j.name}" type="{j.kind}">', f'    <parent link="{j.parent}"/>', f'    <child link="{j.child}"/>']
    s.append(f'    <origin xyz="{_vec(j.xyz)}" rpy="{_vec(j.rpy)}"/>')
    if j.kind != "fixed":
        s.append(f'    <axis xyz="{_vec(j.axis)}"/>')
        if j.limits is not None:
            s.append(f'    <limit lower="{_f(j.limits[0])}" upper="{_f(j.limits[1])}" effort="{_f(j.effort)}" velocity="{_f(j.velocity)}"/>')
        else:
            s.append(f'    <limit effort="{_f(j.effort)}" velocity="{_f(j.velocity)}"/>')
    s.append("  </joint>")
    return "\n".join(s)


def urdf_text(fixed_base: bool = False) -> str:
    """URDF of the mobile robot, or of the fixed-base planning variant rooted at base_link."""
    links, joints = robot_parts()
    if fixed_base:
        drop = {"root_link", "base_x_link", "base_y_link"}
        links = [ln for ln in links if ln.name not in drop]
        joints = [j for j in joints if j.name not in BASE_JOINTS]
    name = "fetchlike_arm" if fixed_base else "fetchlike"
    body = "\n".join([_link_xml(ln) for ln in links] + [_joint_xml(j) for j in joints])
    return f'<?xml version="1.0"?>\n<!-- generated by echo_data/robot/urdf.py; do not edit -->\n<robot name="{name}">\n{body}\n</robot>\n'


def disabled_pairs(fixed_base: bool = False) -> list[tuple[str, str, str]]:
    """(link1, link2, reason) for every adjacent pair and every overlapping-by-design pair."""
    links, joints = robot_parts()
    names = {ln.name for ln in links}
    if fixed_base:
        names -= {"root_link", "base_x_link", "base_y_link"}
    pairs = [(j.parent, j.child, "Adjacent") for j in joints if j.parent in names and j.child in names]
    pairs += [(a, b, "Default") for a, b in DESIGN_PAIRS]
    return pairs


def srdf_text(fixed_base: bool = False) -> str:
    name = "fetchlike_arm" if fixed_base else "fetchlike"
    rows = [f'  <disable_collisions link1="{a}" link2="{b}" reason="{r}"/>' for a, b, r in disabled_pairs(fixed_base)]
    return f'<?xml version="1.0"?>\n<!-- generated by echo_data/robot/urdf.py; do not edit -->\n<robot name="{name}">\n' + "\n".join(rows) + "\n</robot>\n"


def write_assets(out_dir: Path = ASSET_DIR) -> list[Path]:
    """Write the four robot files; returns their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = {
        out_dir / URDF_PATH.name: urdf_text(False),
        out_dir / SRDF_PATH.name: srdf_text(False),
        out_dir / ARM_URDF_PATH.name: urdf_text(True),
        out_dir / ARM_SRDF_PATH.name: srdf_text(True),
    }
    for p, text in files.items():
        p.write_text(text)
    return list(files)


if __name__ == "__main__":
    for path in write_assets():
        print(path)
