"""Run an episode's skill chain with the scripted experts and record every control step.

The experts are generators of actions; this loop is the one place that applies actions,
renders observations and decides when an event's sound stops, so recording is uniform
across skills and an expert cannot forget to log a step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from echo_data.episode import EpisodeSpec
from echo_data.records import ACTION_DIM, SkillOutcome, StepRecord

# The skill whose success resolves an event (and silences its sound): a ringing phone is
# resolved when it is picked up, a doorbell when the door is open, a faucet when closed.
RESOLVING_SKILLS = ("Pick", "OpenDoor", "CloseSink")
# Extra steps the loop grants beyond a skill's own limit before it calls the skill stuck.
_GUARD_STEPS = 20


@dataclass
class Rollout:
    """What a chain produced: per-step records, per-skill outcomes, when each event resolved."""

    steps: list[StepRecord]
    outcomes: list[SkillOutcome]
    resolved_frame: list[int | None]  # per event: frame index at which its sound stops
    chain_length: int
    # (frame, hinge angles of every door) after each successful OpenDoor: the acoustics
    # switch to the opened geometry from that frame on.
    door_changes: list[tuple[int, dict[int, float]]] = field(default_factory=list)

    @property
    def success(self) -> bool:
        """The episode succeeds when every skill of the chain succeeded, in order."""
        return len(self.outcomes) == self.chain_length and all(o.success for o in self.outcomes)


def run_chain(
    world: object,
    spec: EpisodeSpec,
    max_steps: dict[str, int],
    control_hz: int,
    experts: dict[str, Callable] | None = None,
    observe: bool = True,
    on_step: Callable[[StepRecord], None] | None = None,
) -> Rollout:
    """Run `spec.chain` in order in `world`, stopping at the first failed skill.

    Observations are taken before each action is applied (LeRobot convention: the action at
    frame t is what the expert chose after seeing observation t).
    """
    if experts is None:
        from echo_data.skills import EXPERTS

        experts = EXPERTS
    robot = world.robot  # type: ignore[attr-defined]
    steps: list[StepRecord] = []
    outcomes: list[SkillOutcome] = []
    resolved: list[int | None] = [None] * len(spec.events)
    flags = [False] * len(spec.chain)
    door_changes: list[tuple[int, dict[int, float]]] = []
    last_of_event = {call.event: k for k, call in enumerate(spec.chain) if call.skill in RESOLVING_SKILLS}

    for k, call in enumerate(spec.chain):
        expert = experts[call.skill](world, call, spec)
        # Place drives to its goal receptacle before it lowers the object: it may use the
        # Navigate budget for the drive on top of its own.
        budget = max_steps[call.skill] + (max_steps["Navigate"] if call.skill == "Place" else 0) + _GUARD_STEPS
        n = 0
        outcome: SkillOutcome | None = None
        while True:
            try:
                action = next(expert)
            except StopIteration as stop:
                outcome = stop.value
                break
            if n >= budget:
                expert.close()
                outcome = SkillOutcome(call.skill, call.target, False, "timeout", n)
                break
            action = np.asarray(action, dtype=np.float32).reshape(ACTION_DIM)
            obs = world.observe() if observe else {}  # type: ignore[attr-defined]
            state = robot.state().astype(np.float32)
            ear_pos, ear_yaw = robot.ear_pose()
            frame = len(steps)
            rec = StepRecord(
                frame_index=frame,
                timestamp=frame / control_hz,
                skill=call.skill,
                skill_index=k,
                action=action,
                state=state,
                head_rgb=obs.get("head_rgb"),
                head_depth=obs.get("head_depth"),
                wrist_depth=obs.get("wrist_depth"),
                ear_position=tuple(float(v) for v in ear_pos),
                ear_yaw=float(ear_yaw),
                sounding=tuple(r is None for r in resolved),
                skill_success=tuple(flags),
                camera_poses=robot.camera_poses(),
            )
            world.step(action)  # type: ignore[attr-defined]
            steps.append(rec)
            if on_step is not None:
                on_step(rec)
            n += 1
        if outcome is None:  # an expert that returns nothing has failed to say it succeeded
            outcome = SkillOutcome(call.skill, call.target, False, "no outcome", n)
        outcomes.append(outcome)
        flags[k] = bool(outcome.success)
        if not outcome.success:
            break
        if last_of_event.get(call.event) == k:
            resolved[call.event] = len(steps)
        if call.skill == "OpenDoor":
            door_changes.append((len(steps), dict(world.door_angles())))  # type: ignore[attr-defined]
    if steps:
        steps[-1].done = True
        steps[-1].skill_success = tuple(flags)
    return Rollout(steps=steps, outcomes=outcomes, resolved_frame=resolved, chain_length=len(spec.chain), door_changes=door_changes)


def records_digest(steps: list[StepRecord]) -> str:
    """sha256 over every field of every step record: equal digests mean bit-identical rollouts."""
    import hashlib

    h = hashlib.sha256()
    for s in steps:
        h.update(f"{s.frame_index}|{s.timestamp!r}|{s.skill}|{s.skill_index}|{s.ear_position!r}|{s.ear_yaw!r}|{s.sounding}|{s.skill_success}|{s.done}".encode())
        for arr in (s.action, s.state, s.head_rgb, s.head_depth, s.wrist_depth):
            if arr is not None:
                a = np.ascontiguousarray(arr)
                h.update(f"{a.dtype}{a.shape}".encode())
                h.update(a.tobytes())
    return h.hexdigest()
