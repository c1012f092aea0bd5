"""Place's carry as a drive (docs/handover.md#places-carry): where a Place segment's rows turn from
the carry into the placing, and which rows each learner trains on.

A Place segment (the deliver skill's: it drives the held object to its receptacle, then places
it) splits at its first row whose base stands inside Place's own stance: within the stance's
distance of the receptacle's interaction pose and its heading of that pose's heading (the test
of the environment's `handed_over`, `skills.success.pose_offset` and `inside`). The rows before
it are the carry, a drive to the receptacle: `--with-carries` adds them to a drive learner's
(Navigate's) segments, goal the receptacle, `kind` its kind. The rows from it on are the
placing: `--from-stance` trains Place's learner on them alone.

The rows hold the base pose (`observation.state` entries 0-2, world x, y, yaw); the receptacle's
interaction pose is the one the episode record holds (`outcomes[k].handover.goal`, docs/handover.md,
"Recorded in the data"). A dataset built before that record existed has none: there the pose is
computed again from the apartment, regenerated from the manifest's recipe and the episode's
`scene_seed` (as `echo-data view` draws it), with the doors at the plan's angles, so a door that an
OpenDoor of the same episode opened before the Place counts as closed. A segment with no row
inside the stance (the target has no free pose, or the drive never got there) is all carry.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from echo_data.dataset.reader import StepReader, dataset_recipe, episodes_table
from echo_data.dataset.schema import STATE
from echo_data.skill_table import SKILLS, HandOver

OUTSIDE, CARRY, PLACING = 0, 1, 2  # a row's part (`carry_parts`): no deliver skill's, its carry, its placing from the stance on


def deliver_skills() -> tuple[str, ...]:
    """The skills that carry to a stance of their own before they act (Place)."""
    return tuple(n for n, s in SKILLS.items() if s.delivers and s.stance is not None)


def carry_parts(reader: StepReader) -> np.ndarray:
    """(rows,) int8 per row of the reader's split: CARRY before the first row of a deliver segment
    whose base stands inside the skill's stance, PLACING from that row on, OUTSIDE in every other
    skill's rows. The one place the split is made (see the module doc)."""
    from echo_data.skills.success import inside, pose_offset

    idx = reader.index
    part = np.full(len(idx), OUTSIDE, dtype=np.int8)
    rows = np.flatnonzero(np.isin(idx.skill, deliver_skills()))
    if not len(rows):
        return part
    table = episodes_table(reader.meta.root, ["episode_index", "split", "chain", "scene_seed", "outcomes"]).to_pylist()
    episodes = {int(e["episode_index"]): e for e in table if e["split"] == reader.split}
    base = reader.read([STATE], rows)[STATE][:, :3]
    regenerated = _Regenerated(reader)
    for seg in np.unique(idx.segment[rows]):
        mine = np.flatnonzero(idx.segment[rows] == seg)
        at = rows[mine]
        ep, k = episodes[int(idx.episode[at[0]])], int(idx.skill_index[at[0]])
        record = (ep["outcomes"][k] if k < len(ep["outcomes"]) else {}).get("handover")
        pose = record["goal"] if record is not None else regenerated.pose(int(ep["scene_seed"]), str(ep["chain"][k]["target"]))
        stance: HandOver | None = SKILLS[str(idx.skill[at[0]])].stance
        held = [pose is not None and stance is not None and inside(pose_offset(b, pose), stance.distance, stance.heading) for b in base[mine]]
        first = held.index(True) if any(held) else len(at)
        part[at[:first]] = CARRY
        part[at[first:]] = PLACING
    return part


class _Regenerated:
    """The interaction poses of a dataset built before the episode record held them: each
    episode's apartment regenerated once from the recipe and its scene seed (the module doc)."""

    def __init__(self, reader: StepReader) -> None:
        self.root = reader.meta.root
        self.plans: dict[int, Any] = {}

    def pose(self, seed: int, target: str) -> Any:
        """`target`'s interaction pose in the apartment of `seed`, doors at the plan's angles
        (None: it has no free one, so no row is in its stance)."""
        from echo_data.scene.generate import generate_floorplan_from_seed
        from echo_data.scene.nav import NavGrid, interaction_pose

        if seed not in self.plans:
            self.plans[seed] = generate_floorplan_from_seed(dataset_recipe(self.root)[0], seed)
        plan = self.plans[seed]
        doors = {i: float(d.angle) for i, d in enumerate(plan.doors)}
        try:
            return interaction_pose(plan, target, door_angles=doors or None, grid=NavGrid.from_plan(plan, door_angles=doors))
        except ValueError:
            return None


@dataclass
class Selection:
    """The rows one learner trains on, each with the bounds its action windows stay within."""

    rows: np.ndarray  # (n,) split row numbers, in split order
    first: np.ndarray  # (n,) first row of the row's part (a segment, a carry, or a placing from the stance)
    last: np.ndarray  # (n,) last row of that part
    carry: np.ndarray  # (n,) bool: a carry row, trained as a drive (its part's last row is where a drive STOPs)

    def windows(self, reader: StepReader, deltas: dict[str, Sequence[int]]) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """As `StepReader.windows`, clamped to each row's part instead of its segment."""
        values, pads = {}, {}
        for col, d in deltas.items():
            t = self.rows[:, None] + np.asarray(d, dtype=np.int64)[None, :]
            at = np.clip(t, self.first[:, None], self.last[:, None])
            flat = reader.read([col], at.reshape(-1))[col]
            values[col] = flat.reshape(*at.shape, *flat.shape[1:])
            pads[col] = (t < self.first[:, None]) | (t > self.last[:, None])
        return values, pads

    def carry_ends(self, deltas: Sequence[int]) -> np.ndarray:
        """(n, len(deltas)) True where a carry row's window reaches its carry's last row (its STOP)."""
        t = self.rows[:, None] + np.asarray(deltas, dtype=np.int64)[None, :]
        return (t == self.last[:, None]) & self.carry[:, None]


def select_rows(reader: StepReader, skill: str, from_stance: bool = False, with_carries: bool = False) -> Selection:
    """The rows `skill`'s learner trains on: all of its own, or with `from_stance` (a deliver
    skill) only those from its stance on, plus with `with_carries` (the drive skill) every
    deliver segment's carry (`carry_parts`)."""
    idx = reader.index
    own = idx.skill == skill
    part = carry_parts(reader) if from_stance or with_carries else np.full(len(idx), OUTSIDE, dtype=np.int8)
    if from_stance:
        own &= part == PLACING
    carry = (part == CARRY) if with_carries else np.zeros(len(idx), dtype=bool)
    rows = np.flatnonzero(own | carry)
    # a part is a run of rows of one segment and one part
    key = idx.segment * 3 + part
    new = np.concatenate([[True], key[1:] != key[:-1]]) if len(key) else np.zeros(0, dtype=bool)
    run = np.cumsum(new) - 1
    starts = np.flatnonzero(new)
    ends = np.concatenate([starts[1:], [len(key)]]) - 1
    return Selection(rows, starts[run[rows]], ends[run[rows]], carry[rows])


def carried_skills(with_carries: bool) -> tuple[str, ...]:
    """The skills whose carries a drive learner trained `--with-carries` also learns (their
    target kinds join its `kind` input's vocabulary)."""
    return deliver_skills() if with_carries else ()
