"""Run a policy on episodes 0..n-1 of a split, closed-loop, and collect per-episode outcomes.

Each episode is a pure function of (recipe, split, index, policy, planner): a fresh world per
episode, policies reset per skill with seeds from the episode, results ordered by index. So the
results are the same whatever the worker count (timings aside). Episodes are sampled as the build
samples them (attempt 0; a later attempt only when sampling itself finds no solvable layout),
never chosen by how an agent does on them.

The environment renders only what the agent reads (`policy.observations`, a tuple of
observation keys; absent = everything) plus what a video needs: the world and its physics are
the same either way.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.schema import AUDIO_PREFIX, IMAGE_PREFIX
from echo_data.recipe import Recipe

SAMPLING_RETRIES = 3


@dataclass(frozen=True)
class EvalJob:
    recipe: Recipe
    recipe_dir: str | None
    split: str
    policy: str | tuple[str, ...]  # a tuple: one policy per skill (`echo_data.agents.compose`)
    planner: str
    video_dir: str | None = None
    drive_end: str = "handover"  # how a learned drive that does not STOP ends (`agents.runtime.DRIVE_ENDS`)
    member: int | None = None  # which training seed's runs act (`evaluation.seeds`); None: a single training


RESULT_KEYS = ("recipe", "split", "n", "policy", "planner", "versions", "metrics", "episodes")  # evaluate's document


def is_result(path: Path) -> bool:
    """Whether `path` holds an evaluation result echo-data wrote (what `--json` may replace)."""
    try:
        doc = json.loads(path.read_bytes().decode("utf-8"))
    except (OSError, ValueError, RecursionError):
        return False
    return isinstance(doc, dict) and all(k in doc for k in RESULT_KEYS) and isinstance(doc["versions"], dict) and "echo-data" in doc["versions"]


def video_path(folder: Path, episode: str) -> Path:
    """Where `--video` puts episode `episode`'s recording: the one file per episode it writes."""
    return folder / f"{episode}.mp4"


def needs(*agents: Any) -> tuple[bool, bool]:
    """(images, audio): which observation groups the agents (policy, planner) read; an agent
    that does not say (no `observations`) gets everything."""
    images = audio = False
    for agent in agents:
        keys = getattr(agent, "observations", None)
        if keys is None:
            return True, True
        images |= any(k.startswith(IMAGE_PREFIX) for k in keys)
        audio |= any(k.startswith(AUDIO_PREFIX) for k in keys)
    return images, audio


_WORKER: dict[str, Any] = {}


# torch's intra-op threads while a learner acts. One: a learner acts on one observation at a time,
# where more threads only spin (one test episode of the default ACT: 91 s of CPU on 2 cores against
# 13 s on one thread), and a float reduction split over another
# thread count can round differently, so an episode measured on a laptop would not be the episode
# the cluster measures. Training pins its own count the same way (`--threads`, learn/loop.py).
ACTING_THREADS = 1


def acting_threads() -> None:
    """Pin torch (when a policy or planner imported it) to `ACTING_THREADS` in this process."""
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(ACTING_THREADS)


def _worker_state(job: EvalJob) -> tuple[Any, Any, Any]:
    """(env, policy, planner) of this process, made once per job."""
    if _WORKER.get("job") != job:
        from echo_data.agents.loading import load_planner, load_policy
        from echo_data.envs.env import EchoDataEnv

        if _WORKER.get("env") is not None:
            _WORKER["env"].close()
        policy, planner = load_policy(job.policy), load_planner(job.planner)
        acting_threads()
        images, audio = needs(policy, planner)
        if job.video_dir:
            images = audio = True
        from echo_data.evaluation.rendered import rendering

        env = EchoDataEnv(rendering(job.recipe, policy, planner), split=job.split, images=images, audio=audio, recipe_dir=job.recipe_dir)
        _WORKER.update(job=job, env=env, policy=policy, planner=planner)
    return _WORKER["env"], _WORKER["policy"], _WORKER["planner"]


def episode_record(run: Any, index: int) -> dict[str, Any]:
    """The JSON-able outcome of one `EpisodeRun`."""
    return {
        "index": index,
        "episode_id": run.episode_id,
        "setting": run.setting,
        "seed": run.seed,
        "true_chain": run.true_chain,
        "planned_chain": run.planned_chain,
        "plan_correct": run.plan_correct,
        "skills": [o.to_dict() for o in run.outcomes],  # with each hand-over's end pose (build --handover-from reads it)
        "skills_completed": run.skills_completed,
        "success": run.success,
        "steps": run.steps,
        "navigate": [drive_record(r) for r in run.navigate],
        # Place's carries by the drive policy (`agents.runtime.carry_call`): where each handed over
        "carries": [drive_record(r) for r in run.carries],
        "failure": run.failure,
    }


def drive_record(r: Any) -> dict[str, Any]:
    """The JSON-able form of one drive's `NavigateRecord` (a Navigate, or a Place's carry)."""
    return {"skill_index": r.skill_index, "success": r.success, "path_length": round(r.path_length, 6),
            "expert_length": None if r.expert_length != r.expert_length else round(r.expert_length, 6),
            "spl": None if r.expert_length != r.expert_length else round(r.spl, 6),
            **{k: None if v != v else round(v, 6) for k, v in (("goal_distance", r.goal_distance), ("heading_error", r.heading_error),
                                                                ("arm_moved", r.arm_moved))},
            "handed_over": r.handed_over}


def evaluate_episode(job: EvalJob, index: int) -> dict[str, Any]:
    """Sample, run and score episode `index` of `job.split` (in this process)."""
    from echo_data.agents.runtime import AgentActionError, run_episode
    from echo_data.scene.sampling import SamplingError

    t0 = time.perf_counter()
    env, policy, planner = _worker_state(job)
    spec = None
    for attempt in range(SAMPLING_RETRIES):
        try:
            spec = env.sample_spec(job.split, index, attempt)
            break
        except SamplingError:
            continue
    if spec is None:
        return {"index": index, "skipped": f"no solvable layout in {SAMPLING_RETRIES} sampling attempts", "seconds": time.perf_counter() - t0}
    obs, info = env.reset(options={"spec": spec})
    video = _VideoRecorder(env) if job.video_dir else None
    try:
        run = run_episode(env, obs, info, planner, policy, on_step=video, drive_end=job.drive_end)
    except AgentActionError:
        raise
    except Exception as e:  # the agent's own code failed mid-episode: that episode fails, the evaluation goes on
        from echo_data.agents.runtime import EpisodeRun, true_chain

        run = EpisodeRun(spec.episode_id, spec.setting, spec.seed, true_chain(spec), None, False, failure=f"agent error: {type(e).__name__}: {e}".splitlines()[0])
        run.steps = env.steps
    finally:
        close = getattr(policy, "close", None)
        if callable(close):
            close()
    rec = episode_record(run, index)
    if job.member is not None:
        rec["member"] = job.member
    if video is not None and video.frames:
        rec["video"] = video.write(video_path(Path(job.video_dir), spec.episode_id))  # type: ignore[arg-type]
    rec["seconds"] = time.perf_counter() - t0
    return json.loads(json.dumps(rec))  # the record as a results file holds it (and as a resumed run reads it back)


class _VideoRecorder:
    """Keeps what each step's video frame shows (head camera, pose, which sources sound); the
    frames are composed at the end, when the whole track is known (`echo_data.viz.frames`)."""

    def __init__(self, env: Any) -> None:
        self.env = env
        self.steps: list[tuple[Any, Any, Any, tuple[float, float], float, tuple[bool, ...], str]] = []

    @property
    def frames(self) -> int:
        return len(self.steps)

    def __call__(self, env: Any, obs: dict, action: Any, k: int, call: Any, flags: tuple[bool, ...]) -> None:
        from echo_data.camera import DEPTH_UNIT_M
        from echo_data.dataset.schema import IMAGE_COLUMNS

        x, y, yaw = env.world.robot.base_pose()
        depth_m = [None if (d := obs.get(IMAGE_COLUMNS[c])) is None else np.asarray(d, dtype=np.float64) * DEPTH_UNIT_M for c in ("head_depth", "wrist_depth")]
        self.steps.append((obs.get(IMAGE_COLUMNS["head_rgb"]), depth_m[0], depth_m[1], (x, y), yaw, tuple(env.sounding), f"{call.skill}({call.target})"))

    def write(self, path: Path) -> str:
        from echo_data.media import write_mp4
        from echo_data.viz.frames import PANEL, EpisodeFrames
        from echo_data.viz.listening import listening
        from echo_data.viz.topdown import TopDownMap

        track, offsets = self.env.episode_audio()
        hop, fs = self.env.track.hop, self.env.track.fs
        start = int(offsets[0])
        audio = track[start : start + len(self.steps) * hop]
        episode = self.env.episode
        level = listening(audio, self.env.recipe.acoustics.full_scale_db_spl)
        video = EpisodeFrames(TopDownMap(episode.plan, episode.events, size=PANEL), track, fs, sound_note=level.note())
        path_xy = [s[3] for s in self.steps]
        frames = (
            video.frame(rgb, depth, path_xy[: t + 1], yaw, start + t * hop, f"{episode.episode_id}  t={t / self.env.recipe.robot.control_hz:.1f}s  {caption}", sounding, wrist_depth_m=wrist)
            for t, (rgb, depth, wrist, _, yaw, sounding, caption) in enumerate(self.steps)
        )
        path.parent.mkdir(parents=True, exist_ok=True)
        write_mp4(path, frames, fps=float(self.env.recipe.robot.control_hz), audio=level.apply(audio), sample_rate=fs)
        return str(path)


_JOB: dict[str, EvalJob] = {}


def _set_job(job: EvalJob) -> None:
    """Worker setup: the job every task of this evaluation shares (sent once per worker)."""
    _JOB["job"] = job


def _evaluate_index(index: int) -> dict[str, Any]:
    return evaluate_episode(_JOB["job"], index)


def run_episodes(
    job: EvalJob, n: int, workers: int = 1, progress: Callable[[dict[str, Any]], None] | None = None, done: dict[int, dict[str, Any]] | None = None,
    indices: Sequence[int] | None = None,
) -> list[dict[str, Any]]:
    """Episodes 0..n-1 of the split (or those of `indices`), on `workers` processes (the build's
    pool); records ordered by index.

    `done`: records already finished (a resumed evaluation): those episodes are not run again.
    `progress` is called with each newly finished record as it completes."""
    from echo_data.app.executors import make_executor

    wanted = list(range(n)) if indices is None else list(indices)
    out = {i: r for i, r in (done or {}).items() if i in set(wanted)}
    todo = [i for i in wanted if i not in out]
    pool = make_executor("local", max(1, min(workers, len(todo))), _set_job, (job,)) if todo else None
    try:
        for rec in pool.imap_unordered(_evaluate_index, todo) if pool is not None else ():
            out[rec["index"]] = rec
            if progress:
                progress(rec)
    finally:
        if pool is not None:
            pool.close()
    return [out[i] for i in wanted]


def _shown_path(path: Path) -> str:
    """A path as results name it: relative to the working folder when inside it, so a results
    JSON written in a checkout carries no path of the machine it ran on."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)

def evaluate(
    recipe: Recipe,
    recipe_path: Path | None,
    split: str,
    n: int,
    policy: str | tuple[str, ...],
    planner: str,
    workers: int = 1,
    video_dir: Path | None = None,
    progress: Callable[[dict[str, Any]], None] | None = None,
    done: dict[int, dict[str, Any]] | None = None,
    drive_end: str = "handover",
) -> dict[str, Any]:
    """The results document: metrics per setting, per-episode outcomes, what was evaluated.

    `done`: records of episodes already finished (`evaluation.journal`), not run again;
    `drive_end`: how a learned drive that does not STOP ends (`agents.runtime.DRIVE_ENDS`)."""
    from echo_data.agents.compose import spec_name
    from echo_data.agents.loading import identity, load_planner, load_policy
    from echo_data.dataset.manifest import versions
    from echo_data.evaluation.metrics import by_setting
    from echo_data.evaluation.seeds import member_of, per_seed, split_members

    members = split_members(policy)  # one per training seed (`evaluation.seeds`)
    pols, plan = [load_policy(m) for m in members], load_planner(planner)  # fail fast, in this process
    if not isinstance(policy, str):
        policy = tuple(policy)
    t0 = time.perf_counter()
    episodes: list[dict[str, Any]] = []
    for j, member in enumerate(members):
        job = EvalJob(recipe, str(recipe_path.parent) if recipe_path else None, split, member, planner, str(video_dir) if video_dir else None,
                      drive_end, j if len(members) > 1 else None)
        episodes += run_episodes(job, n, workers, progress, done, indices=[i for i in range(n) if member_of(i, len(members)) == j])
    episodes.sort(key=lambda e: e["index"])
    scored = [e for e in episodes if "skipped" not in e]
    shown = identity(pols[0], members[0]) if len(members) == 1 else {
        "name": spec_name(policy), "members": [identity(p, m) for p, m in zip(pols, members, strict=True)]}
    from echo_data.evaluation.provenance import weights

    doc = {
        "recipe": {"name": recipe.name, "path": _shown_path(recipe_path) if recipe_path else None, "content_hash": recipe.content_hash()},
        "split": split,
        "n": n,
        "policy": shown,
        "planner": identity(plan, planner),
        "weights": weights(shown, identity(plan, planner)),  # per skill and the planner: SHA-256 of the weights acted with
        "drive_end": drive_end,
        "acting_threads": ACTING_THREADS,  # torch's threads while learners acted (the episodes depend on it)
        "versions": versions(),
        "metrics": by_setting(scored),
        "skipped": [e["index"] for e in episodes if "skipped" in e],
        "episodes": episodes,
        "wall_seconds": time.perf_counter() - t0,
        "workers": workers,
    }
    if len(members) > 1:
        doc["seeds"] = per_seed(episodes, len(members))
    return doc
