"""Fixtures the test modules share. Helpers that are plain functions live in `tests/support/`
(plans, synthetic episodes, recipes); test modules never import from one another."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from support.synth import build_synth


@pytest.fixture(scope="session")
def synth_dataset(tmp_path_factory: pytest.TempPathFactory) -> Callable[[dict[str, int]], Path]:
    """`synth_dataset({"train": 4, "test": 1})`: a built synthetic dataset of those split sizes,
    built once per session and shared; tests that damage or rewrite a dataset copy it first
    (`support.synth.damageable_copy`) or build their own."""
    built: dict[tuple[tuple[str, int], ...], Path] = {}

    def get(splits: dict[str, int]) -> Path:
        key = tuple(sorted(splits.items()))
        if key not in built:
            built[key] = build_synth(tmp_path_factory.mktemp("synth") / "synth", dict(splits))
        return built[key]

    return get
