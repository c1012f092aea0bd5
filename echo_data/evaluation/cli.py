"""The body of `echo-data evaluate`: check the arguments, run, print the tables, write the JSON."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from echo_data.recipe import Recipe


def _fail(msg: str) -> int:
    print(f"error: {msg}", file=sys.stderr)
    return 2


def format_tables(doc: dict[str, Any]) -> str:
    """Human-readable tables: one per setting, value [95 % interval] (N)."""

    def cell(m: dict[str, Any]) -> str:
        if m["value"] is None:
            return "n/a"
        return f"{m['value']:.3f} [{m['ci95'][0]:.3f}, {m['ci95'][1]:.3f}] (N={m['n']})"

    lines = [f"{doc['recipe']['name']} / {doc['split']}: policy {doc['policy']['name']}, planner {doc['planner']['name']}"]
    for setting, m in doc["metrics"].items():
        lines.append(f"  {setting}  ({m['episodes']} episodes, mean {m['mean_steps']:.0f} steps, {m['seconds']:.0f} s)")
        lines.append(f"    task planning      {cell(m['task_planning'])}")
        lines.append(f"    skill completion   {cell(m['skill_completion'])}")
        for p in m["progressive"]:
            lines.append(f"    through skill {p['through']}    {cell(p)}")
        lines.append(f"    Navigate success   {cell(m['navigate_success'])}")
        lines.append(f"    Navigate SPL       {cell(m['navigate_spl'])}")
    if doc["skipped"]:
        lines.append(f"  skipped (no solvable layout): {doc['skipped']}")
    lines.append(f"  wall time {doc['wall_seconds']:.1f} s on {doc['workers']} worker(s)")
    return "\n".join(lines)


def run_evaluate(
    recipe: Recipe, recipe_path: Path, split: str, n: int, policy: str | tuple[str, ...], planner: str, workers: int, json_out: Path | None, video: Path | None
) -> int:
    from tqdm import tqdm

    from echo_data.agents.compose import is_composite
    from echo_data.agents.loading import AgentLoadError, load_planner, load_policy
    from echo_data.agents.runtime import AgentActionError
    from echo_data.evaluation.run import evaluate

    size = recipe.splits.get(split)
    if size is None:
        return _fail(f"--split {split}: recipe {recipe_path} has no such split ({', '.join(recipe.splits)})")
    if n > size:
        return _fail(f"-n {n}: index {n - 1} is past the {split} split of {recipe_path} ({size} episodes)")
    if json_out is not None and not json_out.parent.is_dir():
        return _fail(f"--json {json_out}: folder {json_out.parent} does not exist")
    if video is not None and video.exists() and not video.is_dir():
        return _fail(f"--video {video}: exists and is not a folder")
    if not isinstance(policy, str) and not is_composite(policy):
        policy = policy[0]  # one plain policy: as before
    try:
        load_policy(policy)
        load_planner(planner)
    except AgentLoadError as e:
        return _fail(str(e))
    bar = tqdm(total=n, desc="evaluate", unit="ep", file=sys.stderr, dynamic_ncols=True)
    done = [0, 0]

    def tick(rec: dict[str, Any]) -> None:
        done[0] += 1
        done[1] += int(bool(rec.get("success")))
        bar.update(1)
        bar.set_postfix_str(f"success {done[1]}/{done[0]}", refresh=False)

    try:
        doc = evaluate(recipe, recipe_path.resolve(), split, n, policy, planner, workers, video, progress=tick)
    except (AgentActionError, AgentLoadError) as e:
        bar.close()
        return _fail(str(e))
    bar.close()
    print(format_tables(doc))
    if json_out is not None:
        from echo_data.dataset.storage import atomic_write_json

        atomic_write_json(json_out, doc)
        print(f"wrote {json_out}")
    return 0
