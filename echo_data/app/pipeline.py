"""One episode end to end: sample the spec, let the experts act in the environment, keep what it saw and heard.

`generate_episode` is a plain function of (recipe, split, index, attempt): every worker on
every machine computes the same bytes for the same arguments. Episodes are run by
`echo_data.agents.runtime.run_episode` in `echo_data.envs.EchoDataEnv` (the same loop that
evaluates policies), so a dataset episode is exactly what the environment gives back.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from echo_data.app import episode_progress
from echo_data.envs.audio import PRE_ROLL_SECONDS, event_waveform, step_samples  # noqa: F401  (re-exported)
from echo_data.episode import EpisodeSpec, SkillCall
from echo_data.recipe import Recipe
from echo_data.records import EpisodeResult, StepRecord

if TYPE_CHECKING:
    from echo_data.agents.dart import Demonstrator
    from echo_data.app.handover_from import LearnerStops
    from echo_data.envs.env import EchoDataEnv
    from echo_data.sounds.library import SoundLibrary


def simulate(spec: EpisodeSpec, recipe: Recipe, observe: bool = True, library: SoundLibrary | None = None,
             handover_stops: Mapping[int, tuple[float, float, float]] | None = None) -> EpisodeResult:
    """Run `spec`'s chain with the scripted experts acting in the environment; record every step.

    `observe`: render the cameras. With a sound `library` the robot also hears (online audio,
    per-step features) and the result carries the finished episode track. The recipe's
    `outputs.max_frames` cuts the run after that many steps (`EpisodeResult.truncated_at`).
    `handover_stops`: chain index -> the pose that entry's Navigate expert stops at (a learner's
    hand-over, `World.handover_stops`); each such entry's hand-over record says whether it did.
    """
    from echo_data.agents.builtin import OraclePlanner
    from echo_data.agents.dart import Demonstrator
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv

    # The build's env speaks joint actions: the Demonstrator hands it the joint form of each step,
    # which for an ee-born command is `robot.ee.to_joint` of its ee form from this very commanded
    # state, i.e. exactly what the env computes in ee mode: both replays are bit-identical
    # (agents/dart.py). Joint-born commands (experts not yet rewritten) stay exact this way.
    env = EchoDataEnv(recipe, split=spec.split, images=observe, audio=library is not None, library=library, action_mode="joint")
    policy = Demonstrator(recipe.experts, recipe.robot.control_hz, spec.seed)  # labels its own, executes perturbed
    recorder = _Recorder(recipe.robot.control_hz, policy)
    budget = sum(recipe.robot.max_steps.get(c.skill, 0) for c in spec.chain)
    episode_progress.begin(min(budget, recipe.outputs.max_frames or budget))
    try:
        obs, info = env.reset(options={"spec": spec})
        env.world.handover_stops = dict(handover_stops or {})
        run = run_episode(env, obs, info, OraclePlanner(), policy, on_step=recorder, max_steps=recipe.outputs.max_frames)
        for k, pose in env.world.handover_stops.items():  # the expert set an unusable pose to None
            handover = run.outcomes[k].handover if k < len(run.outcomes) else None
            if handover is not None:
                handover.learner_stop = pose is not None
        if recorder.steps:  # the last stored step ends the episode
            recorder.steps[-1].done = True
            recorder.steps[-1].skill_success = done_flags(env)
            recorder.steps[-1].skill_stop = run.truncated_at is None  # a cut ends no skill
        success = len(run.outcomes) == len(spec.chain) and all(o.success for o in run.outcomes)
        ro = EpisodeResult(
            spec, recorder.steps, run.outcomes, success,
            resolved_frame=list(env.resolved_step), door_changes=list(env.door_changes), truncated_at=run.truncated_at,
        )
        if env.track is not None and recorder.steps:
            ro.audio, ro.audio_offsets = env.episode_audio()
            ro.spectrogram = _stack(recorder.spectrogram)
            ro.mel = _stack(recorder.mel)
        return ro
    finally:
        policy.close()
        env.close()


def done_flags(env: EchoDataEnv) -> tuple[bool, ...]:
    """The environment's success tests now, per chain entry (latched, in order: `info["skills"][k]["done"]`)."""
    return tuple(k < env.progress for k in range(len(env.episode.chain)))


def _stack(xs: list[np.ndarray]) -> np.ndarray | None:
    return np.stack(xs) if xs else None


class _Recorder:
    """Turns each (observation, action) the runtime is about to apply into a StepRecord.

    A row's `skill_success` is what the environment's success tests say after the row's action
    (the `info` that `step(action)` returns), so the flags and the `done` row agree with a replay:
    they are filled in when the next row arrives (nothing happens in between) or, for the last
    row, by `simulate`.

    The demonstrator's step gives both forms of the row's action (`action`, `action.ee`: the
    expert's own command; `executed`, `executed_ee`: what the robot is sent, when perturbed);
    the privileged columns are read from the world (`echo_data.envs.privileged`); `skill_stop`
    marks the last row of each skill segment (set when the next segment's first row arrives,
    and for the last row by `simulate`)."""

    def __init__(self, control_hz: int, demo: Demonstrator) -> None:
        from echo_data.envs.privileged import PrivilegedProbe

        self.control_hz = control_hz
        self.demo = demo
        self.probe = PrivilegedProbe()
        self.steps: list[StepRecord] = []
        self.spectrogram: list[np.ndarray] = []
        self.mel: list[np.ndarray] = []

    def __call__(self, env: EchoDataEnv, obs: dict[str, np.ndarray], action: np.ndarray, k: int, call: SkillCall, flags: tuple[bool, ...]) -> None:
        from echo_data.dataset.schema import IMAGE_COLUMNS, MEL, SPECTROGRAM, STATE

        x, y, z, yaw = env.ear_pose()
        frame = len(self.steps)
        if self.steps:
            self.steps[-1].skill_success = done_flags(env)
            self.steps[-1].skill_stop = self.steps[-1].skill_index != k
        d = self.demo.step
        if d is None or not np.array_equal(d.executed, action):
            raise RuntimeError(f"frame {frame}: the runtime applies an action the demonstrator did not give")
        self.steps.append(StepRecord(
            frame_index=frame,
            timestamp=frame / self.control_hz,
            skill=call.skill,
            skill_index=k,
            action=d.label,
            state=obs[STATE],
            head_rgb=obs.get(IMAGE_COLUMNS["head_rgb"]),
            head_depth=obs.get(IMAGE_COLUMNS["head_depth"]),
            wrist_depth=obs.get(IMAGE_COLUMNS["wrist_depth"]),
            ear_position=(x, y, z),
            ear_yaw=yaw,
            sounding=tuple(env.sounding),
            camera_poses=env.world.robot.camera_poses(),
            executed=None if np.array_equal(d.executed, d.label) else d.executed,
            action_ee=d.label_ee,
            executed_ee=None if np.array_equal(d.executed_ee, d.label_ee) else d.executed_ee,
            privileged=self.probe(env.world, env.episode, call),
        ))
        if SPECTROGRAM in obs:
            self.spectrogram.append(obs[SPECTROGRAM])
        if MEL in obs:
            self.mel.append(obs[MEL])
        episode_progress.step(len(self.steps))


def render_episode_audio(spec: EpisodeSpec, rollout: EpisodeResult, recipe: Recipe, library: SoundLibrary) -> tuple[np.ndarray, np.ndarray]:
    """The binaural track of a recorded rollout (its ear poses, stops and door changes) and each
    step's sample offset: the same `OnlineTrack` the environment hears with, fed after the fact."""
    from echo_data.envs.audio import OnlineTrack

    track = OnlineTrack(spec, recipe, library)
    poses = [[*s.ear_position, s.ear_yaw] for s in rollout.steps] or [[*spec.start[:2], recipe.acoustics.ear_height, spec.start[2]]]
    doors = dict(rollout.door_changes)
    track.pre_roll(poses[0])
    for e, f in enumerate(rollout.resolved_frame):
        if f == 0:
            track.stop(e)
    for t, pose in enumerate(poses[: len(rollout.steps)]):
        if t + 1 in doors:
            track.open_doors(doors[t + 1], at=track.samples + track.hop)
        track.step(pose)
        for e, f in enumerate(rollout.resolved_frame):
            if f == t + 1:
                track.stop(e)
    return track.finish(), track.offsets(len(rollout.steps))


def generate_episode(
    recipe: Recipe,
    split: str,
    index: int,
    library: SoundLibrary,
    recipe_dir: Path | None = None,
    attempt: int = 0,
    learner: LearnerStops | None = None,
) -> EpisodeResult:
    """Sample, simulate and hear one episode. `attempt` > 0 retries with fresh seeds after an expert failure.
    `learner`: a learner's hand-overs in this episode (`build --handover-from`), used when the
    sampled spec is the one it ran (same seed; a retry's fresh draw is built as usual).

    Raises `echo_data.scene.sampling.SamplingError` when no solvable episode is found within
    the recipe's attempt budget. An expert failure is returned (success False) with reasons; an
    episode cut by `outputs.max_frames` is complete (`truncated_at` set, success False).
    """
    from echo_data.scene.sampling import sample_episode

    spec, rejected = sample_episode(recipe, split, index, library, attempt=attempt)
    stops = learner.stops if learner is not None and learner.seed == spec.seed else None
    result = simulate(spec, recipe, observe=True, library=library, handover_stops=stops)
    result.rejected = rejected
    return result
