"""One episode end to end: sample the spec, simulate the expert, render what the robot hears.

`generate_episode` is a plain function of (recipe, split, index, attempt): every worker on
every machine computes the same bytes for the same arguments.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from echo_data.episode import EpisodeSpec
from echo_data.pcm import as_written
from echo_data.recipe import Recipe
from echo_data.records import EpisodeResult
from echo_data.rollout import Rollout, run_chain

# The event has been sounding for this long when the robot's first observation is taken:
# the first step's spectrogram then holds a full second of the event, as a robot that reacts
# to a sound would hear it. The episode WAV starts at the beginning of this pre-roll.
PRE_ROLL_SECONDS = 1.0


def step_samples(recipe: Recipe) -> int:
    """Audio samples per control step."""
    return recipe.acoustics.sample_rate // recipe.robot.control_hz


def _epoch_window(n: int, start: int | None, end: int | None, ramp: int) -> np.ndarray:
    """Weight of one geometry epoch: 1 inside [start, end), raised-cosine ramps of `ramp` samples
    centred on the boundaries (None = open-ended), so consecutive windows sum to exactly 1."""
    t = np.arange(n, dtype=np.float64)
    w = np.ones(n)
    for edge, rising in ((start, True), (end, False)):
        if edge is None:
            continue
        x = np.clip((t - (edge - ramp / 2)) / ramp, 0.0, 1.0)
        up = 0.5 - 0.5 * np.cos(np.pi * x)
        w *= up if rising else 1.0 - up
    return w


def simulate(spec: EpisodeSpec, recipe: Recipe, observe: bool = True) -> Rollout:
    """Build the SAPIEN world for `spec` and run its skill chain with the scripted experts."""
    from echo_data.world import World

    world = World(spec, recipe, render=observe)
    try:
        return run_chain(world, spec, dict(recipe.robot.max_steps), recipe.robot.control_hz, observe=observe)
    finally:
        world.close()


def render_episode_audio(spec: EpisodeSpec, rollout: Rollout, recipe: Recipe, library: object) -> tuple[np.ndarray, np.ndarray]:
    """The binaural episode track along the robot's actual path, and each step's sample offset.

    Sources play from the start of the pre-roll until the step at which their event was
    resolved (then fade out; reverberation decays naturally). The head stays at its first
    pose during the pre-roll.
    """
    from echo_data.acoustics.hrtf import Hrtf
    from echo_data.acoustics.room import AcousticScene
    from echo_data.acoustics.stream import SourceTrack, render_track

    cfg = recipe.acoustics
    fs = cfg.sample_rate
    hop = step_samples(recipe)
    pre_steps = int(round(PRE_ROLL_SECONDS * recipe.robot.control_hz))
    n_steps = len(rollout.steps)
    poses = np.array(
        [[*s.ear_position, s.ear_yaw] for s in rollout.steps] or [[*spec.start[:2], cfg.ear_height, spec.start[2]]],
        dtype=np.float64,
    )
    poses = np.concatenate([np.repeat(poses[:1], pre_steps, axis=0), poses], axis=0)
    total_steps = len(poses)
    seconds = total_steps * hop / fs + cfg.rir_seconds
    sources = []
    for e, ev in enumerate(spec.events):
        wave = library.waveform(ev.sound_id, fs, seconds)  # type: ignore[attr-defined]
        stop = rollout.resolved_frame[e]
        sources.append(SourceTrack(position=tuple(ev.source), waveform=wave, stop_sample=None if stop is None else (stop + pre_steps) * hop))
    hrtf = Hrtf.load(cfg.hrtf, fs)
    # One acoustic geometry per door state: closed doors until an OpenDoor succeeds, then the
    # leaf at its measured hinge angle. Superposition is linear, so the episode track is the
    # epoch renders joined with one-step raised-cosine crossfades (as between cached RIRs).
    epochs: list[tuple[int, dict[int, float] | None]] = [(0, None)]
    epochs += [((frame + pre_steps) * hop, angles) for frame, angles in rollout.door_changes]
    track = None
    for e, (start, angles) in enumerate(epochs):
        part = render_track(AcousticScene(spec.plan, cfg, door_angles=angles), sources, poses, hop, cfg, hrtf=hrtf)
        if track is None:
            track = np.zeros_like(part)
        end = epochs[e + 1][0] if e + 1 < len(epochs) else len(part)
        track += part * _epoch_window(len(part), start if e else None, end if e + 1 < len(epochs) else None, hop)[:, None]
    assert track is not None
    offsets = (pre_steps + np.arange(n_steps, dtype=np.int64)) * hop
    return track.astype(np.float32), offsets


def generate_episode(
    recipe: Recipe,
    split: str,
    index: int,
    library: object,
    recipe_dir: Path | None = None,
    attempt: int = 0,
) -> EpisodeResult:
    """Sample, simulate and hear one episode. `attempt` > 0 retries with fresh seeds after an expert failure.

    Raises `echo_data.scene.sampling.SamplingError` when no solvable episode is found within
    the recipe's attempt budget. An expert failure is returned (success False) with reasons.
    """
    from echo_data.acoustics.features import step_features
    from echo_data.scene.sampling import sample_episode

    spec, rejected = sample_episode(recipe, split, index, library, attempt=attempt)
    rollout = simulate(spec, recipe, observe=True)
    result = EpisodeResult(spec=spec, steps=rollout.steps, outcomes=rollout.outcomes, success=rollout.success, rejected=rejected)
    if not result.success or not rollout.steps:
        return result
    track, offsets = render_episode_audio(spec, rollout, recipe, library)
    # The features are computed from exactly the samples the WAV will hold (ClippingError if
    # the track would clip: never a spectrogram of a signal that is not in the file).
    track = as_written(track, f"{spec.episode_id} audio")
    spec_feats, mel = step_features(track, offsets, recipe.acoustics.sample_rate, recipe.acoustics.mel_bands)
    result.audio = track
    result.audio_offsets = offsets
    result.spectrogram = spec_feats
    result.mel = mel
    return result
