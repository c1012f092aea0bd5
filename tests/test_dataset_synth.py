"""The synthetic episode generator the build tests inject (tests/support/synth.py) is itself sound."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from support.synth import synth_generate, synth_recipe


def test_synthetic_episode_is_deterministic_and_well_shaped() -> None:
    r = synth_recipe()
    a = synth_generate(r, "train", 3, None, Path("."), attempt=0)
    b = synth_generate(r, "train", 3, None, Path("."), attempt=0)
    assert a.success and len(a.steps) == len(b.steps)
    assert a.spectrogram.shape[1:] == (65, 26, 2) and a.mel.shape[1:] == (64, 101, 2)
    assert np.array_equal(a.audio, b.audio) and np.array_equal(a.steps[-1].head_rgb, b.steps[-1].head_rgb)
    assert not synth_generate(r, "train", 1, None, Path("."), attempt=0).success
