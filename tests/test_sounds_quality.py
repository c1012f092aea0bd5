"""Instances are measurably different within a category, and categories are separable.

Measure (echo_data.sounds.measure): distance = sqrt(D_spec^2 + D_rhythm^2) in dB, D_spec the RMS
difference of per-band mean/std of the 64-band log-mel spectrogram, D_rhythm the RMS difference
of the level's modulation spectrum in 7 octave bands (0.25-32 Hz).
"""

from __future__ import annotations

import numpy as np
import pytest

from echo_data.sounds import SoundLibrary
from echo_data.sounds.measure import distance_matrix, features, report


@pytest.fixture(scope="module")
def rep() -> dict:
    return report(SoundLibrary.builtin())


def test_instances_within_a_category_differ(rep: dict) -> None:
    for cat, r in rep["within_category"].items():
        assert r["min_pair_db"] >= 2.0, (cat, r)


def test_categories_are_separable(rep: dict) -> None:
    assert rep["loo_1nn_accuracy"] >= 0.9, rep["loo_1nn_errors"]
    assert rep["nn_train_to_test_accuracy"] >= 0.9


def test_measure_sees_sameness_and_difference() -> None:
    """The measure is ~0 for the same sound (shifted in time, rendered twice) and large across kinds."""
    lib = SoundLibrary.builtin()
    a = lib.waveform("phone-train-01", 16000)
    b = np.roll(a, len(a) // 3)
    c = lib.waveform("sink-train-01", 16000)
    d = distance_matrix(np.stack([features(a), features(b), features(c)]))
    assert d[0, 1] < 0.3
    assert d[0, 2] > 5.0
