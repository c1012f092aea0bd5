"""Fresh synthesised training instances (`sounds.fresh_train_instances`): regenerated from their
id, never one of the held-out test instances, drawn from the episode seed, test episodes unchanged."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from echo_data.categories import CATEGORY_COUNTS
from echo_data.episode import fresh_sound_seed
from echo_data.recipe import Recipe
from echo_data.scene.sampling import sample_episode
from echo_data.sounds import SoundLibrary, synth

LIB = SoundLibrary.builtin()


def _max_xcorr(a: np.ndarray, b: np.ndarray) -> float:
    """Largest normalised cross-correlation over all lags: 1.0 when one waveform is a shifted copy of the other."""
    n = len(a) + len(b)
    c = np.fft.irfft(np.fft.rfft(a, n) * np.conj(np.fft.rfft(b, n)), n)
    return float(np.max(np.abs(c)) / np.sqrt(float(a @ a) * float(b @ b)))


def test_fresh_id_regenerates_the_same_bytes() -> None:
    iid = synth.fresh_id("phone", 0x3FA2B1C94D07)
    assert iid == "phone-fresh-3fa2b1c94d07" and synth.is_fresh_id(iid)
    inst = LIB.get(iid)
    assert inst.category == "phone" and inst.split == "train" and inst.builtin
    assert inst.duration == synth.design(iid)["duration"]
    a = LIB.waveform(iid, 16000, 1.0)
    b = SoundLibrary.builtin().waveform(iid, 16000, 1.0)
    assert a.tobytes() == b.tobytes() and np.abs(a).max() > 0.1
    for bad in ("phone-fresh-3FA2B1C94D07", "phone-fresh-12", "bird-fresh-3fa2b1c94d07", "phone-test-99"):
        with pytest.raises(KeyError):
            LIB.get(bad)
    # only a library that holds the synthesiser's instances makes fresh ones
    with pytest.raises(KeyError):
        SoundLibrary([]).get(iid)


def test_fresh_variants_cover_every_style() -> None:
    """Variant = number mod VARIANT_CYCLE: fresh draws sample every style the library's instances use."""
    for cat in CATEGORY_COUNTS:
        library_styles = {str(synth.design(i.id).get("style", synth.design(i.id).get("flow"))) for i in LIB.instances(cat)}
        fresh_styles = {str(synth.design(synth.fresh_id(cat, s)).get("style", synth.design(synth.fresh_id(cat, s)).get("flow"))) for s in range(240)}
        assert library_styles <= fresh_styles, cat


@pytest.mark.parametrize("category", list(CATEGORY_COUNTS))
def test_no_fresh_instance_coincides_with_a_test_instance(category: str) -> None:
    """Parameters: no fresh design (400 seeds) equals a test instance's design. Waveform: no fresh
    loop (24 seeds) is a copy of a test loop at any lag: the closest pair's normalised
    cross-correlation stays below 0.9 (the library's own train and test instances reach 0.72 for
    doorbell buzzers, whose low harmonic spectra are alike; 0.09-0.30 for the other categories)."""
    tests = [i.id for i in LIB.instances(category, "test")]
    test_designs = [synth.design(i) for i in tests]
    seeds = [fresh_sound_seed(s, k) for s in range(200) for k in range(2)]
    for s in seeds:
        assert synth.design(synth.fresh_id(category, s)) not in test_designs
    test_loops = [LIB.waveform(i, 16000).astype(np.float64) for i in tests]
    closest = max(_max_xcorr(LIB.waveform(synth.fresh_id(category, s), 16000).astype(np.float64), t) for s in seeds[:24] for t in test_loops)
    assert closest < 0.9


def _recipe(fresh: bool) -> Recipe:
    return Recipe(name="t", setting="multi_event", sounds={"fresh_train_instances": fresh})  # type: ignore[arg-type]


def test_train_episodes_play_fresh_instances_from_the_episode_seed() -> None:
    on, off = _recipe(True), _recipe(False)
    for i in range(2):
        spec, _ = sample_episode(on, "train", i, LIB)
        again, _ = sample_episode(on, "train", i, SoundLibrary.builtin())
        assert spec.to_dict() == again.to_dict()
        assert [e.sound_id for e in spec.events] == [synth.fresh_id(e.category, fresh_sound_seed(spec.seed, k)) for k, e in enumerate(spec.events)]
        # the option changes the voices and nothing else of the episode
        plain, _ = sample_episode(off, "train", i, LIB)
        assert all(LIB.get(e.sound_id).split == "train" and not synth.is_fresh_id(e.sound_id) for e in plain.events)
        assert dataclasses.replace(spec, events=plain.events) == plain
        # the sound the environment plays is the id's, bit for bit
        e = spec.events[0]
        assert LIB.waveform(e.sound_id, 16000).tobytes() == synth.render(e.sound_id, 16000).tobytes()
    # test episodes keep the library's held-out test instances, exactly as without the option
    for i in range(2):
        spec, _ = sample_episode(on, "test", i, LIB)
        plain, _ = sample_episode(off, "test", i, LIB)
        assert spec == plain and all(LIB.get(e.sound_id).split == "test" for e in spec.events)
