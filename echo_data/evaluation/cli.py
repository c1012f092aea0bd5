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
        lines.append(f"    Navigate hand-over {cell(m['navigate_handover'])}")
        lines.append(f"    Navigate SPL       {cell(m['navigate_spl'])}")
        if m.get("carry_handover", {}).get("n"):  # a Place carried by the drive policy
            lines.append(f"    carry hand-over    {cell(m['carry_handover'])}")
    if "seeds" in doc:
        seeds = doc["seeds"]
        each = ", ".join(f"{m['k']}/{m['n']}" for m in seeds["per_seed"])
        lines.append(f"  {seeds['members']} training seeds: skill completion pooled {cell(seeds['pooled'])}; per seed {each}")
    if doc["skipped"]:
        lines.append(f"  skipped (no solvable layout): {doc['skipped']}")
    lines.append(f"  wall time {doc['wall_seconds']:.1f} s on {doc['workers']} worker(s)")
    return "\n".join(lines)


def _check_targets(json_out: Path | None, video: Path | None, resume: bool, split: str, n: int) -> str:
    """Why `--json`/`--video`/`--resume` cannot be used ("" when they can): checked before the first episode.

    Neither overwrites a user's file: `--json OUT` replaces only an earlier evaluation result;
    `--video DIR` writes one `<episode id>.mp4` per episode and nothing else, and refuses a
    folder already holding one of those names (with `--resume`, the same evaluation's)."""
    from echo_data.episode import episode_id
    from echo_data.evaluation.run import is_result, video_path
    from echo_data.targets import TargetError, check_file, check_folder

    if resume and json_out is None:
        return "--resume: continues the evaluation recorded next to --json; give --json"
    if json_out is not None and not json_out.parent.is_dir():
        return f"--json {json_out}: folder {json_out.parent} does not exist"
    if json_out is not None and json_out.is_file() and not is_result(json_out):
        return f"--json {json_out}: exists and is no echo-data evaluation result; echo-data replaces only what it wrote (nothing was touched)"
    if video is not None and video.is_dir() and not resume:
        taken = next((p for i in range(n) if (p := video_path(video, episode_id(split, i))).exists() or p.is_symlink()), None)
        if taken is not None:
            return f"--video {video}: holds {taken.name} already; evaluate writes only new files there (give another folder, or remove it; nothing was touched)"
    try:
        if json_out is not None:
            check_file(json_out, "--json")
        if video is not None:
            check_folder(video, "--video")
    except TargetError as e:
        return str(e)
    return ""


def run_evaluate(
    recipe: Recipe, recipe_path: Path, split: str, n: int, policy: str | tuple[str, ...], planner: str, workers: int, json_out: Path | None, video: Path | None,
    resume: bool = False, drive_end: str = "handover",
) -> int:
    """`echo-data evaluate`: 0 when the results are written, 2 for bad input (one line on stderr).

    With `--json OUT` every finished episode is recorded at once in `OUT.episodes.jsonl`
    (`evaluation.journal`); `resume` runs only the episodes not recorded there."""
    from tqdm import tqdm

    from echo_data.agents.compose import is_composite, spec_name
    from echo_data.agents.loading import AgentLoadError, check_observations, identity, load_planner, load_policy
    from echo_data.agents.runtime import RUNTIME_OBSERVATIONS, AgentActionError
    from echo_data.envs.env import observation_space
    from echo_data.evaluation.journal import Journal, JournalError, journal_path
    from echo_data.evaluation.rendered import rendering
    from echo_data.evaluation.run import evaluate
    from echo_data.evaluation.seeds import SeedSpecError, split_members

    size = recipe.splits.get(split)
    if size is None:
        return _fail(f"--split {split}: recipe {recipe_path} has no such split ({', '.join(recipe.splits)})")
    if n > size:
        return _fail(f"-n {n}: index {n - 1} is past the {split} split of {recipe_path} ({size} episodes)")
    why = _check_targets(json_out, video, resume, split, n)
    if why:
        return _fail(why)
    from echo_data.sounds import SoundLibrary, SoundLibraryError

    try:  # an unusable sound folder is bad input now, not a failed episode in a worker
        SoundLibrary.from_recipe(recipe, recipe_path.resolve().parent).check_covers(recipe)
    except SoundLibraryError as e:
        return _fail(str(e).splitlines()[0])
    if not isinstance(policy, str) and not is_composite(policy):
        policy = policy[0]  # one plain policy: as before
    try:
        members = split_members(policy)  # one per training seed (`evaluation.seeds`)
        pols, plan = [load_policy(m) for m in members], load_planner(planner)
        known = (*observation_space(rendering(recipe, *pols, plan)).spaces, *RUNTIME_OBSERVATIONS)  # GOAL_POSE, privileged: the runtime adds them
        for pol, member in zip(pols, members, strict=True):
            check_observations(pol, f"policy {spec_name(member)!r}", known)
        check_observations(plan, f"planner {planner!r}", known)
        shown = [identity(p, m) for p, m in zip(pols, members, strict=True)]
        key = {"recipe": recipe.content_hash(), "split": split, "policy": shown[0] if len(shown) == 1 else shown,
               "planner": identity(plan, planner), "video": video is not None, "drive_end": drive_end}
    except (AgentLoadError, SeedSpecError) as e:
        return _fail(str(e))
    journal = None
    if json_out is not None:
        try:
            journal = Journal(journal_path(json_out), key, resume)
        except JournalError as e:
            return _fail(str(e))
    if video is not None:
        video.mkdir(parents=True, exist_ok=True)
    done = dict(journal.records) if journal is not None else {}
    bar = tqdm(total=n, initial=sum(i < n for i in done), desc="evaluate", unit="ep", file=sys.stderr, dynamic_ncols=True)
    tally = [0, 0]

    def tick(rec: dict[str, Any]) -> None:
        if journal is not None:
            journal.append(rec)
        tally[0] += 1
        tally[1] += int(bool(rec.get("success")))
        bar.update(1)
        bar.set_postfix_str(f"success {tally[1]}/{tally[0]}", refresh=False)

    finished = False
    try:
        doc = evaluate(recipe, recipe_path.resolve(), split, n, policy, planner, workers, video, progress=tick, done=done, drive_end=drive_end)
        finished = True
    except (AgentActionError, AgentLoadError) as e:
        bar.close()  # before the error line, so it stands alone
        return _fail(str(e) + (f" ({len(journal.records)} finished episode(s) kept in {journal.path})" if journal is not None else ""))
    except KeyboardInterrupt:
        bar.close()
        kept = f"; {len(journal.records)} finished episode(s) kept, --resume continues" if journal is not None else ""
        print(f"interrupted{kept}", file=sys.stderr)
        return 130
    finally:
        bar.close()
        if journal is not None and not finished:
            journal.close(finished=False)
    print(format_tables(doc))
    if json_out is not None and journal is not None:
        from echo_data.dataset.storage import atomic_write_json

        try:
            atomic_write_json(json_out, doc)
        except OSError as e:
            journal.close(finished=False)
            return _fail(f"--json {json_out}: cannot write ({e.strerror or e}); the episodes are kept in {journal.path}, --resume writes it")
        journal.close(finished=True)
        print(f"wrote {json_out}")
    return 0
