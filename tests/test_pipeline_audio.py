"""The episode track as the pipeline renders it: pre-roll offsets, sources that stop, doors that open."""

from __future__ import annotations

import math

import numpy as np
import pytest

from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.levels import P_REF, ClippingError, full_scale_pa
from echo_data.acoustics.noise import NoiseFloor
from echo_data.app.pipeline import PRE_ROLL_SECONDS, render_episode_audio, step_samples
from echo_data.envs.audio import epoch_window
from echo_data.episode import EpisodeSpec, SkillCall, SoundEvent
from echo_data.recipe import Recipe
from echo_data.records import ACTION_DIM, STATE_DIM, EpisodeResult, StepRecord
from echo_data.scene.generate import generate_floorplan
from echo_data.sounds import SoundLibrary


def test_epoch_windows_partition_unity() -> None:
    n, hop = 5000, 160
    t = np.arange(n)
    ws = [epoch_window(t, None, 1200, hop), epoch_window(t, 1200, 3100, hop), epoch_window(t, 3100, None, hop)]
    assert np.allclose(sum(ws), 1.0, atol=1e-12)
    assert ws[0][1000] == 1.0 and ws[0][1300] == 0.0 and ws[1][2000] == 1.0


def _interior_door_plan(recipe: Recipe):
    for seed in range(200):
        plan = generate_floorplan(recipe, np.random.default_rng(seed))
        for d in plan.doors:
            a, b = plan.doorways[d.doorway].rooms
            if a >= 0 and b >= 0:
                return plan, d, plan.rooms[a], plan.rooms[b]
    raise AssertionError("no plan with an interior door")


def _spec_and_rollout(recipe: Recipe, n_steps: int, resolved: int | None, door_change: int | None):
    recipe = recipe.model_copy(update={"scene": recipe.scene.model_copy(update={"rooms": (3, 4), "door_probability": 1.0})})
    plan, door, room_a, room_b = _interior_door_plan(recipe)
    lib = SoundLibrary.builtin()
    src = (*room_b.rect.center, 1.0)
    ear = (*room_a.rect.center, recipe.acoustics.ear_height)
    ev = SoundEvent("alarm", lib.instances("alarm", "train")[0].id, "alarm_0", src, 0)
    spec = EpisodeSpec("train-000000", "train", 0, 0, 1, "object_relocation", plan, (ear[0], ear[1], 0.0), (ev,), (SkillCall("Navigate", "alarm_0", 0),))
    steps = [
        StepRecord(i, i / 10, "Navigate", 0, np.zeros(ACTION_DIM, np.float32), np.zeros(STATE_DIM, np.float32), None, None, None, ear, 0.0, (True,))
        for i in range(n_steps)
    ]
    changes = [] if door_change is None else [(door_change, {door.index: math.radians(90)})]
    return spec, EpisodeResult(spec, steps, [], False, resolved_frame=[resolved], door_changes=changes), lib


@pytest.fixture(scope="module")
def recipe() -> Recipe:
    return Recipe(name="t")


def test_offsets_include_the_pre_roll(recipe: Recipe) -> None:
    spec, ro, lib = _spec_and_rollout(recipe, 12, None, None)
    track, offsets = render_episode_audio(spec, ro, recipe, lib)
    hop = step_samples(recipe)
    pre = int(PRE_ROLL_SECONDS * recipe.acoustics.sample_rate)
    assert offsets.tolist() == [pre + i * hop for i in range(12)]
    assert track.shape[1] == 2 and len(track) >= offsets[-1] + hop
    # the event is already audible in the first second the robot hears
    assert np.sqrt(np.mean(track[:pre] ** 2)) > 1e-4


def test_after_the_source_stops_only_the_noise_floor_remains(recipe: Recipe) -> None:
    """No digital silence: once the source and its reverberation have died away the track is
    exactly the room's noise bed (at the stated calibration), and at its stated level."""
    spec, ro, lib = _spec_and_rollout(recipe, 30, 10, None)
    track, offsets = render_episode_audio(spec, ro, recipe, lib)
    cfg = recipe.acoustics
    stop = offsets[10]
    quiet_from = stop + int(0.02 * cfg.sample_rate) + int(1.5 * cfg.rir_seconds * cfg.sample_rate) + 200
    assert np.abs(track[stop - 1600 : stop]).max() > 0
    bed = NoiseFloor(cfg.sample_rate, cfg.noise_floor_dba, spec.plan.seed, Hrtf.load(cfg.hrtf, cfg.sample_rate))
    expect = bed.render(0, len(track))[quiet_from:] / full_scale_pa(cfg.full_scale_db_spl)
    # the track holds 16-bit samples (what the WAV stores): half an LSB of rounding
    np.testing.assert_allclose(track[quiet_from:], expect, rtol=0, atol=0.5 / 32768 + 1e-9)
    assert np.all(np.abs(track[quiet_from:]).max(axis=0) > 0)
    # and a source at its calibrated level is far above the bed
    level = 20 * np.log10(np.sqrt(np.mean(track[: offsets[0]].astype(np.float64) ** 2)) * full_scale_pa(cfg.full_scale_db_spl) / P_REF)
    assert level > 45.0, level


def test_opening_the_door_lets_the_sound_through(recipe: Recipe) -> None:
    # without the room's noise bed (its low-frequency rumble would mask the closed-door level)
    recipe = recipe.model_copy(update={"acoustics": recipe.acoustics.model_copy(update={"noise_floor_dba": 0.0})})
    n, change = 40, 20
    spec, closed, lib = _spec_and_rollout(recipe, n, None, None)
    _, opened, _ = _spec_and_rollout(recipe, n, None, change)
    a, offsets = render_episode_audio(spec, closed, recipe, lib)
    b, _ = render_episode_audio(spec, opened, recipe, lib)
    hop = step_samples(recipe)  # the crossfade spans one control step centred on the change
    before = slice(offsets[2], offsets[change] - hop // 2)
    after = slice(offsets[change] + hop, offsets[n - 1])
    assert np.array_equal(a[before], b[before])  # same geometry until the door opens
    gain_db = 10 * np.log10(np.mean(b[after] ** 2) / np.mean(a[after] ** 2))
    assert gain_db > 6.0, gain_db


def test_a_track_that_would_clip_is_refused_not_clipped(recipe: Recipe) -> None:
    """Calibration: the same episode at a full scale 1 dB below its peak raises ClippingError
    (the build records the attempt as failed with that one-line reason); 1 dB above it gives the
    same samples scaled by the calibration ratio."""
    spec, ro, lib = _spec_and_rollout(recipe, 12, None, None)
    track, _ = render_episode_audio(spec, ro, recipe, lib)
    peak_db = 20 * np.log10(np.abs(track.astype(np.float64)).max()) + recipe.acoustics.full_scale_db_spl
    low = recipe.model_copy(update={"acoustics": recipe.acoustics.model_copy(update={"full_scale_db_spl": peak_db - 1.0})})
    with pytest.raises(ClippingError, match="would clip"):
        render_episode_audio(spec, ro, low, lib)
    high = recipe.model_copy(update={"acoustics": recipe.acoustics.model_copy(update={"full_scale_db_spl": peak_db + 1.0})})
    louder, _ = render_episode_audio(spec, ro, high, lib)
    scale = 10 ** ((recipe.acoustics.full_scale_db_spl - peak_db - 1.0) / 20)
    # both tracks are 16-bit samples, each with up to half an LSB of rounding; the quiet one's
    # rounding is magnified by the scale
    np.testing.assert_allclose(louder, track * scale, rtol=0, atol=(scale + 1.0) * 0.5 / 32768 * 1.001)
