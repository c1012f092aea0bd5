"""The sections of a recipe (scene, objects, sounds, events, robot and cameras, acoustics,
outputs, experts): one pydantic model each, strict (unknown keys and true/false as numbers are
refused). `echo_data.recipe` assembles them into the `Recipe`; split out so each file has one job.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from echo_data import skill_table
from echo_data.categories import (
    CATEGORIES,
    DISTRACTOR_SHAPES,
    RELOCATION_CATEGORIES,
    Category,
    DistractorShape,
    RelocationCategory,
)

# Apartment layout families (echo_data/scene/layouts.py): rows of rectangular rooms, an L-shaped
# room, a corridor with rooms off it, an open-plan kitchen/living room.
LayoutName = Literal["rows", "l_shape", "corridor", "open_plan"]
LAYOUTS: tuple[LayoutName, ...] = ("rows", "l_shape", "corridor", "open_plan")


MIN_ROOM_SIZE_SPAN = 0.1  # m


def _has_bool(v: Any) -> bool:
    if isinstance(v, bool):
        return True
    if isinstance(v, dict):
        return any(_has_bool(x) for x in v.values())
    if isinstance(v, (list, tuple)):
        return any(_has_bool(x) for x in v)
    return False


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_numbers(cls, v: Any, info: Any) -> Any:
        """YAML's true/false are not numbers: `seed: true` must not become seed 1."""
        field = cls.model_fields.get(info.field_name)
        sub = isinstance(field.annotation, type) and issubclass(field.annotation, BaseModel) if field else False
        if field is not None and not sub and "bool" not in str(field.annotation) and _has_bool(v):
            raise ValueError("expected a number or text, got true/false")
        return v


def _known_materials() -> set[str]:
    """Material names of pyroomacoustics' database (absorption coefficients per octave band)."""
    import pyroomacoustics as pra

    names: set[str] = set()
    for group in pra.materials_data["absorption"].values():
        names |= set(group)
    return names


def _check_range(v: tuple[float, float], name: str = "range") -> tuple[float, float]:
    if v[0] > v[1]:
        raise ValueError(f"{name} must be [low, high] with low <= high, got {list(v)}")
    return v


def _within(v: Any, name: str, lo: float, hi: float, unit: str = "") -> Any:
    """A [low, high] range whose ends lie inside [lo, hi] (`unit` is said after the bounds)."""
    _check_range(v)
    if v[0] < lo or v[1] > hi:
        raise ValueError(f"{name} must lie within [{lo:g}, {hi:g}]{unit}, got {list(v)}")
    return v


class SceneConfig(_Strict):
    """Procedural apartment sampler."""

    rooms: tuple[int, int] = (2, 4)
    room_size: tuple[float, float] = (3.2, 5.0)  # side length range of a room (m)
    wall_height: float = Field(2.5, gt=1.8, le=5.0)
    wall_thickness: float = Field(0.1, gt=0.02, le=0.5)
    doorway_width: float = Field(1.0, ge=0.85, le=1.6)
    door_probability: float = Field(0.6, ge=0.0, le=1.0)  # interior doorway gets a hinged leaf
    furniture_per_room: tuple[int, int] = (1, 3)
    wall_materials: tuple[str, ...] = ("plasterboard", "brickwork", "rough_concrete")
    floor_materials: tuple[str, ...] = ("linoleum_on_concrete", "carpet_cotton", "carpet_thin")
    ceiling_materials: tuple[str, ...] = ("ceiling_plasterboard",)
    furniture_materials: tuple[str, ...] = ("wooden_door",)
    # "textured": procedural textures, per-room style, randomised room lights and sun;
    # "flat": one colour per surface and fixed lights (the cheaper pre-texture look)
    look: Literal["textured", "flat"] = "textured"
    # layout families drawn from per apartment; [rows] alone reproduces the generator as it was
    # before the other families existed, draw for draw
    layouts: tuple[LayoutName, ...] = LAYOUTS
    # floors of kitchens and bathrooms: a floor drawn from `floor_materials` that is soft (a
    # carpet) is replaced by one of these; null keeps the drawn floor (the generator before this key)
    wet_floor_materials: tuple[str, ...] | None = ("ceramic_tiles", "linoleum_on_concrete")

    @field_validator("layouts")
    @classmethod
    def _layouts(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        if not v or len(set(v)) != len(v):
            raise ValueError(f"layouts must name each of {list(LAYOUTS)} at most once, at least one, got {list(v)}")
        return v

    @field_validator("wall_materials", "floor_materials", "ceiling_materials", "furniture_materials", "wet_floor_materials")
    @classmethod
    def _materials(cls, v: tuple[str, ...] | None) -> tuple[str, ...] | None:
        if v is None:
            return v
        if not v:
            raise ValueError("at least one material is required")
        known = _known_materials()
        bad = [m for m in v if m not in known]
        if bad:
            raise ValueError(f"unknown material {bad[0]!r} (see pyroomacoustics.materials_data)")
        return v

    @field_validator("rooms")
    @classmethod
    def _rooms(cls, v: tuple[int, int]) -> tuple[int, int]:
        return _within(v, "rooms", 2, 6)

    @field_validator("room_size")
    @classmethod
    def _room_size(cls, v: tuple[float, float]) -> tuple[float, float]:
        _within(v, "room_size", 2.5, 12.0, " m")
        if v[1] - v[0] < MIN_ROOM_SIZE_SPAN:  # the layouts draw sides strictly inside the range (scene/layouts.py)
            raise ValueError(f"room_size must span at least {MIN_ROOM_SIZE_SPAN} m (high - low), got {list(v)}")
        return v

    @field_validator("furniture_per_room")
    @classmethod
    def _fpr(cls, v: tuple[int, int]) -> tuple[int, int]:
        return _within(v, "furniture_per_room", 0, 6)


class ObjectsConfig(_Strict):
    """Sounding targets and silent clutter."""

    targets: tuple[RelocationCategory, ...] = RELOCATION_CATEGORIES
    distractors: tuple[int, int] = (1, 3)
    distractor_shapes: tuple[DistractorShape, ...] = DISTRACTOR_SHAPES
    # each instance drawn at its own size within its category's range (scene/objects.py
    # SIZE_RANGES); false: every instance at the category's base size (before this key)
    size_variants: bool = True

    @field_validator("distractors")
    @classmethod
    def _d(cls, v: tuple[int, int]) -> tuple[int, int]:
        return _within(v, "distractors", 0, 12)

    @field_validator("targets", "distractor_shapes")
    @classmethod
    def _no_repeats(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        if len(set(v)) != len(v):
            raise ValueError(f"each name at most once, got {list(v)}")
        return v

    @model_validator(mode="after")
    def _shapes_for_distractors(self) -> ObjectsConfig:
        if self.distractors[1] > 0 and not self.distractor_shapes:
            raise ValueError(f"distractor_shapes is empty but distractors asks for up to {self.distractors[1]} (give shapes or distractors: [0, 0])")
        return self


class SoundsConfig(_Strict):
    """Sound library: the built-in synthesised instances and/or the user's WAV folders."""

    builtin: bool = True
    folders: dict[Category, str] = Field(default_factory=dict)
    folder_test_fraction: float = Field(0.3, ge=0.0, lt=1.0)
    # Each event of a train (or val) episode that would play a built-in train instance plays a
    # fresh synthesised one instead, drawn from the episode's seed (`episode.fresh_sound_seed`):
    # thousands of training voices instead of 77, so a learner hears the category, not the voices.
    # Test episodes keep the library's held-out test instances.
    fresh_train_instances: bool = False


class EventsConfig(_Strict):
    """Which sound events happen, how often, and in which order they must be resolved."""

    categories: dict[Category, float] = Field(
        default_factory=lambda: {c: 1.0 for c in CATEGORIES}
    )
    # Multi-event priority rule: the category earlier in this list is resolved first.
    priority: tuple[Category, ...] = (
        "sink",
        "doorbell",
        "alarm",
        "phone",
        "furby",
    )

    @field_validator("categories")
    @classmethod
    def _weights(cls, v: dict[str, float]) -> dict[str, float]:
        if not all(math.isfinite(w) for w in v.values()):
            raise ValueError("category weights must be finite numbers")
        if any(w < 0 for w in v.values()) or sum(v.values()) <= 0:
            raise ValueError("category weights must be >= 0 with a positive sum")
        return v

    @field_validator("priority")
    @classmethod
    def _prio(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        if sorted(v) != sorted(CATEGORIES):
            raise ValueError(f"priority must list each of {list(CATEGORIES)} exactly once")
        return v


class CameraConfig(_Strict):
    width: int = Field(128, ge=16, le=1024)
    height: int = Field(128, ge=16, le=1024)
    fov_deg: float = Field(70.0, gt=10.0, lt=170.0)
    rgb: bool = True
    depth: bool = True


class RobotConfig(_Strict):
    """Robot, cameras, rates and step limits."""

    physics_hz: int = Field(100, ge=50, le=1000)
    control_hz: int = Field(10, ge=1, le=50)
    head_camera: CameraConfig = CameraConfig()
    wrist_camera: CameraConfig = CameraConfig(rgb=False)
    # "physical": objects stay in the hand by finger friction alone; "magic": Habitat's rule, the
    # object nearest the gripper attaches when the gripper closes within 15 cm of it (echo_data.world).
    grasp: Literal["physical", "magic"] = "physical"
    max_steps: dict[str, int] = Field(
        default_factory=skill_table.default_max_steps
    )
    # The form a policy acts in by default in `EchoDataEnv` (its `action_mode`):
    # "joint" = `action` (12: base, torso, 7 arm joint targets, gripper opening),
    # "ee_delta" = `action.ee` (11: base, torso, TCP change in the base frame, binary gripper).
    # The dataset stores both forms either way (docs/action_spaces.md).
    action_space: Literal["joint", "ee_delta"] = "joint"

    @field_validator("max_steps")
    @classmethod
    def _max_steps(cls, v: dict[str, int]) -> dict[str, int]:
        for k, n in v.items():
            if k not in skill_table.SKILLS:
                raise ValueError(f"max_steps: unknown skill {k!r} (skills: {', '.join(skill_table.SKILLS)})")
            if not 1 <= n <= 100_000:
                raise ValueError(f"max_steps.{k} must lie within [1, 100000], got {n}")
        return v

    @model_validator(mode="after")
    def _rates(self) -> RobotConfig:
        if self.physics_hz % self.control_hz:
            raise ValueError(f"physics_hz ({self.physics_hz}) must be a multiple of control_hz ({self.control_hz})")
        return self


class AcousticsConfig(_Strict):
    """Room acoustics and binaural rendering."""

    sample_rate: int = Field(16000, ge=8000, le=48000)
    rir_seconds: float = Field(0.5, gt=0.05, le=3.0)
    ism_order: int = Field(3, ge=0, le=12)
    rays: int = Field(2000, ge=0, le=200000)
    scattering: float = Field(0.3, ge=0.0, le=1.0)
    air_absorption: bool = True
    hrtf: Literal["kemar", "sphere"] = "kemar"
    grid: float = Field(0.5, gt=0.05, le=2.0)  # receiver cache grid (m)
    yaws: int = Field(72, ge=1, le=360)  # head-yaw bins per grid point (RIRs interpolated between two)
    closed_door_loss_db: float = Field(25.0, ge=0.0, le=80.0)
    ear_height: float = Field(1.2, gt=0.2, le=2.0)
    mel_bands: int = Field(64, ge=8, le=256)
    # calibration: a WAV sample of 1.0 is this sound pressure level (see acoustics.levels)
    full_scale_db_spl: float = Field(120.0, ge=90.0, le=160.0)
    noise_floor_dba: float = Field(30.0, ge=0.0, le=70.0)  # room noise bed in dB(A); 0 = none


class OutputsConfig(_Strict):
    """What the dataset stores and how it is cut into shards."""

    episodes_per_shard: int = Field(16, ge=1, le=10000)
    observations: tuple[Literal["head_rgb", "head_depth", "wrist_depth", "spectrogram", "mel"], ...] = (
        "head_rgb",
        "head_depth",
        "wrist_depth",
        "spectrogram",
        "mel",
    )
    planner_export: bool = True
    # End every episode after its first `max_frames` control steps (None: whole episodes). The
    # experts still act, so the stored frames are exactly the first frames of the full episode;
    # a cut episode is complete, not a failure, and is marked `truncated_at` (README, "Episodes cut
    # by outputs.max_frames"). For planner data, which reads the first second only.
    max_frames: int | None = Field(None, ge=1, le=100_000)


class Perturbation(_Strict):
    """Standard deviations of the end-effector perturbation, per control step (`experts.perturbation`)."""

    # cm per axis of the TCP's translation this step; the base's travel this step likewise (its
    # vx, vy noise is this distance per control period)
    position_cm: float = Field(0.0, ge=0.0, le=5.0)
    # degrees per axis of the TCP's rotation this step; the base's turn this step likewise
    rotation_deg: float = Field(0.0, ge=0.0, le=20.0)

    @property
    def active(self) -> bool:
        return self.position_cm > 0.0 or self.rotation_deg > 0.0


class ExpertsConfig(_Strict):
    """How the scripted experts demonstrate."""

    # DART (Laskey et al. 2017): the executed action is the expert's plus zero-mean Gaussian noise
    # of `action_noise` times the per-dimension standard deviations of
    # `echo_data.agents.dart.NOISE_STD` (units there); the `action` column keeps the expert's own
    # command from the perturbed state, `action.executed` what the robot did. 0 = no noise.
    action_noise: float = Field(0.0, ge=0.0, le=4.0)
    # Perturbations in end-effector space (echo_data.agents.dart): the executed `action.ee` is the
    # expert's plus zero-mean Gaussian noise per control step, on the TCP change while the expert
    # moves the hand and on the base velocities while it drives; the label is the expert's own
    # command from the perturbed state. Off when both are 0. Applies to commands born in ee form;
    # `action_noise` perturbs only joint-born commands (no built-in expert yields them any more).
    perturbation: Perturbation = Field(default_factory=lambda: Perturbation())
    # Hand-over starts (M3-style): the build's Navigate stops at a random point of the next
    # skill's stance (`skill_table.HandOver`, docs/handover.md) instead of the exact
    # interaction pose, so the next skill's demonstration starts anywhere a learned Navigate may
    # hand over. A fraction f of the stance: the stop is uniform in a disc of f times the stance's
    # radius (less the path follower's stopping tolerance) around the interaction point, free and
    # in straight sight of it, its heading within f times the stance's heading tolerance of the
    # pose's (`echo_data.skills.navigate.handover_goal`). 0 = the exact pose.
    handover_noise: float = Field(0.0, ge=0.0, le=1.0)


