"""The skill learners, one folder per algorithm, and their registry.

Adding an algorithm: a folder with a config (a `SkillConfig` dataclass) and a model (`loss`,
`predict`), and one line in `ALGORITHMS` (docs/adding_a_learner.md). The CLI (`echo-data train
<name>`), the fit loop and the policy read everything else from the config.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from echo_data.learn.algos.base import SkillConfig


@dataclass(frozen=True)
class Algorithm:
    name: str  # as in config.json's "algo" and `echo-data train <name>` (underscores as dashes)
    config: type[SkillConfig]
    model: str  # "module:Class" of the network, imported only when a run is built (torch)
    summary: str


def _algorithms() -> dict[str, Algorithm]:
    from echo_data.learn.algos.act.config import ACTConfig
    from echo_data.learn.algos.bc.config import BCConfig
    from echo_data.learn.algos.bc_rnn.config import BCRNNConfig
    from echo_data.learn.algos.diffusion.config import DiffusionConfig

    return {a.name: a for a in (
        Algorithm("bc", BCConfig, "echo_data.learn.algos.bc.model:BCModel", "Behaviour cloning: encoders -> MLP -> the next action(s)."),
        Algorithm("bc_rnn", BCRNNConfig, "echo_data.learn.algos.bc_rnn.model:BCRNNModel", "BC-RNN: a GRU over the steps of a skill, reset at each skill's start."),
        Algorithm("act", ACTConfig, "echo_data.learn.algos.act.model:ACTModel", "ACT-style chunking: a transformer predicts k actions, temporal ensembling when acting."),
        Algorithm("diffusion", DiffusionConfig, "echo_data.learn.algos.diffusion.model:DiffusionModel", "Diffusion Policy: a 1-D conv U-Net denoises an action horizon (DDPM / DDIM)."),
    )}


ALGORITHMS: dict[str, Algorithm] = _algorithms()


def algorithm(name: str) -> Algorithm:
    if name not in ALGORITHMS:
        raise KeyError(f"unknown algorithm {name!r}; choose from {', '.join(ALGORITHMS)}")
    return ALGORITHMS[name]


def config_from_run(d: dict[str, Any]) -> SkillConfig:
    """A run folder's config.json -> its typed config. Runs from before the registry carry no
    "algo": a `recurrent` run was BC-RNN, any other BC."""
    name = d.get("algo") or ("bc_rnn" if d.get("recurrent") else "bc")
    old = {"audio_form": "stored"} if "algo" not in d else {}  # older runs fed the stored form
    if "algo" not in d and d.get("recurrent") and "seq_batch" in d:
        old["batch_size"] = d["seq_batch"]
    return algorithm(name).config.from_dict({**old, **d})


def build_model(cfg: SkillConfig) -> Any:
    """The algorithm's network for a resolved config (weights initialised from torch's RNG)."""
    import importlib

    from echo_data.learn.features import FeatureSpec
    from echo_data.learn.models import stored_audio_shape

    module, _, cls = algorithm(cfg.ALGO).model.partition(":")
    return getattr(importlib.import_module(module), cls)(cfg, FeatureSpec.from_dict(cfg.features), stored_audio_shape(cfg.audio_shape))
