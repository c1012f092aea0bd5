"""Episode sampling: (recipe, split, index) -> EpisodeSpec, the pure draw plus the physics check.

`echo_data.scene.draw` draws an attempt from its seed and rejects what cannot be solved without
physics; here each drawn apartment's objects are also let rest on their receptacles in a
physics-only SAPIEN scene, and a draw whose objects slide or tip is rejected ("unstable_objects").
Rejections are counted by reason; after `recipe.max_attempts_per_episode` failures a
`SamplingError` carries the counts.
"""

from __future__ import annotations

import math

import numpy as np
import sapien

from echo_data.episode import EpisodeSpec, attempt_draws
from echo_data.floorplan import FloorPlan
from echo_data.protocols import SoundLibrary
from echo_data.recipe import Recipe
from echo_data.scene.bodies import build_object
from echo_data.scene.build import build_statics
from echo_data.scene.draw import Reject, SamplingError, draw_episode

SETTLE_SECONDS = 0.5
SETTLE_MAX_SHIFT = 0.01  # m
SETTLE_MAX_TILT = math.radians(5.0)


def settle_shift(plan: FloorPlan, physics_hz: int = 100, seconds: float = SETTLE_SECONDS) -> dict[str, tuple[float, float]]:
    """Let the objects rest on the receptacles in a physics-only scene; per object (shift m, tilt rad)."""
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    scene.set_timestep(1.0 / physics_hz)
    build_statics(scene, plan, with_walls=False)
    bodies = {o.name: build_object(scene, o) for o in plan.objects}
    for _ in range(int(round(seconds * physics_hz))):
        scene.step()
    out: dict[str, tuple[float, float]] = {}
    for o in plan.objects:
        pose = bodies[o.name].pose
        shift = float(np.linalg.norm(np.asarray(pose.p) - np.asarray(o.position)))
        w, x, y, z = (float(v) for v in pose.q)
        # tilt = angle between the body's z axis and world z
        cos_tilt = 1.0 - 2.0 * (x * x + y * y)
        out[o.name] = (shift, float(math.acos(max(-1.0, min(1.0, cos_tilt)))))
    return out


def settles(plan: FloorPlan, physics_hz: int) -> bool:
    """Every object stays within SETTLE_MAX_SHIFT and SETTLE_MAX_TILT when it comes to rest."""
    return not any(shift > SETTLE_MAX_SHIFT or tilt > SETTLE_MAX_TILT for shift, tilt in settle_shift(plan, physics_hz).values())


def sample_episode(
    recipe: Recipe, split: str, index: int, library: SoundLibrary, attempt: int = 0
) -> tuple[EpisodeSpec, dict[str, int]]:
    """The episode (split, index) of `recipe` plus the rejected attempts counted by reason.

    Sampling attempts run from `attempt * recipe.max_attempts_per_episode` on, at most
    `max_attempts_per_episode` of them, so a build that retries an episode after an expert
    failure (`attempt` = 1, 2, ...) gets fresh seeds that never repeat an earlier retry's.
    """
    budget = recipe.max_attempts_per_episode
    counts: dict[str, int] = {}
    for k, seed in attempt_draws(recipe.seed, split, index, attempt, budget):
        try:
            spec = draw_episode(recipe, split, index, k, seed, library)
            if not settles(spec.plan, recipe.robot.physics_hz):
                raise Reject("unstable_objects")
            return spec, counts
        except Reject as r:
            counts[r.reason] = counts.get(r.reason, 0) + 1
    raise SamplingError(f"{split}-{index:06d}: no solvable episode in {budget} attempts ({counts})", counts)
