"""The hand-over (docs/handover.md): one stance per skill in the skill table, read by the chain
(`handover_call`), the environment (`info["skills"][k]["handed_over"]`), the runtime (a learned
drive that does not STOP ends there) and `evaluate`'s records."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from echo_data.agents.builtin import OraclePlanner, OracleSkills, StillSkills
from echo_data.episode import SkillCall
from echo_data.skill_table import SKILLS, STANCE_CENTRE, handover_call

ROOT = Path(__file__).resolve().parents[1]


def test_every_manipulation_skill_has_a_stance_inside_navigates_success_region() -> None:
    from echo_data.skills.success import NAV_SUCCESS_DIST, NAV_SUCCESS_YAW

    for s in SKILLS.values():
        if s.role == "approach":
            assert s.stance is None  # it drives to the next skill's stance
        else:
            assert s.stance is not None and 0 < s.stance.distance < NAV_SUCCESS_DIST and 0 < s.stance.heading < NAV_SUCCESS_YAW


def test_handover_call_names_whose_stance_a_drive_ends_in() -> None:
    relocation = (SkillCall("Navigate", "phone", 0), SkillCall("Pick", "phone", 0), SkillCall("Place", "furniture:2", 0))
    door = (SkillCall("Navigate", "door:1", 1), SkillCall("OpenDoor", "door:1", 1))
    assert handover_call(relocation, 0) is relocation[1]  # Navigate ends where Pick starts
    assert handover_call(relocation, 1) is None  # Pick does not drive
    assert handover_call(relocation, 2) is relocation[2]  # Place's carry ends in Place's own stance
    assert handover_call(door, 0) is door[1]
    assert handover_call((SkillCall("Navigate", "door:1", 1),), 0) is None  # nothing after it


class _DriveThatNeverStops:
    """A learner-like Navigate (not privileged, never STOPs): the Navigate expert's commands read
    through the environment the test holds, then holding still once the expert has arrived. It
    stands in for a learned drive so the runtime's ending rule is tested on real physics."""

    ends_itself = False
    observations = ("observation.state",)

    def __init__(self, env: Any) -> None:
        self.env, self.expert, self.still = env, OracleSkills(), StillSkills()
        self.arrived = False

    def reset(self, info: dict[str, Any]) -> None:
        spec = self.env.episode
        self.expert.reset({**info, "world": self.env.world, "call": spec.chain[info["skill_index"]], "spec_object": spec})
        self.still.reset(info)
        self.arrived = False

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        a = None if self.arrived else self.expert.act(obs)
        self.arrived = a is None
        return self.still.act(obs) if a is None else a


@pytest.fixture(scope="module")
def quick_env() -> Any:
    from echo_data.envs.env import EchoDataEnv

    env = EchoDataEnv(str(ROOT / "recipes" / "quickstart.yaml"), split="test", images=False, audio=False)
    yield env
    env.close()


@pytest.mark.parametrize("index", [0, 1])
def test_a_drive_that_does_not_stop_ends_in_the_stance_not_at_the_regions_edge(quick_env: Any, index: int) -> None:
    from echo_data.agents.runtime import run_episode

    env = quick_env
    stance = None
    ends = {}
    for drive_end in ("success", "handover", "centre"):
        obs, info = env.reset(options={"split": "test", "index": index})
        chain = env.episode.chain
        to = handover_call(chain, 0)
        assert to is not None
        stance = SKILLS[to.skill].stance
        assert all("handed_over" in s for s in info["skills"])
        run = run_episode(env, obs, info, OraclePlanner(), _DriveThatNeverStops(env), skills=1, drive_end=drive_end)
        assert run.outcomes[0].success, run.failure
        ends[drive_end] = run.navigate[0]
    assert stance is not None
    at_edge, inside = ends["success"], ends["handover"]
    # the paper's test alone ends it the first step inside its 1.5 m region, outside the stance
    assert not at_edge.handed_over and at_edge.goal_distance > stance.distance
    # the hand-over ends it inside the next skill's stance, later on the same path
    assert inside.handed_over and inside.goal_distance <= stance.distance and inside.heading_error <= stance.heading
    assert inside.path_length > at_edge.path_length
    # "centre" goes on past the stance's rim to its centre (the reported hand-over is the stance's)
    centre = ends["centre"]
    assert centre.handed_over and centre.goal_distance <= stance.distance * STANCE_CENTRE and centre.heading_error <= stance.heading * STANCE_CENTRE
    assert centre.path_length >= inside.path_length
    if index == 0:  # here the hand-over rule ends it at the rim (8° of the 10°): "centre" had to go on
        assert inside.heading_error > stance.heading * STANCE_CENTRE


def test_drive_end_is_checked() -> None:
    from echo_data.agents.runtime import run_episode

    with pytest.raises(ValueError, match="drive_end"):
        run_episode(None, {}, {}, OraclePlanner(), StillSkills(), drive_end="edge")


def test_the_experts_demonstrations_hand_over_inside_the_stance(quick_env: Any) -> None:
    """With `experts.handover_noise` 1 the experts' Navigate stops anywhere in the next skill's
    stance (never outside it); the runtime records that as a hand-over."""
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv

    recipe = quick_env.recipe.model_copy(update={"experts": quick_env.recipe.experts.model_copy(update={"handover_noise": 1.0})})
    env = EchoDataEnv(recipe, split="test", images=False, audio=False)
    try:
        offsets = []
        for index in (0, 1, 2):
            obs, info = env.reset(options={"split": "test", "index": index})
            run = run_episode(env, obs, info, OraclePlanner(), OracleSkills(), skills=1)
            nav = run.navigate[0]
            stance = SKILLS[env.episode.chain[1].skill].stance
            assert stance is not None and nav.success and nav.handed_over
            assert nav.goal_distance <= stance.distance and nav.heading_error <= stance.heading
            offsets.append(nav.goal_distance)
        assert max(offsets) > 0.02 and not math.isnan(max(offsets))  # drawn off the exact pose
    finally:
        env.close()
