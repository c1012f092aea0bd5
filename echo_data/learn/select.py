"""Choosing a checkpoint closed loop: the policy as it is now, run on a few episodes of the
validation split (never the test split) with the oracle planner and the oracle for the other
skills; its skill's success rate is the score that picks best.pt (`--select-every`).

Why: robomimic found the checkpoint with the lowest validation loss 50-100 % worse closed loop
than the best one (Mandlekar et al. 2021, "What Matters in Learning from Offline Human
Demonstrations for Robot Manipulation"). Validation episodes are sampled from the dataset's own
recipe under the split name "val" (their own seeds); when the recipe builds no val episodes,
`select_episodes` of them are added to one setting whose train episodes hold the skill.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from echo_data.learn import runs

SELECT_DIR = runs.SELECT_DIR


def validation_recipe(dataset: Path, skill: str, episodes: int) -> Any:
    """The dataset's recipe with at least `episodes` val episodes in a setting that holds `skill`."""
    from echo_data.dataset.reader import dataset_recipe, episode_records

    recipe, _ = dataset_recipe(dataset)
    if recipe.splits.get("val", 0) >= episodes:
        return recipe
    if not recipe.composition:
        return recipe.model_copy(update={"splits": {**recipe.splits, "val": episodes}})
    table = episode_records(dataset, ["split", "setting", "chain"])
    having = sorted({r["setting"] for r in table if r["split"] == "train" and any(c["skill"] == skill for c in r["chain"])})
    if not having:
        raise runs.RunError(f"--select-every: no train episode of {dataset} holds {skill}")
    comp = {s: {**c, "val": episodes if s == having[0] else 0} for s, c in recipe.composition.items()}
    return recipe.model_copy(update={"composition": comp, "splits": {**recipe.splits, "val": episodes}})


# The env's action form (`robot.action_space`) -> the action column a policy must clone to act in it.
COLUMN_OF_SPACE = {"joint": "action", "ee_delta": "action.ee"}


def check_action_space(dataset: Path, action_column: str) -> None:
    """Refuse, before any training, a closed-loop choice that could never act: validation episodes
    run in the dataset recipe's `robot.action_space`, which takes one action column's form."""
    from echo_data.dataset.reader import dataset_recipe

    recipe, _ = dataset_recipe(dataset)
    want = COLUMN_OF_SPACE[recipe.robot.action_space]
    if action_column != want:
        raise runs.RunError(f"--select-every with --action-column {action_column}: {dataset}'s recipe acts in robot.action_space "
                            f"{recipe.robot.action_space}, whose policies clone {want} (pass --action-column {want})")


# The STOP thresholds a `--stop` run is scored with at each choice (`closed_loop_scores`). Why a
# choice: the STOP's class weight makes 0.5 the point where the network's odds of "this is the
# expert's last row" equal the weighted ratio, and where the demonstrations end at a random point
# of the success region (`experts.handover_noise`), which state ends a segment is not in the
# observations: measured, at 0.5 the Navigate learner (nav_audio) stopped at step ~30 of every
# validation episode, 0.2-0.8 m into paths of 1.5-7.7 m. A higher threshold stops later.
STOP_THRESHOLDS = (0.5, 0.95, 0.995)


def closed_loop_scores(cfg: Any, model: Any, out: Path) -> dict[str, float]:
    """`val_success` of the current weights (`closed_loop_success`); for a `--stop` run the best
    over `STOP_THRESHOLDS` and the threshold that reached it (`stop_threshold`; ties: the
    highest, the latest stop, nearest the target where the next skill starts)."""
    if not cfg.stop:
        return {"val_success": closed_loop_success(cfg, model, out)}
    best = {"val_success": math.nan, "stop_threshold": STOP_THRESHOLDS[0]}
    for t in STOP_THRESHOLDS:
        cfg.stop_threshold = t
        s = closed_loop_success(cfg, model, out)
        if not math.isnan(s) and (math.isnan(best["val_success"]) or s >= best["val_success"]):
            best = {"val_success": s, "stop_threshold": t}
    cfg.stop_threshold = best["stop_threshold"]
    return best


def closed_loop_success(cfg: Any, model: Any, out: Path) -> float:
    """Success rate of `cfg.skill` over `cfg.select_episodes` validation episodes with the
    model's current weights (nan when no episode reached the skill)."""
    from echo_data.evaluation.run import evaluate

    scored = out / SELECT_DIR
    # One folder per scoring: evaluate keeps a loaded policy per (recipe, split, policy path) in
    # its in-process worker, so a reused path would score the first weights again.
    at = f"{SELECT_DIR}/scored-{len(list(scored.glob('scored-*'))) + 1:03d}"
    folder = out / at
    runs.write_run_files(out, "policy", runs.POLICY_CLASS, cfg.to_dict(), {"algo": cfg.ALGO, "skill": cfg.skill}, at=at)
    runs.save_torch(out, f"{at}/{runs.BEST}", {"model": {k: v.detach().cpu() for k, v in model.state_dict().items()}})
    recipe = validation_recipe(Path(cfg.dataset), cfg.skill, cfg.select_episodes)
    was_training = model.training
    doc = evaluate(recipe, None, "val", cfg.select_episodes, (f"{cfg.skill}={folder}", "oracle"), "oracle")
    model.train(was_training)
    outcomes = [s["success"] for e in doc["episodes"] if "skipped" not in e for s in e["skills"] if s["skill"] == cfg.skill]
    return sum(outcomes) / len(outcomes) if outcomes else math.nan
