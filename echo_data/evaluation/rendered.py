"""What evaluation renders: the observations the agents read, whatever the recipe stores.

A recipe's `outputs.observations` says what a build writes to disk; the environment observes
the same list. A learner trained on another recipe (a shipped reference learner reading the
wrist camera, say) may read an observation this recipe does not store, so evaluation widens the
list by what the agents declare (`observations`). The cameras themselves are the recipe's
(`robot.*_camera`): an observation its cameras cannot give stays absent and is refused by
`check_observations`. Episodes are sampled from the seed, not from the outputs, so the widened
recipe plays the same episodes.
"""

from __future__ import annotations

from typing import Any

from echo_data.dataset.schema import IMAGE_COLUMNS, MEL, SPECTROGRAM
from echo_data.recipe import Recipe

OUTPUT_OF = {**{col: name for name, col in IMAGE_COLUMNS.items()}, SPECTROGRAM: "spectrogram", MEL: "mel"}  # observation key -> outputs name


def rendering(recipe: Recipe, *agents: Any) -> Recipe:
    """`recipe` with `outputs.observations` widened by every observation the agents read."""
    stored = tuple(recipe.outputs.observations)
    wanted = [OUTPUT_OF[k] for a in agents for k in (getattr(a, "observations", None) or ()) if k in OUTPUT_OF]
    extra = tuple(dict.fromkeys(n for n in wanted if n not in stored))
    if not extra:
        return recipe
    return recipe.model_copy(update={"outputs": recipe.outputs.model_copy(update={"observations": stored + extra})})
