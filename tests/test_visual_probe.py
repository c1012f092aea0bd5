"""A tiny run of the visual probe (studies/visual_probe/bench_visual_probe.py): a small CNN trained on crops
of a few homes tells phone / alarm / furby / distractor apart on homes of other seeds well above
chance. Rendering and training are seeded, so the figure is the same on every run."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from support.optional import needs_torch

ROOT = Path(__file__).resolve().parents[1]


def _probe():
    spec = importlib.util.spec_from_file_location("bench_visual_probe", ROOT / "studies" / "visual_probe" / "bench_visual_probe.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    return mod


@pytest.mark.slow
@needs_torch
def test_probe_tells_objects_apart_on_unseen_homes() -> None:
    probe = _probe()
    recipe = ROOT / "recipes" / "object_relocation.yaml"
    x, y = probe.collect(recipe, list(range(80)), 6, mono=False)  # about 1000 crops, 20 s
    xt, yt = probe.collect(recipe, list(range(10_000, 10_008)), 6, mono=False)
    assert set(y.tolist()) == set(yt.tolist()) == {0, 1, 2, 3}  # all four classes on both sides
    acc = probe.train_probe(x, y, xt, yt, epochs=25)
    assert acc >= 0.8, acc  # chance is 0.25; this seeded run gives 0.86 (0.96 before the layout families and instance sizes)
