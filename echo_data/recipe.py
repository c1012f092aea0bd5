"""Recipe schema, loading (with `extends:`), defaults and content hash.

A recipe is validated completely before any work starts; every problem becomes a
`RecipeError` whose one-line message names the file and the key path.
"""

from __future__ import annotations

import hashlib
import json
import math
import stat
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import yaml

if TYPE_CHECKING:
    import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from echo_data import skill_table
from echo_data.categories import (
    CATEGORIES,
    DISTRACTOR_SHAPES,
    RELOCATION_CATEGORIES,
    STATE_CATEGORIES,
    Category,
    DistractorShape,
    RelocationCategory,
)

SETTINGS = ("object_relocation", "state_transition", "multi_event")
# Apartment layout families (echo_data/scene/layouts.py): rows of rectangular rooms, an L-shaped
# room, a corridor with rooms off it, an open-plan kitchen/living room.
LayoutName = Literal["rows", "l_shape", "corridor", "open_plan"]
LAYOUTS: tuple[LayoutName, ...] = ("rows", "l_shape", "corridor", "open_plan")


class RecipeError(ValueError):
    """A recipe problem; `str()` is one line naming the file and the key."""


# Largest split a recipe may ask for: episode ids have six digits, and a plan this size builds
# for months on a workstation (a typo of a few zeros should not start such a build).
MAX_SPLIT_EPISODES = 1_000_000
MAX_NAME_LENGTH = 100  # the name becomes a folder and file names (at most 255 bytes each)
# A recipe is a few levels deep and extends one or two files; far more is a mistake (or a file
# written to crash the loader: 2,000 nested brackets overflowed Python's stack in a traceback).
MAX_EXTENDS_DEPTH = 16
MAX_NESTING = 32
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
        _check_range(v)
        if v[0] < 2 or v[1] > 6:
            raise ValueError(f"rooms must lie within [2, 6], got {list(v)}")
        return v

    @field_validator("room_size")
    @classmethod
    def _room_size(cls, v: tuple[float, float]) -> tuple[float, float]:
        _check_range(v)
        if v[0] < 2.5 or v[1] > 12.0:
            raise ValueError(f"room_size must lie within [2.5, 12] m, got {list(v)}")
        if v[1] - v[0] < MIN_ROOM_SIZE_SPAN:  # the layouts draw sides strictly inside the range (scene/layouts.py)
            raise ValueError(f"room_size must span at least {MIN_ROOM_SIZE_SPAN} m (high - low), got {list(v)}")
        return v

    @field_validator("furniture_per_room")
    @classmethod
    def _fpr(cls, v: tuple[int, int]) -> tuple[int, int]:
        _check_range(v)
        if v[0] < 0 or v[1] > 6:
            raise ValueError(f"furniture_per_room must lie within [0, 6], got {list(v)}")
        return v


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
        _check_range(v)
        if v[0] < 0 or v[1] > 12:
            raise ValueError(f"distractors must lie within [0, 12], got {list(v)}")
        return v

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
    # Hand-over starts (M3-style): the build's Navigate stops at a random point of its own success
    # region instead of the exact interaction pose, so the next skill's demonstration starts where
    # a learned Navigate hands over. A fraction f of the region: the stop is uniform in the disc of
    # radius f x 1.3 m around the interaction point (free, in straight sight of it), heading at the
    # target within f x 9 degrees (`echo_data.skills.navigate.handover_goal`). 0 = the exact pose.
    handover_noise: float = Field(0.0, ge=0.0, le=1.0)


class Recipe(_Strict):
    """A whole, validated recipe."""

    name: str = Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$", max_length=MAX_NAME_LENGTH)
    seed: int = Field(0, ge=0)
    splits: dict[str, int] = Field(default_factory=lambda: {"train": 8, "test": 4})
    setting: Literal["object_relocation", "state_transition", "multi_event"] | dict[
        Literal["object_relocation", "state_transition", "multi_event"], float
    ] = "object_relocation"
    # Exact episode counts per setting and split (the STMM-1.9K table); when given, `splits`
    # is derived from it and each episode's setting is fixed by its index (see setting_for).
    composition: dict[
        Literal["object_relocation", "state_transition", "multi_event"], dict[str, int]
    ] | None = None
    max_attempts_per_episode: int = Field(8, ge=1, le=100)
    scene: SceneConfig = SceneConfig()
    objects: ObjectsConfig = ObjectsConfig()
    sounds: SoundsConfig = SoundsConfig()
    events: EventsConfig = EventsConfig()
    robot: RobotConfig = Field(default_factory=RobotConfig)  # made per recipe: its max_steps reads the skill table then
    acoustics: AcousticsConfig = AcousticsConfig()
    outputs: OutputsConfig = OutputsConfig()
    experts: ExpertsConfig = ExpertsConfig()

    @field_validator("splits")
    @classmethod
    def _splits(cls, v: dict[str, int]) -> dict[str, int]:
        if not v:
            raise ValueError("at least one split is required")
        for k, n in v.items():
            if k not in ("train", "test", "val"):
                raise ValueError(f"unknown split {k!r} (use train, val, test)")
            if not isinstance(n, int) or n < 0 or n > MAX_SPLIT_EPISODES:
                raise ValueError(f"split {k!r} must be an integer within [0, {MAX_SPLIT_EPISODES}], got {n}")
        if sum(v.values()) == 0:
            raise ValueError("every split has 0 episodes: nothing to build")
        return v

    @field_validator("composition")
    @classmethod
    def _composition(cls, v: dict[str, dict[str, int]] | None) -> dict[str, dict[str, int]] | None:
        for setting, per_split in (v or {}).items():
            for k, n in per_split.items():
                if k not in ("train", "test", "val"):
                    raise ValueError(f"{setting}: unknown split {k!r} (use train, val, test)")
                if n < 0 or n > MAX_SPLIT_EPISODES:
                    raise ValueError(f"{setting}.{k} must be an integer within [0, {MAX_SPLIT_EPISODES}], got {n}")
        return v

    @field_validator("setting")
    @classmethod
    def _setting(cls, v: Any) -> Any:
        if isinstance(v, dict) and not all(math.isfinite(w) for w in v.values()):
            raise ValueError("setting weights must be finite numbers")
        if isinstance(v, dict) and (any(w < 0 for w in v.values()) or sum(v.values()) <= 0):
            raise ValueError("setting weights must be >= 0 with a positive sum")
        return v

    @model_validator(mode="before")
    @classmethod
    def _derive_splits(cls, data: Any) -> Any:
        if isinstance(data, dict) and isinstance(data.get("composition"), dict):
            totals: dict[str, int] = {}
            for per_split in data["composition"].values():
                if not isinstance(per_split, dict):  # `object_relocation: 5`: the validator names composition.object_relocation
                    return data
                for split, n in per_split.items():
                    if isinstance(n, int) and not isinstance(n, bool) and 0 <= n <= MAX_SPLIT_EPISODES:
                        totals[split] = totals.get(split, 0) + n
                    else:  # let the composition validator name the bad count
                        return data
            if "splits" in data and data["splits"] != totals:
                raise ValueError(f"splits {data['splits']} disagree with composition totals {totals}; give one of them")
            data = {**data, "splits": totals}
        return data

    def setting_for(self, split: str, index: int, rng: np.random.Generator) -> str:
        """The setting of episode `index` of `split`.

        With `composition`, settings are laid out in a fixed interleaved order so that any
        prefix (e.g. `--limit`) keeps the proportions; otherwise drawn from the weights.
        """
        if self.composition:
            counts = {s: c.get(split, 0) for s, c in self.composition.items() if c.get(split, 0) > 0}
            total = sum(counts.values())
            if index >= total:
                raise ValueError(f"index {index} beyond {total} episodes of split {split!r}")
            # Largest-remainder interleave: episode i goes to the setting furthest behind its share.
            done = {s: 0 for s in counts}
            for i in range(index + 1):
                pick = max(counts, key=lambda s: (counts[s] * (i + 1) / total - done[s], -list(counts).index(s)))
                done[pick] += 1
            return pick
        weights = self.setting_weights()
        names = sorted(weights)
        return str(rng.choice(names, p=[weights[n] for n in names]))

    def settings_drawn(self) -> list[str]:
        """The settings an episode of this recipe can have (positive weight or count)."""
        if self.composition:
            return [s for s in SETTINGS if any(n > 0 for n in self.composition.get(s, {}).values())]  # type: ignore[call-overload]
        return [s for s in SETTINGS if s in self.setting_weights()]

    def categories_drawn(self) -> list[str]:
        """The sound categories an event of this recipe can have (drawn setting, positive weight)."""
        drawn = self.settings_drawn()
        pool: list[str] = []
        if {"object_relocation", "multi_event"} & set(drawn):
            pool += [c for c in self.objects.targets if c in RELOCATION_CATEGORIES]
        if {"state_transition", "multi_event"} & set(drawn):
            pool += list(STATE_CATEGORIES)
        return [c for c in CATEGORIES if c in pool and self.events.categories.get(c, 0.0) > 0]

    def setting_weights(self) -> dict[str, float]:
        """The setting mix as normalised weights."""
        if isinstance(self.setting, str):
            return {self.setting: 1.0}
        total = sum(self.setting.values())
        return {k: w / total for k, w in self.setting.items() if w > 0}

    def content_hash(self) -> str:
        """sha256 of the canonical JSON of the resolved recipe."""
        data = self.model_dump(mode="json")
        if data["outputs"]["max_frames"] is None:  # whole episodes: the hash recipes had before the key existed
            del data["outputs"]["max_frames"]
        if data["experts"] == ExpertsConfig().model_dump(mode="json"):  # noiseless experts: as before the key existed
            del data["experts"]
        if data["robot"]["grasp"] == "physical":  # the physical grasp: as before the key existed
            del data["robot"]["grasp"]
        if not data["sounds"]["fresh_train_instances"]:  # library voices only: as before the key existed
            del data["sounds"]["fresh_train_instances"]
        if data["robot"]["action_space"] == "joint":  # the env's default action form: as before the key existed
            del data["robot"]["action_space"]
        blob = json.dumps(data, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(blob.encode()).hexdigest()


def _deep_merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _deep_merge(out[k], v)
        else:
            out[k] = v
    return out


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that refuses a key given twice in one mapping (plain YAML keeps the last)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        first_line: dict[Any, int] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                if key in first_line:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key {key!r} (first given at line {first_line[key]})", key_node.start_mark
                    )
                first_line[key] = key_node.start_mark.line + 1
            except TypeError:  # an unhashable key: SafeLoader reports it below
                continue
        return super().construct_mapping(node, deep=deep)


def _resolve(path: Path, chain: tuple[Path, ...]) -> Path:
    """The real path of a recipe file; a symlink loop is one line naming the file that led there."""
    try:
        return path.resolve()
    except (RuntimeError, OSError):  # RuntimeError before Python 3.13, OSError (ELOOP) after
        where = f"{chain[-1]}: extends: {path}" if chain else str(path)
        raise RecipeError(f"{where}: symlink loop (the link points back to itself)") from None


def _deepest(data: Any, limit: int) -> str | None:
    """The key path of the first value nested deeper than `limit` levels (None when none is);
    iterative, so no nesting can exhaust Python's stack."""
    stack: list[tuple[Any, str, int]] = [(data, "", 0)]
    while stack:
        v, where, depth = stack.pop()
        if depth > limit:
            return where or "<root>"
        items = v.items() if isinstance(v, dict) else enumerate(v) if isinstance(v, list) else ()
        for k, x in items:
            stack.append((x, f"{where}.{k}" if where else str(k), depth + 1))
    return None


def _read_yaml(path: Path, chain: tuple[Path, ...] = ()) -> dict[str, Any]:
    """Read a recipe file and resolve its `extends:` chain into one mapping."""
    path = _resolve(path, chain)
    if path in chain:
        raise RecipeError(f"{path}: extends: circular chain {' -> '.join(str(p) for p in chain + (path,))}")
    if len(chain) >= MAX_EXTENDS_DEPTH:
        raise RecipeError(f"{chain[0]}: extends: a chain of more than {MAX_EXTENDS_DEPTH} files (at {path})")
    try:
        mode = path.stat().st_mode
        if not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):  # a FIFO or device would block or stream forever
            raise RecipeError(f"{path}: not a regular file")
        text = path.read_text()
    except FileNotFoundError:
        raise RecipeError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as e:
        raise RecipeError(f"{path}: cannot read recipe ({e.__class__.__name__}: {getattr(e, 'strerror', None) or e})") from None
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 (a SafeLoader)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise RecipeError(f"{path}: malformed YAML{where}: {problem}") from None
    except RecursionError:  # PyYAML composes nested nodes recursively
        raise RecipeError(f"{path}: nested more than {MAX_NESTING} levels deep") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise RecipeError(f"{path}: a recipe must be a mapping of keys, got {type(data).__name__}")
    deep = _deepest(data, MAX_NESTING)
    if deep is not None:
        raise RecipeError(f"{path}: {deep}: nested more than {MAX_NESTING} levels deep")
    parent = data.pop("extends", None)
    if parent is not None:
        if not isinstance(parent, str):
            raise RecipeError(f"{path}: extends: must be a file path")
        base = _read_yaml((path.parent / parent), chain + (path,))
        data = _deep_merge(base, data)
    return data


def _loc(loc: tuple[Any, ...]) -> str:
    parts = [str(p) for p in loc if not str(p).startswith(("function-", "literal[", "dict[", "tuple["))]
    # pydantic reports union branches by type name; keep only the real path.
    return ".".join(p for p in parts if p not in ("str", "int", "float", "list", "dict")) or "<root>"


def recipe_from_mapping(data: dict[str, Any], source: str = "<recipe>") -> Recipe:
    """Validate a mapping; raise a one-line `RecipeError` naming `source` and the key."""
    try:
        recipe = Recipe.model_validate(data)
    except ValidationError as e:
        errors = e.errors()
        # Of a union's branch errors (e.g. `setting` as a name or as weights) the deepest says most.
        err = max((x for x in errors if x["loc"][:1] == errors[0]["loc"][:1]), key=lambda x: len(x["loc"]))
        key = _loc(tuple(err["loc"]))
        msg = err["msg"].removeprefix("Value error, ")
        if err["type"] == "extra_forbidden":
            msg = "unknown key"
        elif err["type"] == "missing":
            msg = "required key is missing"
        more = f" (+{len(e.errors()) - 1} more)" if len(e.errors()) > 1 else ""
        raise RecipeError(f"{source}: {key}: {msg}{more}") from None
    _check_sound_folders(recipe, source)
    _check_draws(recipe, source)
    return recipe


def _check_draws(recipe: Recipe, source: str) -> None:
    """Weights that leave a drawn setting nothing to draw: refused, never replaced by a uniform
    draw (a category given weight 0 must never appear in an episode)."""
    weights = recipe.events.categories
    for setting in recipe.settings_drawn():
        if setting in ("object_relocation", "multi_event"):
            targets = [c for c in recipe.objects.targets if c in RELOCATION_CATEGORIES]
            if not targets:
                raise RecipeError(f"{source}: objects.targets: empty, but setting {setting} draws a sounding object")
            if not any(weights.get(c, 0.0) > 0 for c in targets):
                raise RecipeError(
                    f"{source}: events.categories.{targets[0]}: every target of objects.targets ({', '.join(targets)}) "
                    f"has weight 0, but setting {setting} draws one of them"
                )
        if setting in ("state_transition", "multi_event") and not any(weights.get(c, 0.0) > 0 for c in STATE_CATEGORIES):
            raise RecipeError(
                f"{source}: events.categories.{STATE_CATEGORIES[0]}: {' and '.join(STATE_CATEGORIES)} have weight 0, "
                f"but setting {setting} draws one of them"
            )


def _check_sound_folders(recipe: Recipe, source: str) -> None:
    base = Path(source).parent if source != "<recipe>" else Path.cwd()
    for cat, folder in recipe.sounds.folders.items():
        p = (base / folder) if not Path(folder).is_absolute() else Path(folder)
        if not p.is_dir():
            raise RecipeError(f"{source}: sounds.folders.{cat}: not a readable folder: {folder}")
    if recipe.sounds.fresh_train_instances and not recipe.sounds.builtin:
        raise RecipeError(f"{source}: sounds.fresh_train_instances: needs builtin: true (fresh instances come from the built-in synthesiser)")
    if not recipe.sounds.builtin and not recipe.sounds.folders:
        raise RecipeError(f"{source}: sounds: builtin is false and no folders are given")


def load_recipe(path: str | Path) -> Recipe:
    """Load, resolve `extends:`, validate. Raises `RecipeError` with a one-line message."""
    p = Path(path)
    data = _read_yaml(p)
    recipe = recipe_from_mapping(data, str(p))
    return recipe


def resolve_folder(recipe_path: str | Path, folder: str) -> Path:
    """A sound folder path as given in a recipe, resolved against the recipe's directory."""
    f = Path(folder)
    return f if f.is_absolute() else (Path(recipe_path).resolve().parent / f)
