"""The paper's two-level agent run in the environment: one plan, then one policy per skill.

`run_episode` is the one loop that runs an episode, for the build's experts and for any policy
under evaluation:
1. the planner answers with a skill chain in the planner export's JSON
   (`[{"skill": "Navigate", "target": "phone"}, ...]`); the plan is right when it equals the
   episode's true chain exactly, order included;
2. with a right plan, each skill of the chain runs until its success test holds or its step
   budget from the recipe runs out; a failed skill ends the episode. Success is the
   environment's one evaluation per step (`info["skills"]`; the dataset's `skill_success`
   column records its in-order latched form, `done`). Policies that end themselves run until
   they return None (STOP) and are then tested on the state they stopped in:
   - the scripted experts (privileged): after a skill's test first holds, an expert still lets
     go, backs off and tucks the arm, which the next skill starts from, so those steps belong
     to the skill (the step rows say so: that skill's `skill_success` flag is already true).
     The last skill ends where its test first holds: the environment then terminates the
     episode and refuses further steps;
   - a learned policy (SoundSpaces' STOP): the environment waits for its stop
     (`env.agent_stops`), then `env.stop_skill()` evaluates the test once: the skill counts
     only if it holds there, else the episode ends failed.
3. a Place whose learned policy was trained from its stance on (`--from-stance`) is carried by
   the drive policy first, inside the same chain entry (`carry_call`, docs/handover.md#places-carry):
   the planner's chain stays one Place entry.

What a policy is given is observations only (`echo_data.protocols`): its reset info is the call
as a listener says it (`skill_info`), `act` gets the environment's observation plus, when the
policy lists them in `observations`, `GOAL_POSE` (the starred rows' target position) and the
`observation.privileged.*` columns (the privileged sanity learner: computed from the world by
the build's own `envs.privileged.PrivilegedProbe` before each action, so acting sees what the
rows hold; `RUNTIME_OBSERVATIONS`). The world, the skill call and the episode spec go to
privileged policies (the scripted experts) only.

A non-finite action ends the episode as failed with that reason; an action that is not 12 real
numbers (wrong shape, complex, not numbers) is the policy's bug and raises `AgentActionError`.

`max_steps` cuts an episode after its first `max_steps` control steps (the recipe's
`outputs.max_frames`, for data that needs only the first seconds): the policy acts exactly as it
would in the whole episode up to the cut, skills finished by then keep their outcomes, the skill
running at the cut gets none, and `EpisodeRun.truncated_at` records the cut. A chain that ends
within the budget is not truncated.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from echo_data.episode import EpisodeSpec, SkillCall
from echo_data.protocols import Planner, Policy, is_privileged
from echo_data.records import ACTION_DIM, EE_ACTION_DIM, GOAL_POSE, PRIVILEGED_COLUMNS, HandOverRecord, SkillOutcome

if TYPE_CHECKING:
    from echo_data.envs.env import EchoDataEnv


class AgentActionError(ValueError):
    """A policy returned something that is not an action of the dataset's shape."""


class StopEpisode(Exception):
    """Raised by an `on_step` hook to end the episode before that action is applied (like a
    `max_steps` cut: the running skill gets no outcome, `truncated_at` records where)."""


@dataclass
class NavigateRecord:
    """One Navigate skill as SPL needs it: success, the agent's path, the expert's planned path."""

    skill_index: int
    success: bool
    path_length: float  # metres the base travelled during the skill
    expert_length: float  # metres of the navigation expert's planned path from the skill's start
    # Where it handed over, against the goal the expert stops at (its interaction pose, fixed at
    # the skill's start; nan: no goal): the base's distance (m) and heading error (rad, wrapped),
    # and how far the arm moved during the drive (largest change of a torso or arm joint, rad;
    # the experts hold it). The next skill's demonstrations start at that pose with that arm.
    goal_distance: float = math.nan
    heading_error: float = math.nan
    arm_moved: float = math.nan
    # Whether it ended inside the next skill's stance (the environment's `handed_over`,
    # docs/handover.md); the paper's Navigate success is `success`.
    handed_over: bool = False

    @property
    def spl(self) -> float:
        """Success weighted by path length: S * l / max(l, p) (Anderson et al., 2018)."""
        if not self.success:
            return 0.0
        return self.expert_length / max(self.expert_length, self.path_length, 1e-9)


@dataclass
class EpisodeRun:
    """How one episode went under one agent."""

    episode_id: str
    setting: str
    seed: int
    true_chain: list[dict[str, str]]
    planned_chain: list[dict[str, str]] | None  # None: the planner's answer was not a chain (see `failure`)
    plan_correct: bool
    outcomes: list[SkillOutcome] = field(default_factory=list)
    navigate: list[NavigateRecord] = field(default_factory=list)
    # Place's carries done by the drive policy (`carry_call`): where each handed over into Place's
    # stance, as a Navigate's record (its skill_index the Place entry's; success = handed over)
    carries: list[NavigateRecord] = field(default_factory=list)
    steps: int = 0
    failure: str = ""
    truncated_at: int | None = None  # control steps run when `max_steps` cut the episode

    @property
    def skills_completed(self) -> int:
        """Skills of the true chain that succeeded in order (0 when the plan is wrong)."""
        n = 0
        for o in self.outcomes:
            if not o.success:
                break
            n += 1
        return n if self.plan_correct else 0

    @property
    def success(self) -> bool:
        """Skill-completion success: the plan right and every skill succeeded in order."""
        return self.plan_correct and self.skills_completed == len(self.true_chain)


def true_chain(spec: EpisodeSpec) -> list[dict[str, str]]:
    """The episode's chain as the planner export writes it (targets named as a listener would)."""
    from echo_data.dataset.encode import target_kind

    return [{"skill": c.skill, "target": target_kind(c.target, spec.plan)} for c in spec.chain]


class PlanError(ValueError):
    """A planner's answer that is not a skill chain; the message says what is wrong with it."""


def normalise_plan(plan: Any) -> list[dict[str, str]]:
    """A planner's answer (a list or tuple of {"skill", "target"} strings, or its JSON text) as plain
    JSON-able lists and strings; anything else raises `PlanError` saying why, so a planner's
    arrays, generators or objects never reach the results file."""
    import json

    if isinstance(plan, str):
        try:
            plan = json.loads(plan)
        except ValueError:
            raise PlanError("not JSON text") from None
    if not isinstance(plan, (list, tuple)):
        raise PlanError(f"expected a list of {{'skill', 'target'}}, got {type(plan).__name__}")
    out = []
    for i, c in enumerate(plan):
        if not isinstance(c, dict) or not isinstance(c.get("skill"), str) or not isinstance(c.get("target"), str):
            raise PlanError(f"item {i}: expected {{'skill': str, 'target': str}}, got {type(c).__name__}")
        out.append({"skill": str(c["skill"]), "target": str(c["target"])})
    return out


def _expert_path(env: EchoDataEnv, call: SkillCall) -> tuple[float, tuple[float, float, float] | None]:
    """Length of the navigation expert's planned path from where the base stands to the skill's
    goal (nan: no goal or path), and that goal (its interaction pose; None when it has none)."""
    from echo_data.skills.navigate import goal_pose, path_length

    grid = env.nav_grid()
    world = env.world
    try:
        goal = goal_pose(world, call.target, grid)
    except ValueError:
        return math.nan, None
    return path_length(grid, world.robot.base_pose(), goal), goal


def _arm_joints(env: EchoDataEnv) -> np.ndarray:
    robot = env.world.robot
    return np.concatenate([[robot.torso()], robot.arm_qpos()])


def _handover(env: EchoDataEnv, goal: tuple[float, float, float] | None, arm_start: np.ndarray) -> dict[str, float]:
    """`NavigateRecord`'s hand-over fields for the base and arm now."""
    from echo_data.skills.navigate import wrap

    x, y, yaw = env.world.robot.base_pose()
    moved = float(np.max(np.abs(_arm_joints(env) - arm_start)))
    if goal is None:
        return {"arm_moved": moved}
    return {"goal_distance": math.hypot(x - goal[0], y - goal[1]), "heading_error": abs(wrap(yaw - goal[2])), "arm_moved": moved}


def handover_record(env: EchoDataEnv, info: dict[str, Any], k: int) -> HandOverRecord | None:
    """Where chain entry `k` ended against the stance it hands over to (`skill_table.handover_call`;
    None when it hands over to none): the base pose now, that target's interaction pose with the
    doors as they stand, and the environment's `handed_over` of the step that ended it."""
    from echo_data.skill_table import SKILLS, handover_call
    from echo_data.skills.navigate import goal_pose, wrap

    chain = env.episode.chain
    to = handover_call(chain, k)
    stance = SKILLS[to.skill].stance if to is not None else None
    if to is None or stance is None:
        return None
    end = env.world.robot.base_pose()
    try:
        goal: tuple[float, float, float] | None = goal_pose(env.world, to.target, env.nav_grid())
    except ValueError:
        goal = None
    return HandOverRecord(
        to.skill, k if to is chain[k] else k + 1, stance.distance, stance.heading, end, goal,
        None if goal is None else math.hypot(end[0] - goal[0], end[1] - goal[1]), None if goal is None else abs(wrap(end[2] - goal[2])),
        bool(info["skills"][k]["handed_over"]))


# Observation keys the runtime adds for a policy that lists them (no env observation holds them).
RUNTIME_OBSERVATIONS = (GOAL_POSE, *PRIVILEGED_COLUMNS)


def _goal_observation(env: EchoDataEnv, call: SkillCall) -> np.ndarray:
    """`GOAL_POSE` for skill `call`: its target's interaction pose now (NaN when it has none)."""
    from echo_data.skills.navigate import goal_pose

    try:
        return np.asarray(goal_pose(env.world, call.target, env.nav_grid()), dtype=np.float32)
    except ValueError:
        return np.full(3, np.nan, dtype=np.float32)


def skill_info(call: SkillCall, k: int, target_kind: str, budget: int, seed: int, action_mode: str = "joint") -> dict[str, Any]:
    """What every policy's `reset` gets (`echo_data.protocols.SKILL_INFO`): the call as a listener
    says it, and the form `act` must return (12 joint or 11 ee floats)."""
    return {"skill": call.skill, "target": call.target, "target_kind": target_kind, "skill_index": k,
            "event": call.event, "budget": budget, "episode_seed": seed, "action_mode": action_mode}


def succeeded(info: dict[str, Any], k: int) -> bool:
    """Chain skill k's success test as the environment evaluated it at its last step (`info["skills"]`)."""
    return bool(info["skills"][k]["success"])


# How a learned drive that does not STOP ends (`run_episode(drive_end=...)`, docs/handover.md):
# "handover": when it stands inside the next skill's stance (its success test holding too), or at
# its budget, where the success test on that state decides; "centre": as "handover", but only once
# it stands in the stance's centre (`skill_table.STANCE_CENTRE`), not the first step inside its
# rim; "success": the first step its success test holds (the paper's 1.5 m region: it hands over
# at the region's edge). The hand-over recorded and reported is the stance's in every case.
DRIVE_ENDS = ("handover", "centre", "success")


class Leg(NamedTuple):
    """What one policy's run of steps in a chain entry left (`run_episode`'s `leg`)."""

    n: int  # control steps taken
    path: float  # metres the base travelled
    reason: str  # why it failed ("" none)
    ended: bool  # the episode ended during it
    stops: bool  # a learned STOP ended it, judged by the environment (`stop_skill`)


def carry_call(policy: Any, call: SkillCall) -> SkillCall | None:
    """The drive call that carries for `call` before its skill acts, or None (the skill drives
    itself, as the Place expert does): for a deliver skill (Place) whose policy starts in its
    stance (a run trained `--from-stance`, which sets `starts_in_stance`), the approach skill
    (Navigate) to the same target, acted by the policy's member for the approach skill
    (`agents.compose.SkillDispatch.policy_for`). docs/handover.md#places-carry."""
    from echo_data.skill_table import SKILLS, approach_skill

    member = getattr(policy, "policy_for", None)
    if not SKILLS[call.skill].delivers or not callable(member) or not getattr(member(call.skill), "starts_in_stance", False):
        return None
    return SkillCall(approach_skill().name, call.target, call.event)


StepHook = Callable[["EchoDataEnv", dict[str, np.ndarray], np.ndarray, int, SkillCall, tuple[bool, ...]], None]


def run_episode(
    env: Any, first_obs: dict[str, np.ndarray], info: dict[str, Any], planner: Planner, policy: Policy,
    on_step: StepHook | None = None, max_steps: int | None = None, skills: int | None = None,
    drive_end: str = "handover",
) -> EpisodeRun:
    """Run one episode already reset in `env` (its first observation and info) with a planner and a skill policy.
    Long because it is the one episode loop (build, evaluate and DAgger share it): its per-skill
    state (budget, probe, path, stop) lives across the steps of one loop, kept in one place.

    Success is read from the environment's `info["skills"]` (one evaluation per step).
    `on_step(env, obs, action, skill_index, call, skill_flags)` is called before each action is
    applied (the build records its rows there; DAgger labels there); it may raise `StopEpisode`.
    A Place whose policy starts in its stance is carried first (`carry_call`): the drive policy
    runs in the same entry until the environment's `handed_over` holds or the approach skill's
    budget is spent (a STOP ends only the carry), then the skill's own policy with the rest of
    the entry's budget; `on_step` gets the drive call during the carry, `run.carries` its record.
    `max_steps`: cut the episode after that many control steps (see the module docstring);
    `skills`: run only the chain's first `skills` skills; `drive_end`: see `DRIVE_ENDS`.
    """
    from echo_data.envs.env import EnvInputError, as_action
    from echo_data.envs.privileged import PrivilegedProbe
    from echo_data.skill_table import SKILLS, handover_call, skill_budget

    if drive_end not in DRIVE_ENDS:
        raise ValueError(f"drive_end {drive_end!r}: expected one of {', '.join(DRIVE_ENDS)}")
    env = getattr(env, "unwrapped", env)  # gymnasium wrappers around an EchoDataEnv
    spec: EpisodeSpec = env.episode
    truth = true_chain(spec)
    reset_planner = getattr(planner, "reset", None)  # optional (echo_data.protocols)
    if callable(reset_planner):  # the episode's truth (the env's info holds the chain) for a privileged planner only
        reset_planner({**info, "true_chain": truth, "spec_object": spec} if is_privileged(planner)
                      else {"episode_id": spec.episode_id, "episode_seed": spec.seed})
    try:
        planned: list[dict[str, str]] | None = normalise_plan(planner.plan(first_obs))
        malformed = ""
    except PlanError as e:
        planned, malformed = None, str(e)
    run = EpisodeRun(spec.episode_id, spec.setting, spec.seed, truth, planned, planned == truth)
    if not run.plan_correct:
        run.failure = "plan wrong" if planned is not None else f"plan malformed: {malformed}"
        return run
    obs = first_obs

    def flags() -> tuple[bool, ...]:  # the environment's latched success tests now, per chain entry
        return tuple(bool(s["done"]) for s in info["skills"])

    def cut() -> bool:
        return max_steps is not None and env.steps >= max_steps

    mode = getattr(env, "action_mode", "joint")  # an EchoDataEnv's "joint" | "ee_delta"

    def leg(k: int, call: SkillCall, acting: SkillCall, budget: int, carry: bool) -> Leg:
        """One policy's run of control steps in chain entry `k`: the skill `call`, or the carry
        before it (`carry`), which the policy acts as the drive call `acting`."""
        nonlocal obs, info
        reset_info = skill_info(acting, k, truth[k]["target"], budget, spec.seed, mode)
        if is_privileged(policy):  # the scripted experts plan on the true state (echo_data.protocols)
            reset_info.update(call=acting, spec_object=spec, world=env.world)
        policy.reset(reset_info)
        # after reset: a per-skill policy switches (a composition names its acting member `active`)
        ends_itself = bool(getattr(policy, "ends_itself", False))
        # a learned policy's STOP: the env waits for it (a carry's STOP only ends the carry)
        stops = ends_itself and not carry and not is_privileged(getattr(policy, "active", policy))
        if stops or getattr(env, "agent_stops", False):
            env.agent_stops = stops
        wanted = getattr(policy, "observations", None) or ()
        goal = _goal_observation(env, call) if GOAL_POSE in wanted else None
        probe = PrivilegedProbe() if any(c in wanted for c in PRIVILEGED_COLUMNS) else None
        # a learned drive that does not STOP ends at the hand-over (else at its success test); a carry always at its hand-over
        at_handover = carry or (SKILLS[call.skill].role == "approach" and not ends_itself and drive_end in ("handover", "centre")
                                and handover_call(spec.chain, k) is not None)
        end_flag = "handed_over" if at_handover else "success"
        centre = at_handover and not carry and drive_end == "centre"  # on past the stance's rim to its centre
        path, n, reason, ended = 0.0, 0, "", False
        while True:
            if (carry or not ends_itself) and info["skills"][k][end_flag] and (not centre or env.in_stance_centre(k)):
                break
            if goal is not None:
                obs = {**obs, GOAL_POSE: goal}
            if probe is not None:  # the state this observation shows, as the build's rows
                obs = {**obs, **probe(env.world, spec, call)}
            action = policy.act(obs)
            if action is None:  # the policy ended the skill itself (STOP)
                if stops:  # its success test on the state it stopped in decides (the env's STOP)
                    obs, _, terminated, _, info = env.stop_skill()
                    reason = info.get("failure", "")
                    ended = terminated
                break
            if cut():  # after act(): a skill that ends exactly at the cut is finished, not cut
                run.truncated_at = env.steps
                break
            if n >= budget:  # a drive out of steps inside its success region still counts (as the expert's); a carry hands over as it stands
                reason = "" if carry or (at_handover and succeeded(info, k)) else "timeout"
                break
            try:
                a = as_action(action, EE_ACTION_DIM if mode == "ee_delta" else ACTION_DIM)
            except EnvInputError as e:
                raise AgentActionError(f"policy {e} at step {env.steps}") from None
            if on_step is not None:
                try:
                    on_step(env, obs, a, k, acting, flags())
                except StopEpisode:
                    run.truncated_at = env.steps
                    break
            x0, y0, _ = env.world.robot.base_pose()
            obs, _, terminated, truncated, info = env.step(a)
            n += 1
            if info.get("failure"):
                reason = info["failure"]
                break
            x1, y1, _ = env.world.robot.base_pose()
            path += math.hypot(x1 - x0, y1 - y0)
            if terminated or truncated:  # the chain is done (or past the episode's budget): no step follows
                ended = True
                reason = "" if terminated else "timeout" if n >= budget else "episode step limit"
                break
        close = getattr(policy, "close", None)  # optional (echo_data.protocols)
        if (reason or ended or run.truncated_at is not None) and ends_itself and callable(close):
            close()
        return Leg(n, path, reason, ended, stops)

    for k, call in enumerate(spec.chain[:skills]):
        if cut():  # the previous skill ended exactly at the cut and more of the chain remains
            run.truncated_at = env.steps
            break
        budget = skill_budget(env.recipe, call.skill)
        approach = SKILLS[call.skill].role == "approach"  # Navigate: scored by SPL too
        carried = carry_call(policy, call)  # Place carried by the drive policy (docs/handover.md#places-carry)
        drives = approach or carried is not None
        expert_len, nav_goal = _expert_path(env, call) if drives else (math.nan, None)
        arm_start = _arm_joints(env) if drives else np.zeros(0)  # where the arm was when a drive began (its hand-over record)
        used = 0
        if carried is not None:  # first the drive policy to this entry's stance, within the approach skill's budget
            part = leg(k, call, carried, min(skill_budget(env.recipe, carried.skill), budget), True)
            handed = bool(info["skills"][k]["handed_over"])
            if run.truncated_at is None:  # (a carry running at the cut has no record, as a skill has no outcome)
                run.carries.append(NavigateRecord(k, handed, part.path, expert_len, **_handover(env, nav_goal, arm_start), handed_over=handed))
            used = part.n
        if carried is None or not (part.reason or part.ended or run.truncated_at is not None):
            part = leg(k, call, call, budget - used, False)
            used += part.n
        if run.truncated_at is not None:  # the skill running at the cut has no outcome
            break
        reason = part.reason
        ok = not reason and (bool(info["skills"][k]["done"]) if part.stops else succeeded(info, k))
        if not ok and not reason:
            expert = getattr(policy, "outcome", None)
            reason = getattr(expert, "reason", "") or "success test false"
        run.outcomes.append(SkillOutcome(call.skill, call.target, ok, "" if ok else reason, used, handover_record(env, info, k)))
        if approach:
            run.navigate.append(NavigateRecord(k, ok, part.path, expert_len, **_handover(env, nav_goal, arm_start),
                                               handed_over=bool(info["skills"][k]["handed_over"])))
        if not ok:
            run.failure = f"{call.skill}({call.target}): {reason}"
            break
    run.steps = env.steps
    return run
