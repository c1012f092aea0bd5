"""A synthetic episode generator with the real shapes, for fast tests of the dataset side.

It stands in for `echo_data.app.pipeline.generate_episode` only in tests (injected into `build`):
deterministic per (split, index, attempt), with expert failures and sampling errors on some
first attempts so retries and the manifest's failure records are exercised.
"""

from __future__ import annotations

import hashlib
import time
from pathlib import Path

import numpy as np

from echo_data.acoustics.features import step_features
from echo_data.episode import EpisodeSpec, SkillCall, SoundEvent, episode_seed
from echo_data.floorplan import FloorPlan, Furniture, PlacedObject, Rect, Room
from echo_data.pcm import as_written
from echo_data.recipe import CameraConfig, OutputsConfig, Recipe, RobotConfig
from echo_data.records import ACTION_DIM, EE_ACTION_DIM, PRIVILEGED_COLUMNS, STATE_DIM, EpisodeResult, SkillOutcome, StepRecord


class SamplingError(RuntimeError):
    """Same name as echo_data.scene.sampling.SamplingError (the build matches it by name)."""

    def __init__(self, message: str) -> None:
        super().__init__(message)
        self.counts = {"path_blocked": 2}  # rejections by reason, as the real one carries


def synth_recipe(**over: object) -> Recipe:
    base: dict = dict(
        name="synth",
        seed=7,
        splits={"train": 5, "test": 3},
        setting={"object_relocation": 1.0, "state_transition": 1.0},
        max_attempts_per_episode=3,
        robot=RobotConfig(head_camera=CameraConfig(width=24, height=16), wrist_camera=CameraConfig(width=16, height=16, rgb=False)),
        outputs=OutputsConfig(episodes_per_shard=2),
    )
    base.update(over)
    return Recipe(**base)


def _plan(seed: int) -> FloorPlan:
    room = Room(0, "kitchen", Rect(0.0, 0.0, 4.0, 4.0), "linoleum_on_concrete", "plasterboard", "ceiling_plasterboard")
    table = Furniture(0, "table", 0, (1.0, 1.0), (0.8, 0.6, 0.75), 0.0, "wooden_door", True)
    counter = Furniture(1, "counter", 0, (3.0, 3.0), (1.0, 0.6, 0.9), 3.1416, "wooden_door", True)
    phone = PlacedObject(0, "phone_0", "phone", (1.0, 1.0, 0.76), 0.0, 0, True)
    return FloorPlan(seed, (room,), (), (), (), (table, counter), (), (phone,))


def _pose(rng: np.random.Generator) -> np.ndarray:
    """A random rigid camera-to-world transform."""
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    t = np.eye(4)
    t[:3, :3] = q * np.sign(np.linalg.det(q))
    t[:3, 3] = rng.uniform(-3, 3, 3)
    return t


def synth_generate(
    recipe: Recipe, split: str, index: int, library: object, recipe_dir: Path, attempt: int = 0, delay: float = 0.0
) -> EpisodeResult:
    """Deterministic fake rollout: 3-6 steps, images, spectrograms and audio of the right shapes."""
    if delay:
        time.sleep(delay)
    seed = episode_seed(recipe.seed, split, index, attempt)
    if attempt == 0 and index % 5 == 2:
        raise SamplingError(f"no solvable layout for {split}-{index}")
    rng = np.random.default_rng(seed)
    setting = ("object_relocation", "state_transition")[index % 2]
    event = SoundEvent("phone", f"phone_{index % 3:03d}", "phone_0", (1.0, 1.0, 0.8), 0)
    chain = (
        SkillCall("Navigate", "phone_0", 0),
        SkillCall("Pick", "phone_0", 0),
        SkillCall("Navigate", "furniture:1", 0),
        SkillCall("Place", "furniture:1", 0),
    )
    spec = EpisodeSpec(f"{split}-{index:06d}", split, index, attempt, seed, setting, _plan(seed), (2.0, 2.0, 0.5), (event,), chain)
    fails = attempt == 0 and index % 3 == 1
    hz, sr = recipe.robot.control_hz, recipe.acoustics.sample_rate
    n = 3 + int(rng.integers(0, 4))
    head, wrist = recipe.robot.head_camera, recipe.robot.wrist_camera
    steps = []
    extra = np.random.default_rng([seed & 0xFFFFFFFF, 1])  # the echo-data/3 columns, from their own stream
    for t in range(n):
        k = min(t * len(chain) // n, len(chain) - 1)
        steps.append(
            StepRecord(
                frame_index=t,
                timestamp=t / hz,
                skill=chain[k].skill,
                skill_index=k,
                action=rng.normal(size=ACTION_DIM).astype(np.float32),
                state=rng.normal(size=STATE_DIM).astype(np.float32),
                head_rgb=rng.integers(0, 256, (head.height, head.width, 3), dtype=np.uint8),
                head_depth=rng.integers(0, 5000, (head.height, head.width), dtype=np.uint16),
                wrist_depth=rng.integers(0, 2000, (wrist.height, wrist.width), dtype=np.uint16),
                ear_position=(2.0, 2.0, 1.2),
                ear_yaw=0.5,
                sounding=(t < n - 1,),
                skill_success=tuple(j < k for j in range(len(chain))),
                done=t == n - 1,
                camera_poses={"head": _pose(rng), "wrist": _pose(rng)},
                action_ee=np.append(extra.normal(size=EE_ACTION_DIM - 1), float(t % 2)).astype(np.float32),  # binary gripper_close
                privileged={col: extra.normal(size=d).astype(np.float32) for col, d in PRIVILEGED_COLUMNS.items()},
                skill_stop=t == n - 1 or min((t + 1) * len(chain) // n, len(chain) - 1) != k,
            )
        )
    samples = (n + 1) * sr // hz
    # Noise well below full scale, and features of exactly the samples the WAV will hold, as
    # the real pipeline does (validate recomputes them from the WAV).
    audio = as_written(0.3 * np.tanh(rng.standard_normal((samples, 2))))
    offsets = np.array([(t + 1) * sr // hz for t in range(n)], dtype=np.int64)
    spectrogram, mel = step_features(audio, offsets, sr, recipe.acoustics.mel_bands)
    outcomes = [SkillOutcome(c.skill, c.target, True, "", n // len(chain)) for c in chain]
    if fails:
        outcomes = outcomes[:1] + [SkillOutcome("Pick", "phone_0", False, "no IK solution", 2)]
    return EpisodeResult(spec, steps, outcomes, not fails, audio, offsets, spectrogram, mel, {"object_moved": 1})


def slow_generate(*args: object, **kw: object) -> EpisodeResult:
    return synth_generate(*args, **kw, delay=0.25)  # type: ignore[arg-type]


def null_library(recipe: Recipe, recipe_dir: Path) -> None:
    """The synthetic generator needs no sound library."""
    return None


def build_synth(out: Path, splits: dict[str, int], **over: object) -> Path:
    """A built synthetic dataset at `out` (for loader, card, export and view tests); `over`
    replaces fields of `synth_recipe`."""
    from echo_data.app.build import build

    build(synth_recipe(splits=splits, **over), Path(__file__), out, generate=synth_generate, make_library=null_library, progress=False)
    return out


def damageable_copy(pristine: Path, tmp_path: Path) -> Path:
    """A copy of a built dataset that one test may damage without touching the shared original."""
    import shutil

    copy = tmp_path / "synth"
    shutil.copytree(pristine, copy)
    return copy


def file_digests(root: Path) -> dict[str, str]:
    """sha256 of every file of a dataset but its manifest (which records how the build ran)."""
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name != "manifest.json"
    }
