"""Every skill of the robot, declared once: its expert, its success test, whether its success
resolves (silences) its event, its step budget and what it acts on.

The environment, the runtime, the experts' table and the tests read this registry; nothing
else dispatches on skill names. Adding a skill is one module (expert + success test) and one
`Skill(...)` line below (and its step limit in the recipe's `robot.max_steps`).

Experts are named "module:function" and imported on first use, so reading the registry does
not load mplib.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from echo_data.skills import success as S
from echo_data.target import Target, TargetKind

if TYPE_CHECKING:
    from echo_data.episode import EpisodeSpec, SkillCall
    from echo_data.recipe import Recipe
    from echo_data.world import World

# Extra steps granted beyond a skill's own limit before it is called stuck.
GUARD_STEPS = 20


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
    """One skill's contract."""

    name: str
    expert: str  # "module:function", a generator expert(world, call, spec) -> SkillOutcome
    success: SuccessTest  # on the live world, after any control step
    resolves_event: bool  # its success silences its event's sound (a picked-up phone, an opened door)
    budget: tuple[str, ...]  # recipe `robot.max_steps` keys whose limits add up to its step limit
    targets: tuple[TargetKind, ...]  # what `call.target` may name

    def expert_fn(self) -> Callable[..., Any]:
        module, _, name = self.expert.partition(":")
        return getattr(importlib.import_module(module), name)

    def step_budget(self, recipe: Recipe) -> int:
        """Control steps the skill may take: its recipe limits plus GUARD_STEPS."""
        limits: dict[str, int] = {str(k): int(v) for k, v in recipe.robot.max_steps.items()}
        return sum(limits[k] for k in self.budget) + GUARD_STEPS


def carried_object(spec: EpisodeSpec, call: SkillCall) -> str | None:
    """The object a Place call carries: the Pick target of the same event."""
    return next((c.target for c in spec.chain if c.event == call.event and c.skill == "Pick"), None)


def _navigated(world: World, call: SkillCall, at: Situation) -> bool:
    return S.navigate_success(world, call.target, grid=at.nav_grid(), poses=at.poses)


def _picked(world: World, call: SkillCall, at: Situation) -> bool:
    return S.pick_success(world, call.target)


def _placed(world: World, call: SkillCall, at: Situation) -> bool:
    name = carried_object(at.spec, call)
    return name is not None and S.place_success(world, name, Target.parse(call.target).index)


def _door_opened(world: World, call: SkillCall, at: Situation) -> bool:
    return S.door_open_success(world, Target.parse(call.target).index)


def _sink_closed(world: World, call: SkillCall, at: Situation) -> bool:
    return S.sink_closed_success(world, Target.parse(call.target).index)


SKILLS: dict[str, Skill] = {
    s.name: s
    for s in (
        Skill("Navigate", "echo_data.skills.navigate:navigate", _navigated, False, ("Navigate",), ("object", "door", "faucet", "furniture")),
        Skill("Pick", "echo_data.skills.pick:pick", _picked, True, ("Pick",), ("object",)),
        # Place also drives the object across the apartment: Navigate's limit is added to its own.
        Skill("Place", "echo_data.skills.place:place", _placed, False, ("Place", "Navigate"), ("furniture",)),
        Skill("OpenDoor", "echo_data.skills.open_door:open_door", _door_opened, True, ("OpenDoor",), ("door",)),
        Skill("CloseSink", "echo_data.skills.close_sink:close_sink", _sink_closed, True, ("CloseSink",), ("faucet",)),
    )
}
RESOLVING_SKILLS: tuple[str, ...] = tuple(n for n, s in SKILLS.items() if s.resolves_event)


def skill(name: str) -> Skill:
    """The registered skill `name`; a KeyError names the known ones."""
    try:
        return SKILLS[name]
    except KeyError:
        raise KeyError(f"unknown skill {name!r} (known: {', '.join(SKILLS)})") from None


def skill_budget(recipe: Recipe, name: str) -> int:
    """Control steps skill `name` may take under `recipe` (see `Skill.step_budget`)."""
    return skill(name).step_budget(recipe)
