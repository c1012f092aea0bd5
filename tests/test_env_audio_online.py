"""The environment's ears render step by step what the offline streaming renderer renders for the whole path."""

from __future__ import annotations

import numpy as np

from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.levels import to_full_scale
from echo_data.acoustics.noise import NoiseFloor
from echo_data.acoustics.room import AcousticScene
from echo_data.acoustics.stream import SourceTrack, render_track
from echo_data.envs.audio import OnlineTrack, event_waveform, pre_roll_steps, step_samples
from echo_data.episode import EpisodeSpec, SkillCall, SoundEvent
from echo_data.pcm import as_written
from echo_data.recipe import Recipe
from echo_data.scene.generate import generate_floorplan
from echo_data.sounds import SoundLibrary


def _spec(recipe: Recipe, lib: SoundLibrary) -> EpisodeSpec:
    plan = generate_floorplan(recipe, np.random.default_rng(3))
    rooms = plan.rooms
    evs = (
        SoundEvent("alarm", lib.instances("alarm", "train")[0].id, "alarm_0", (*rooms[0].rect.center, 0.9), 0),
        SoundEvent("phone", lib.instances("phone", "train")[1].id, "phone_0", (*rooms[-1].rect.center, 0.8), 1),
    )
    x, y = rooms[0].rect.center
    return EpisodeSpec("train-000000", "train", 0, 0, 1, "multi_event", plan, (x + 0.4, y, 0.0), evs, (SkillCall("Navigate", "alarm_0", 0),))


def test_online_blocks_equal_the_offline_render() -> None:
    """Same samples, bit for bit: a walking, turning head, one source stopping mid-way, the tail,
    calibrated to full scale with the noise bed added, as the offline render plus the noise would be."""
    recipe = Recipe(name="t")
    lib = SoundLibrary.builtin()
    spec = _spec(recipe, lib)
    cfg, hop, pre = recipe.acoustics, step_samples(recipe), pre_roll_steps(recipe)
    n, stop_frame = 40, 17
    x, y, yaw = spec.start
    walk = np.array([[x + 0.05 * i, y + 0.02 * i, cfg.ear_height, yaw + 0.12 * i] for i in range(n)])
    poses = np.concatenate([np.repeat(walk[:1], pre, axis=0), walk])

    online = OnlineTrack(spec, recipe, lib)
    online.pre_roll(walk[0])
    for t in range(n):
        block = online.step(walk[t])
        assert block.shape == (hop, 2) and block.dtype == np.float32
        if t + 1 == stop_frame:
            online.stop(0)
    track = online.finish()

    seconds = len(poses) * hop / cfg.sample_rate + cfg.rir_seconds
    sources = [
        SourceTrack(ev.source, event_waveform(spec, e, lib, cfg.sample_rate, seconds), (stop_frame + pre) * hop if e == 0 else None)
        for e, ev in enumerate(spec.events)
    ]
    hrtf = Hrtf.load(cfg.hrtf, cfg.sample_rate)
    offline = render_track(AcousticScene(spec.plan, cfg), sources, poses, hop, cfg, hrtf=hrtf)
    noise = NoiseFloor(cfg.sample_rate, cfg.noise_floor_dba, spec.plan.seed, hrtf).render(0, len(offline))
    offline = as_written(to_full_scale(offline.astype(np.float64) + noise, cfg.full_scale_db_spl))
    assert track.shape == offline.shape
    assert np.array_equal(track, offline)
    assert np.abs(track[: (pre + n) * hop]).max() > 1e-3  # not trivially silent


def test_a_stop_is_causal() -> None:
    """Blocks rendered before a source stops do not change when it stops (no look-ahead)."""
    recipe = Recipe(name="t")
    lib = SoundLibrary.builtin()
    spec = _spec(recipe, lib)
    a, b = OnlineTrack(spec, recipe, lib), OnlineTrack(spec, recipe, lib)
    pose = (*spec.start[:2], recipe.acoustics.ear_height, 0.0)
    for tr in (a, b):
        tr.pre_roll(pose)
    ra = [a.step(pose) for _ in range(5)]
    rb = [b.step(pose) for _ in range(5)]
    b.stop(0)
    b.stop(1)
    assert all(np.array_equal(p, q) for p, q in zip(ra, rb))
    later_a, later_b = a.step(pose), b.step(pose)
    assert not np.array_equal(later_a, later_b)
