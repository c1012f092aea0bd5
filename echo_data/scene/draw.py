"""One episode drawn from its seed, with the solvability checks that need no physics (pure: no SAPIEN).

Each draw (see `echo_data.episode.attempt_draws`) takes everything from its own seed: the
setting, the apartment, the sound events (targets, sound instances, sources), the skill
chain and the robot's start pose. A draw is solvable when a base path leads from the start
through every interaction pose in chain order and a free frontal region lies before doors and
sinks; otherwise `Reject` names the reason. `echo_data.scene.sampling` adds the physics check
(objects stay put when they settle) and the attempt loop.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy import ndimage

from echo_data.categories import RELOCATION_CATEGORIES, STATE_CATEGORIES
from echo_data.episode import EpisodeSpec, SkillCall, SoundEvent, episode_id, fresh_sound_seed
from echo_data.floorplan import FloorPlan, Rect, Vec3
from echo_data.protocols import SoundLibrary
from echo_data.recipe import Recipe
from echo_data.scene.furniture import front_zone, place_object
from echo_data.scene.generate import generate_floorplan
from echo_data.scene.nav import NavGrid, interaction_pose
from echo_data.scene.objects import instance_scale
from echo_data.scene.structure import GenerationError, door_swing_zone
from echo_data.skill_table import SKILLS, event_chain
from echo_data.sounds.instance_ids import fresh_id
from echo_data.target import Target

START_MIN_DISTANCE = 2.0  # m from the first target's sound source
START_ROOM_MARGIN = 0.4  # m from the room's wall centre lines
START_TRIES = 200
FRONTAL_DEPTH = 1.0  # m of free floor in front of a door / sink
ROBOT_WIDTH = 0.64  # m, diameter of the base disc (nav's default radius 0.32)


class SamplingError(RuntimeError):
    """No acceptable episode within the attempt budget; `counts` holds rejections by reason."""

    def __init__(self, message: str, counts: dict[str, int] | None = None) -> None:
        super().__init__(message)
        self.counts = dict(counts or {})

    def __reduce__(self) -> tuple:
        # picklable with its counts (it crosses process-pool boundaries)
        return (SamplingError, (str(self), self.counts))


class Reject(Exception):
    """This draw is not a solvable episode; `reason` counts it in the manifest."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason



def _weighted(rng: np.random.Generator, names: list[str], weights: Mapping[Any, float]) -> str:
    """One of `names` by `weights` (missing = 0). Every weight zero is refused (the recipe loader
    refuses such a recipe first): a category given weight 0 is never drawn."""
    w = np.array([max(float(weights.get(n, 0.0)), 0.0) for n in names])
    if w.sum() <= 0:
        raise ValueError(f"every one of {names} has weight 0 in events.categories")
    return names[int(rng.choice(len(names), p=w / w.sum()))]


def _sound_id(library: SoundLibrary, category: str, split: str, rng: np.random.Generator, fresh_seed: int | None = None) -> str:
    """A sound instance of `category` from `split` (val uses train sounds). With `fresh_seed`
    (`sounds.fresh_train_instances`), a draw of a built-in train instance becomes the fresh
    instance of that seed; the draw itself is unchanged, so user files keep their share."""
    sound_split = "train" if split == "val" else split
    ids = sorted(s.id for s in library.instances(category, sound_split))
    if not ids:
        raise SamplingError(f"the sound library has no {sound_split!r} sounds of category {category!r}", {})
    pick = ids[int(rng.integers(len(ids)))]
    if fresh_seed is not None and sound_split == "train" and library.get(pick).builtin:
        return fresh_id(category, fresh_seed)
    return pick


# ------------------------------------------------------------------------------ geometry checks
def _component_of(labels: np.ndarray, grid: NavGrid, xy: tuple[float, float]) -> int:
    i, j = grid.cell(*xy)
    if 0 <= i < labels.shape[0] and 0 <= j < labels.shape[1]:
        return int(labels[i, j])
    return 0


def _stand_component(plan: FloorPlan, grid: NavGrid, labels: np.ndarray, target: str) -> int:
    """Free-region label of the interaction pose for `target` (0 when there is none)."""
    try:
        x, y, _ = interaction_pose(plan, target, grid=grid)
    except ValueError:
        return 0
    return _component_of(labels, grid, (x, y))


def door_frontal_region(plan: FloorPlan, door_index: int, depth: float = FRONTAL_DEPTH) -> Rect:
    """The floor in front of a door's doorway on the swing (approach) side: doorway wide, `depth` deep."""
    door = plan.doors[door_index]
    dw = plan.doorways[door.doorway]
    t = next((w.thickness for w in plan.walls), 0.1)
    swing = plan.rooms[door.swing_room].rect
    if dw.axis == "x":
        s = 1.0 if swing.center[1] > dw.center[1] else -1.0
        v0 = dw.center[1] + s * t / 2.0
        half = max(dw.width, ROBOT_WIDTH) / 2.0
        return Rect(dw.center[0] - half, min(v0, v0 + s * depth), dw.center[0] + half, max(v0, v0 + s * depth))
    s = 1.0 if swing.center[0] > dw.center[0] else -1.0
    v0 = dw.center[0] + s * t / 2.0
    half = max(dw.width, ROBOT_WIDTH) / 2.0
    return Rect(min(v0, v0 + s * depth), dw.center[1] - half, max(v0, v0 + s * depth), dw.center[1] + half)


def sink_frontal_region(plan: FloorPlan, faucet_index: int, depth: float = FRONTAL_DEPTH) -> Rect:
    """The floor in front of the sink cabinet: `depth` deep, cabinet (or robot) wide."""
    f = plan.furniture[plan.faucets[faucet_index].furniture]
    z = front_zone(f, depth)
    if z.size[0] < ROBOT_WIDTH and abs(round(math.sin(f.yaw))) == 1:
        c = z.center[0]
        z = Rect(c - ROBOT_WIDTH / 2.0, z.ymin, c + ROBOT_WIDTH / 2.0, z.ymax)
    elif z.size[1] < ROBOT_WIDTH and abs(round(math.cos(f.yaw))) == 1:
        c = z.center[1]
        z = Rect(z.xmin, c - ROBOT_WIDTH / 2.0, z.xmax, c + ROBOT_WIDTH / 2.0)
    return z


def region_free(plan: FloorPlan, region: Rect, room: int, ignore_door: int | None = None) -> bool:
    """Whether `region` lies inside `room` (less half a wall) and touches no furniture, wall or
    other door's swing."""
    t = next((w.thickness for w in plan.walls), 0.1)
    inner = plan.rooms[room].rect.expanded(-t / 2.0 + 1e-6)
    if not (inner.contains(region.xmin, region.ymin) and inner.contains(region.xmax, region.ymax)):
        return False
    shrunk = region.expanded(-1e-6)
    if any(shrunk.intersects(f.footprint) for f in plan.furniture):
        return False
    if any(shrunk.intersects(w.footprint) for w in plan.walls):
        return False
    return all(shrunk.intersects(door_swing_zone(d)) is False for d in plan.doors if d.index != ignore_door)


# ------------------------------------------------------------------------------ one draw
def draw_episode(recipe: Recipe, split: str, index: int, attempt: int, seed: int, library: SoundLibrary) -> EpisodeSpec:
    """Draw `attempt` of episode (split, index) from `seed`; `Reject` names why it is not solvable.
    The physics check of the drawn objects is the SAPIEN side's (`echo_data.scene.sampling`).
    Long because the order of its random draws is the episode's seed story: kept in one body so a
    change cannot reorder the draws (every dataset's bytes hang on it)."""
    rng = np.random.default_rng(seed)
    setting = recipe.setting_for(split, index, rng)
    try:
        plan = generate_floorplan(recipe, rng)
    except GenerationError:
        raise Reject("no_floorplan") from None
    grid = NavGrid.from_plan(plan)
    labels, _ = ndimage.label(grid.free)

    weights = dict(recipe.events.categories)
    want_reloc = setting in ("object_relocation", "multi_event")
    want_state = setting in ("state_transition", "multi_event")
    state_cat = _weighted(rng, list(STATE_CATEGORIES), weights) if want_state else None
    reloc_cat = _weighted(rng, [c for c in recipe.objects.targets if c in RELOCATION_CATEGORIES], weights) if want_reloc else None

    # The robot works inside one free region of the closed-door apartment ("home"): the one
    # in front of the state event's door / sink, else the largest.
    state_target: str | None = None
    if state_cat == "doorbell":
        belled = [d.index for d in plan.doors if d.doorbell is not None]
        door_i = belled[int(rng.integers(len(belled)))]
        state_target = str(Target.door(door_i))
        if not region_free(plan, door_frontal_region(plan, door_i), plan.doors[door_i].swing_room, ignore_door=door_i):
            raise Reject("no_frontal_region")
    elif state_cat == "sink":
        state_target = str(Target.faucet(0))
        sink = plan.furniture[plan.faucets[0].furniture]
        if not region_free(plan, sink_frontal_region(plan, 0), sink.room):
            raise Reject("no_frontal_region")
    if state_target is not None:
        try:
            sx, sy, _ = interaction_pose(plan, state_target, grid=grid)
        except ValueError:
            raise Reject("no_interaction_pose") from None
        home = _component_of(labels, grid, (sx, sy))
    stand = {f.index: _stand_component(plan, grid, labels, str(Target.furniture(f.index))) for f in plan.furniture if f.receptacle}
    if state_target is None:
        # relocation only: the region with the most receptacles (ties: the larger region)
        sizes = np.bincount(labels.ravel())
        regions = sorted({c for c in stand.values() if c > 0})
        if not regions:
            raise Reject("no_receptacle")
        home = max(regions, key=lambda c: (sum(v == c for v in stand.values()), int(sizes[c]), -c))
    if home == 0:
        raise Reject("no_interaction_pose")

    receptacles = [i for i, c in stand.items() if c == home]
    events: list[tuple[str, str, Vec3]] = []  # (category, target, source)
    if reloc_cat is not None:
        name = f"{reloc_cat}_0"
        if len(receptacles) < 2:
            raise Reject("no_receptacle")
        scale = instance_scale(reloc_cat, name, plan.seed) if recipe.objects.size_variants else 1.0
        nxt = place_object(plan, reloc_cat, name, rng, sounding=True, receptacles=receptacles, scale=scale)
        if nxt is None:
            raise Reject("no_receptacle")
        plan = nxt
        obj = plan.object_by_name(name)
        events.append((reloc_cat, name, obj.position))
    if state_cat == "doorbell" and state_target is not None:
        door_i = Target.parse(state_target).index
        bell = plan.doors[door_i].doorbell
        assert bell is not None  # the door was drawn among those with a bell
        events.append(("doorbell", state_target, bell))
    elif state_cat == "sink":
        events.append(("sink", str(Target.faucet(0)), plan.faucets[0].spout))

    prio: list[str] = list(recipe.events.priority)
    events.sort(key=lambda e: prio.index(e[0]))
    sound_events = tuple(
        SoundEvent(category=c, sound_id=_sound_id(library, c, split, rng, fresh_sound_seed(seed, k) if recipe.sounds.fresh_train_instances else None),
                   target=t, source=(float(s[0]), float(s[1]), float(s[2])), priority=k)
        for k, (c, t, s) in enumerate(events)
    )

    # start pose: a free spot in the home region, far enough from the first sound
    first = sound_events[0].source
    start: tuple[float, float, float] | None = None
    for _ in range(START_TRIES):
        room = plan.rooms[int(rng.integers(len(plan.rooms)))].rect.expanded(-START_ROOM_MARGIN)
        if room.xmax <= room.xmin or room.ymax <= room.ymin:
            continue
        x, y = float(rng.uniform(room.xmin, room.xmax)), float(rng.uniform(room.ymin, room.ymax))
        if math.hypot(x - first[0], y - first[1]) < START_MIN_DISTANCE:
            continue
        if not grid.is_free(x, y) or _component_of(labels, grid, (x, y)) != home:
            continue
        start = (round(x, 3), round(y, 3), round(float(rng.uniform(-math.pi, math.pi)), 4))
        break
    if start is None:
        raise Reject("no_start")

    chain: list[SkillCall] = []
    for k, ev in enumerate(sound_events):  # each event's skills as the registry chains them
        place_at = None
        if ev.category in RELOCATION_CATEGORIES:  # a relocated object goes back to a receptacle
            obj = plan.object_by_name(ev.target)
            place_at = str(Target.furniture(_place_goal(plan, grid, obj.receptacle, obj.category, receptacles, ev.target)))
        chain += event_chain(ev.target, k, place_at)

    _check_paths(plan, grid, start, chain)

    return EpisodeSpec(
        episode_id=episode_id(split, index),
        split=split,
        index=index,
        attempt=attempt,
        seed=seed,
        setting=setting,
        plan=plan,
        start=start,
        events=sound_events,
        chain=tuple(chain),
    )


def _place_goal(plan: FloorPlan, grid: NavGrid, source: int, category: str, receptacles: list[int], target: str) -> int:
    """The receptacle nearest to the pick pose (straight line) that has room for the object
    and a collision-free path from the pick pose."""
    try:
        px, py, _ = interaction_pose(plan, target, grid=grid)
    except ValueError:
        raise Reject("no_interaction_pose") from None
    probe_rng = np.random.default_rng(plan.seed)
    cands = []
    for i in receptacles:
        if i == source:
            continue
        f = plan.furniture[i]
        cands.append((math.hypot(f.center[0] - px, f.center[1] - py), i))
    for _, i in sorted(cands):
        scale = plan.object_by_name(target).scale
        if place_object(plan, category, "_probe", probe_rng, sounding=False, receptacles=[i], scale=scale) is None:
            continue
        try:
            gx, gy, _ = interaction_pose(plan, str(Target.furniture(i)), grid=grid)
        except ValueError:
            continue
        if grid.plan_path((px, py), (gx, gy)) is not None:
            return i
    raise Reject("no_place_goal")


def _check_paths(plan: FloorPlan, grid: NavGrid, start: tuple[float, float, float], chain: list[SkillCall]) -> None:
    """A base path from the start through every interaction pose in chain order.

    Doors are closed, except that after an OpenDoor the door counts as open at its
    open threshold (the least a successful OpenDoor guarantees).
    """
    cur = (start[0], start[1])
    door_angles: dict[int, float] = {}
    for call in chain:
        s = SKILLS[call.skill]
        if s.effect != "opens_door" and not s.drives:  # acts where the base stands
            continue
        if s.effect == "opens_door":
            i = Target.parse(call.target).index
            door_angles[i] = plan.doors[i].open_threshold
            grid = NavGrid.from_plan(plan, robot_radius=grid.robot_radius, resolution=grid.resolution, door_angles=door_angles)
            # the robot ends beside the opened leaf; continue from the nearest free spot
            moved = grid.nearest_free(*cur, radius=1.0)
            if moved is None:
                raise Reject("no_path")
            cur = moved
            continue
        try:
            gx, gy, _ = interaction_pose(plan, call.target, door_angles=door_angles or None, grid=grid)
        except ValueError:
            raise Reject("no_interaction_pose") from None
        if grid.plan_path(cur, (gx, gy)) is None:
            raise Reject("no_path")
        cur = (gx, gy)
