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
SCORED = "scored.json"  # in each select/scored-NNN: the recipe (name, path, content hash) and the val episodes it was scored on


def validation_recipe(dataset: Path, skill: str, episodes: int, recipe: Any = None, source: str = "") -> Any:
    """`recipe` (default: the dataset's) with at least `episodes` val episodes (for a `--select-recipe`,
    `source` its file: in the settings that hold `skill`, those whose train episodes in `dataset`
    hold it), added to one such setting when it has fewer. A `--select-recipe` that builds only
    test episodes there is refused: selection never runs on test."""
    from echo_data.dataset.reader import dataset_recipe, episode_records

    if recipe is None:
        recipe, _ = dataset_recipe(dataset)
    if recipe.splits.get("val", 0) >= episodes and not (source and recipe.composition):
        return recipe
    only_test = f"--select-recipe {source}: KEY builds no train or val episode of a setting holding {skill} (only test): selection never runs on test"
    if not recipe.composition:
        if source and not recipe.splits.get("train", 0) and not recipe.splits.get("val", 0):
            raise runs.RunError(only_test.replace("KEY", "splits"))
        return recipe.model_copy(update={"splits": {**recipe.splits, "val": episodes}})
    table = episode_records(dataset, ["split", "setting", "chain"])
    having = sorted({r["setting"] for r in table if r["split"] == "train" and any(c["skill"] == skill for c in r["chain"])})
    if not having:
        raise runs.RunError(f"--select-every: no train episode of {dataset} holds {skill}")
    if sum(recipe.composition.get(s, {}).get("val", 0) for s in having) >= episodes:  # a --select-recipe's val episodes where the skill is
        return recipe
    built = [s for s in having if recipe.composition.get(s, {}).get("train", 0) or recipe.composition.get(s, {}).get("val", 0)]
    if source and not built:
        raise runs.RunError(only_test.replace("KEY", "composition"))
    to = (built or having)[0]
    comp = {s: {**c, "val": episodes if s == to else 0} for s, c in recipe.composition.items()}
    return recipe.model_copy(update={"composition": comp, "splits": {**recipe.splits, "val": episodes}})


def selection_recipe(cfg: Any) -> Any:
    """The recipe whose val split `cfg` is scored on, with val episodes: `--select-recipe`'s (refused
    when it cannot be read, or changed since the run recorded its content hash, which it records)
    or the dataset's."""
    if not cfg.select_recipe:
        return validation_recipe(Path(cfg.dataset), cfg.skill, cfg.select_episodes)
    from echo_data.recipe import RecipeError, load_recipe

    try:
        recipe = load_recipe(cfg.select_recipe)
    except RecipeError as e:
        raise runs.RunError(f"--select-recipe {e}") from None
    if cfg.select_recipe_sha256 and recipe.content_hash() != cfg.select_recipe_sha256:
        raise runs.RunError(f"--select-recipe {cfg.select_recipe}: changed since the run started (content hash "
                            f"{recipe.content_hash()[:12]}, recorded {cfg.select_recipe_sha256[:12]}); resume with the recipe it chose on")
    cfg.select_recipe_sha256 = recipe.content_hash()  # the recipe as given (before val episodes are added): what results name
    return validation_recipe(Path(cfg.dataset), cfg.skill, cfg.select_episodes, recipe, cfg.select_recipe)


# The env's action form (`robot.action_space`) -> the action column a policy must clone to act in it.
COLUMN_OF_SPACE = {"joint": "action", "ee_delta": "action.ee"}


def check_selection(cfg: Any) -> None:
    """Refuse, before any training, a closed-loop choice that could never run: validation episodes
    act in the recipe's `robot.action_space`, which takes one action column's form, and must render
    what the learner reads (`evaluation.rendered`)."""
    recipe = selection_recipe(cfg)
    want = COLUMN_OF_SPACE[recipe.robot.action_space]
    if cfg.action_column != want:
        head = f"--select-recipe {cfg.select_recipe}:" if cfg.select_recipe else f"--select-every with --action-column {cfg.action_column}: {cfg.dataset}'s recipe"
        raise runs.RunError(f"{head} acts in robot.action_space {recipe.robot.action_space}, whose policies clone {want} (pass --action-column {want})")
    if not cfg.select_recipe:
        return
    from types import SimpleNamespace

    from echo_data.agents.runtime import RUNTIME_OBSERVATIONS
    from echo_data.envs.env import observation_space
    from echo_data.evaluation.rendered import rendering
    from echo_data.learn.features import FeatureSpec
    from echo_data.learn.policy import learner_observations

    learner = SimpleNamespace(observations=learner_observations(FeatureSpec.from_dict(cfg.features)))
    known = (*observation_space(rendering(recipe, learner)).spaces, *RUNTIME_OBSERVATIONS)
    missing = [k for k in learner.observations if k not in known]
    if missing:
        raise runs.RunError(f"--select-recipe {cfg.select_recipe}: robot: its cameras cannot give {missing[0]}, which the learner reads "
                            "(turn that camera on under robot.head_camera / robot.wrist_camera)")


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
    recipe = selection_recipe(cfg)
    was_training = model.training
    doc = evaluate(recipe, Path(cfg.select_recipe) if cfg.select_recipe else None, "val", cfg.select_episodes, (f"{cfg.skill}={folder}", "oracle"), "oracle")
    model.train(was_training)
    runs.write_json(out, f"{at}/{SCORED}", {"recipe": doc["recipe"], "split": doc["split"], "skill": cfg.skill,
                                            "episodes": [{k: e.get(k) for k in ("index", "episode_id", "setting", "seed", "skipped")} for e in doc["episodes"]]})
    outcomes = [s["success"] for e in doc["episodes"] if "skipped" not in e for s in e["skills"] if s["skill"] == cfg.skill]
    return sum(outcomes) / len(outcomes) if outcomes else math.nan
