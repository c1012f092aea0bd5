"""`echo-data evaluate-planner RUN`: a finished planner run scored on its dataset's test split,
once, apart from training (which chooses on validation and never reads the test split). Split
from `learn.planner` by job.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

from echo_data.dataset.manifest import MANIFEST
from echo_data.dataset.reader import dataset_manifest, is_dataset
from echo_data.learn import runs
from echo_data.learn.features import FeatureSpec
from echo_data.learn.loop import setup_torch
from echo_data.learn.planner import PlannerConfig, build_model, errors, predict, resolve, score
from echo_data.learn.planner_data import chosen_episodes, episode_rows, load_episodes


def _same_dataset(cfg: PlannerConfig, root: Path, run: Path) -> None:
    """Refuse a dataset other than the one `run` was trained on: what training derived from its
    train split (feature constants, categories, skill templates, event sets, priority rule) must
    be what the run's config.json holds, or the test figures would not be the run's."""
    again = asdict(resolve(PlannerConfig(str(root), cfg.inputs, audio=cfg.audio, image_size=cfg.image_size, order=cfg.order)))
    saved = asdict(cfg)
    for key in ("features", "audio_shape", "categories", "templates", "event_sets", "priority"):
        if json.loads(json.dumps(again[key])) != json.loads(json.dumps(saved[key])):
            raise runs.RunError(f"{root}: not the dataset {run} was trained on ({key} of its train split differs from {run / runs.CONFIG})")


def score_test(run: Path, dataset: Path | None = None) -> dict[str, Any]:
    """Score a finished planner run on the test split of its dataset (`dataset`, default the one
    in config.json): the kept checkpoint (best.pt) with the decoder chosen on validation, plus
    both decoders for the record (neither chooses anything). Writes test.json in the run folder
    and returns it; the figures and keys are those eval.json carried when training scored the
    test split itself."""
    from echo_data.dataset.validate import check_whole

    policy = runs.read_json(run / runs.POLICY)
    if policy.get("kind") != "planner":
        raise runs.RunError(f"{run / runs.POLICY}: a {policy.get('kind')!r} run, not a planner run")
    if not (run / runs.EVAL).is_file():
        raise runs.RunError(f"{run / runs.EVAL}: missing (training of {run} has not finished; `echo-data train planner ... --resume` finishes it)")
    cfg = PlannerConfig.from_dict(runs.read_json(run / runs.CONFIG))
    root = Path(cfg.dataset) if dataset is None else dataset
    if not is_dataset(root):
        raise runs.RunError(f"{root}: not an echo-data dataset (no {MANIFEST})" + ("; give the dataset the run was trained on: evaluate-planner RUN DATASET" if dataset is None else ""))
    dataset_manifest(root, "test", "to score (build the recipe whole into another folder, whose train split is the same, and give it: evaluate-planner RUN DATASET)")
    check_whole(root)
    _same_dataset(cfg, root, run)
    setup_torch(cfg.seed, cfg.threads)
    model = build_model(cfg)
    model.load_state_dict(runs.load_torch(run / runs.BEST)["model"])
    model.eval()
    meta = episode_rows(root, "train")
    chosen, _, _ = chosen_episodes(cfg, meta)
    heard = {e["sound_id"] for r in meta if r["episode_index"] in chosen for e in r["events"]}  # the sounds of the episodes training read
    test = load_episodes(root, "test", FeatureSpec.from_dict(cfg.features))
    priority = cfg.priority if cfg.order == "priority" else None
    decoders = {"threshold": None, "sets": cfg.event_sets}
    test_said = predict(model, test, cfg.categories, decoders[cfg.decode], priority)
    report = {
        "run": str(run),
        "decode": cfg.decode,
        "episodes": {"test": len(test.events)},
        "test_sounds_heard_in_training": sorted({s for ss in test.sounds for s in ss} & heard),
        "test": score(test_said, test, cfg.templates),
        # what the kept checkpoint gets wrong on the test split, for the record (never used to choose)
        "test_errors": errors(test_said, test.events),
        # both decoders on the test split, for the record; the one scored above was chosen on validation
        "test_events_in_order_by_decoder": {
            name: {g: v["events_in_order"] for g, v in score(predict(model, test, cfg.categories, sets, priority), test, cfg.templates).items()}
            for name, sets in decoders.items()
        },
    }
    runs.adopt(run)
    runs.write_json(run, runs.TEST, report)
    return report
