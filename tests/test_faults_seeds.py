"""The seed story: every attempt's manifest record, failed or not, reproduces that attempt.

The sampler resamples internally (rejected draws) and the build retries after expert failures;
the record must name the draw and seed of the spec that was actually simulated. Before, it
recorded `episode_seed(..., attempt)` for build attempt a, a seed the sampler never used for
a > 0 (it draws from a * budget on).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from support.synth import synth_generate

from echo_data.app.build import build, default_library
from echo_data.episode import attempt_draws, episode_seed
from echo_data.recipe import load_recipe
from echo_data.records import EpisodeResult, SkillOutcome
from echo_data.scene.sampling import sample_episode

RECIPES = Path(__file__).resolve().parent.parent / "recipes"


@pytest.fixture(scope="module")
def recipe():  # noqa: ANN201
    r = load_recipe(RECIPES / "quickstart.yaml")
    return r.model_copy(update={"max_attempts_per_episode": 3, "composition": None, "splits": {"train": 1}, "setting": "object_relocation"})


def _real_sampler_expert_fails_twice(recipe, split, index, library, recipe_dir, attempt=0):  # noqa: ANN001, ANN201
    """The real sampler; the expert 'fails' on attempts 0 and 1 (no physics needed to test seeds)."""
    spec, rejected = sample_episode(recipe, split, index, library, attempt=attempt)
    if attempt < 2:
        return EpisodeResult(spec, [], [SkillOutcome("Navigate", spec.chain[0].target, False, "stuck", 3)], False, rejected=rejected)
    ep = synth_generate(recipe, split, index, library, recipe_dir, attempt=attempt)
    ep.spec = spec
    return ep


def test_failed_attempts_rerun_from_their_manifest_entries(recipe, tmp_path: Path) -> None:  # noqa: ANN001
    import json

    out = tmp_path / "ds"
    build(recipe, RECIPES / "quickstart.yaml", out, generate=_real_sampler_expert_fails_twice, progress=False)
    failed = json.loads((out / "manifest.json").read_text())["failed_episodes"]
    assert [f["attempt"] for f in failed] == [0, 1]
    library = default_library(recipe, RECIPES)
    for entry in failed:
        lo, hi = entry["draws"]
        assert (lo, hi) == (entry["attempt"] * 3, entry["attempt"] * 3 + 3)
        assert lo <= entry["draw"] < hi and entry["seed"] == episode_seed(recipe.seed, "train", 0, entry["draw"])
        spec, _ = sample_episode(recipe, entry["split"], entry["index"], library, attempt=entry["attempt"])
        assert (spec.attempt, spec.seed) == (entry["draw"], entry["seed"])  # the very episode that failed
    assert failed[1]["seed"] != episode_seed(recipe.seed, "train", 0, 1)  # what the old record claimed


def test_attempt_draws_never_overlap() -> None:
    seen: set[int] = set()
    for a in range(4):
        draws = attempt_draws(7, "val", 3, a, 5)
        assert [k for k, _ in draws] == list(range(5 * a, 5 * a + 5))
        assert all(s == episode_seed(7, "val", 3, k) for k, s in draws)
        assert not seen & {k for k, _ in draws}
        seen |= {k for k, _ in draws}
