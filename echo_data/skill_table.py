"""Every skill of the robot, declared once: one `Skill(...)` line below holds its name, its
expert, its success test, whether its success resolves (silences) its event, its step budget, what
it acts on, its role in an event's chain and its effect on the world when it succeeds.

Everything else reads this table and nothing else dispatches on skill names (tests/
test_skill_vocabulary.py counts the name literals used as logic elsewhere): the recipe takes
its skill names and default step limits from it, the sampler builds chains from the roles
(`event_chain`), the environment applies the effects (`apply_effect`, `Skill.effect`), the
runtime and the experts take budgets, the planner's prompt the descriptions, DAgger the skills
whose expert labels any state, and the experts' table (`echo_data.skills.EXPERTS`) the experts.
Adding a skill is one module (expert + success test) and one line here (docs/adding_a_skill.md).

The vocabulary layer (docs/ARCHITECTURE.md), below everything that uses it: at import this
module reads only `echo_data.target`; experts and success tests are named "module:function" and
imported on first call, so the recipe and the sampler can read the table without loading
physics or mplib.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

from echo_data.target import Target, TargetKind

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.recipe import Recipe
    from echo_data.world import World

# Where a skill sits in an event's chain (`event_chain`):
# "approach": opens every event's chain, brings the base to the event's target;
# "resolve": acts on the event's target where the approach left the base (the one skill whose
#            `targets` hold the target's kind);
# "deliver": follows the resolve skill it names in `follows`, carrying to a goal of its own.
ChainRole = Literal["approach", "resolve", "deliver"]
# What a success changes in the world beyond the robot (the environment applies it once, when
# the skill completes in chain order): "places_object": the carried object rests on the target
# furniture from now on (a later Pick lifts it from there); "opens_door": the target door stands
# open (the acoustics and the navigation grid follow the door's angle).
Effect = Literal["", "places_object", "opens_door"]

# Extra steps granted beyond a skill's own limit before it is called stuck.
GUARD_STEPS = 20


@dataclass(frozen=True)
class HandOver:
    """Where a skill's manipulation is taught to begin (its stance): the base within `distance` m
    of its target's interaction pose (`scene.nav.interaction_pose`) and its heading within
    `heading` rad of that pose's heading. The drive before it ends there: a Navigate before the
    skill, or the skill's own drive (Place's carry). One region per skill, read by the experts
    (`experts.handover_noise` draws the demonstrations' starts from it), the environment
    (`info["skills"][k]["handed_over"]`), the runtime (a learned drive ends when it holds) and
    `evaluate` (docs/handover.md)."""

    distance: float  # m
    heading: float  # rad


# The stance of every manipulation skill (why this size: docs/handover.md). Manipulation learners
# succeed from the exact pose and fall from starts spread over Navigate's 1.5 m success region
# (the paper table's rows "alone" against "after a hand-over"); the region is wide enough for a
# drive learner to end in and at least twice the Navigate expert's own stopping tolerances
# (skills.navigate.GOAL_TOL, YAW_TOL), so its drawn stops stay inside.
STANCE = HandOver(distance=0.25, heading=math.radians(10.0))
# A learned drive ending "centre" (`agents.runtime.DRIVE_ENDS`) goes on until it stands in this
# fraction of the stance (distance and heading both), its centre: a drive cut the first step it
# enters the stance hands over at its rim (measured for Navigate*'s heading: docs/handover.md).
# The stance itself stays the hand-over test.
STANCE_CENTRE = 0.5


@dataclass(frozen=True)
class Situation:
    """What a success test may read besides the world: the episode and the navigation grid at
    the doors' current angles (cached by the environment, so the test is cheap per step)."""

    spec: EpisodeSpec
    nav_grid: Callable[[], Any]
    poses: dict[Any, Any] = field(default_factory=dict)  # navigate_success's interaction points, per episode


SuccessTest = Callable[["World", "SkillCall", Situation], bool]


@dataclass(frozen=True)
class Skill:
    """One skill's contract (see the module doc)."""

    name: str
    expert: str  # "module:function", a generator expert(world, call, spec) -> SkillOutcome
    success: SuccessTest  # on the live world, after any control step
    resolves_event: bool  # its success silences its event's sound (a picked-up phone, an opened door)
    budget: tuple[str, ...]  # recipe `robot.max_steps` keys whose limits add up to its step limit
    targets: tuple[TargetKind, ...]  # what `call.target` may name
    max_steps: int  # its default limit in the recipe's `robot.max_steps`
    role: ChainRole
    effect: Effect = ""
    follows: str = ""  # "deliver" skills: the resolve skill they carry on from
    description: str = ""  # what it does, in the planner's prompt (dataset/planner.prompt)
    labels_any_state: bool = False  # its expert can act from any state the learner reaches (DAgger)
    stance: HandOver | None = None  # where its manipulation begins (None: it only drives)

    def expert_fn(self) -> Callable[..., Any]:
        return _import(self.expert)

    def step_budget(self, recipe: Recipe) -> int:
        """Control steps the skill may take: its recipe limits plus GUARD_STEPS."""
        limits: dict[str, int] = {str(k): int(v) for k, v in recipe.robot.max_steps.items()}
        return sum(limits[k] for k in self.budget) + GUARD_STEPS

    @property
    def drives(self) -> bool:
        """Whether it moves the base to its own target's interaction pose (approach, deliver)."""
        return self.role != "resolve"

    @property
    def delivers(self) -> bool:
        """Whether it carries the object its `follows` skill lifted to a goal of its own."""
        return self.role == "deliver"

    @property
    def lifts(self) -> bool:
        """Whether its success puts an object in the hand (a deliver skill follows it)."""
        return any(s.follows == self.name for s in SKILLS.values())


def role_of(name: str) -> ChainRole | None:
    """The role of skill `name`; None for a name that is no skill (a planner's free answer)."""
    s = SKILLS.get(name)
    return s.role if s is not None else None


def approach_skill() -> Skill:
    """The skill that opens every event's chain (its step limit is also a carry's drive limit)."""
    return next(s for s in SKILLS.values() if s.role == "approach")


def carried_object(spec: EpisodeSpec, call: SkillCall) -> str | None:
    """The object a deliver call (Place) carries: the target of the skill it follows in the same event."""
    follows = skill(call.skill).follows
    return next((c.target for c in spec.chain if c.event == call.event and c.skill == follows), None) if follows else None


def _import(path: str) -> Any:
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)


def lazy_test(path: str) -> SuccessTest:
    """The success test "module:function" (world, call, at) -> bool, imported on its first call:
    a new skill's registry line can name the test in its own module."""
    def test(world: World, call: SkillCall, at: Situation) -> bool:
        return bool(_import(path)(world, call, at))

    test.__qualname__ = path
    return test


SKILLS: dict[str, Skill] = {
    s.name: s
    for s in (
        Skill("Navigate", "echo_data.skills.navigate:navigate", lazy_test("echo_data.skills.success:navigated"), False, ("Navigate",),
              ("object", "door", "faucet", "furniture"), 600, "approach", labels_any_state=True,
              description="drive the base to stand in front of a target (object, door, sink or furniture)"),
        Skill("Pick", "echo_data.skills.pick:pick", lazy_test("echo_data.skills.success:picked"), True, ("Pick",), ("object",), 250, "resolve",
              stance=STANCE, labels_any_state=True, description="grasp a small object and lift it"),
        # Place also drives the object across the apartment: Navigate's limit is added to its own.
        Skill("Place", "echo_data.skills.place:place", lazy_test("echo_data.skills.success:placed"), False, ("Place", "Navigate"), ("furniture",), 250,
              "deliver", "places_object", follows="Pick", stance=STANCE, labels_any_state=True, description="put the held object down on a piece of furniture"),
        Skill("OpenDoor", "echo_data.skills.open_door:open_door", lazy_test("echo_data.skills.success:door_opened"), True, ("OpenDoor",), ("door",), 300,
              "resolve", "opens_door", stance=STANCE, labels_any_state=True, description="open the door whose bell rang"),
        Skill("CloseSink", "echo_data.skills.close_sink:close_sink", lazy_test("echo_data.skills.success:sink_closed"), True, ("CloseSink",), ("faucet",),
              200, "resolve", stance=STANCE, labels_any_state=True, description="turn the running faucet off"),
    )
}


def default_max_steps() -> dict[str, int]:
    """The recipe's default `robot.max_steps`: every skill's own limit (read when a recipe is made,
    so a skill registered later is in it)."""
    return {n: s.max_steps for n, s in SKILLS.items()}


def event_chain(target: str, event: int, goal: str | None = None) -> list[SkillCall]:
    """The skill calls that answer event `event` on `target`: the approach skill to it, the skill
    that resolves a target of its kind, then the skill that delivers to `goal` if one follows that
    (relocations: Navigate, Pick, Place; a door: Navigate, OpenDoor; a faucet: Navigate, CloseSink)."""
    from echo_data.episode import SkillCall

    kind = Target.parse(target).kind
    approach = approach_skill()
    resolve = [s for s in SKILLS.values() if s.role == "resolve" and kind in s.targets]
    if len(resolve) != 1:
        raise ValueError(f"target {target!r}: {len(resolve)} skills resolve a {kind} (need exactly one)")
    chain = [SkillCall(approach.name, target, event), SkillCall(resolve[0].name, target, event)]
    for s in SKILLS.values():
        if s.role == "deliver" and s.follows == resolve[0].name:
            if goal is None:
                raise ValueError(f"{s.name} follows {resolve[0].name}: event {event} needs a goal")
            chain.append(SkillCall(s.name, goal, event))
    return chain


def apply_effect(world: World, call: SkillCall, spec: EpisodeSpec) -> None:
    """What `call`'s success changes in the world's bookkeeping (`Skill.effect`): a placed object
    rests on its goal from now on. (An opened door needs no bookkeeping: its angle is physics.)"""
    if skill(call.skill).effect == "places_object":
        name = carried_object(spec, call)
        if name is not None:
            world.receptacles[name] = Target.parse(call.target).index


def handover_call(chain: Sequence[SkillCall], k: int) -> SkillCall | None:
    """The chain entry whose stance (`Skill.stance`) the drive of entry `k` ends in: for an
    approach skill the next entry when it acts on the same target from a stance; for a skill
    that drives itself to a stance (Place's carry) the entry itself; else None (no hand-over)."""
    s = skill(chain[k].skill)
    if s.role == "approach":
        nxt = chain[k + 1] if k + 1 < len(chain) else None
        return nxt if nxt is not None and nxt.target == chain[k].target and skill(nxt.skill).stance is not None else None
    return chain[k] if s.drives and s.stance is not None else None


def skill(name: str) -> Skill:
    """The registered skill `name`; a KeyError names the known ones."""
    try:
        return SKILLS[name]
    except KeyError:
        raise KeyError(f"unknown skill {name!r} (known: {', '.join(SKILLS)})") from None


def skill_budget(recipe: Recipe, name: str) -> int:
    """Control steps skill `name` may take under `recipe` (see `Skill.step_budget`)."""
    return skill(name).step_budget(recipe)
