"""`echo-data build`: episodes -> shards, with workers, resume and kill-safety (the orchestration).

Episodes are computed anywhere (see `echo_data.app.executors`): a worker samples, simulates and
hears one episode (`echo_data.app.pipeline`) and encodes it (`echo_data.dataset.encode`), its
attempts in `echo_data.app.attempts`; this
process alone writes, through `echo_data.dataset.writer.DatasetWriter` (staging, shards in
order, manifest, meta), whose files are all replaced atomically (`echo_data.dataset.storage`).
A kill therefore loses at most the episodes in flight, and a resume verifies shards by sha256,
reuses staged episodes and redoes the rest, producing the same bytes. The write path top-down:
build -> writer -> shards (`echo_data.dataset.shards`) / manifest -> storage.
"""

from __future__ import annotations

import errno
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Any, Literal

from echo_data.app import episode_progress
from echo_data.app.attempts import FailedEpisode, Generate, Job, default_library, init_job, one_line, run_task
from echo_data.app.executors import ExecutorError, make_executor
from echo_data.app.handover_from import HandoverRun, load_handover_run
from echo_data.dataset import learner_stops
from echo_data.dataset.lock import LOCK_NAME, BuildLock, BuildLockedError
from echo_data.dataset.manifest import (
    ManifestError,
    ShardPlans,
    load_manifest,
    new_manifest,
    plan_shards,
    split_sizes,
    write_manifest,
)
from echo_data.dataset.schema import FORMAT_VERSION, StepLayout
from echo_data.dataset.writer import DatasetWriter
from echo_data.dataset.written import DATASET, NotWrittenByUs, dataset_files, read_marker, remove_written, write_marker
from echo_data.outputs import OutputError, check_output_path
from echo_data.protocols import SoundLibrary
from echo_data.recipe import Recipe

BuildMode = Literal["new", "resume", "overwrite"]


class OutputWriteError(OutputError):
    """The output cannot be written (disk full, read-only): exit 2; finished episodes are kept."""


class BuildError(RuntimeError):
    """The build could not finish (an episode never succeeded, a worker died); resumable."""


@dataclass
class BuildSummary:
    """What a build produced; `str()` is the end-of-build summary."""

    out: Path
    episodes: dict[str, int]
    steps: dict[str, int]
    generated: int  # episodes computed by this run
    reused: int  # episodes found done (verified shards or stored intermediates)
    failed_attempts: int  # expert failures / sampling errors, whole dataset
    rejected: int  # sampling rejections, whole dataset
    shards: int
    bytes: int
    seconds: float
    success_rate: float | None
    skills: dict[str, dict[str, int]] = field(default_factory=dict)

    def __str__(self) -> str:
        eps = ", ".join(f"{k} {v}" for k, v in self.episodes.items())
        steps = sum(self.steps.values())
        rate = "n/a" if self.success_rate is None else f"{self.success_rate:.0%}"
        skills = ", ".join(f"{k} {v['successes']}/{v['attempts']}" for k, v in self.skills.items())
        return (
            f"{self.out}: episodes {eps}; {steps} steps in {self.shards} shards, {self.bytes / 1e6:.1f} MB; "
            f"{self.generated} generated, {self.reused} reused in {self.seconds:.1f} s; "
            f"episode success {rate} ({self.failed_attempts} failed attempts, {self.rejected} rejected samples)"
            + (f"; skills {skills}" if skills else "")
        )


# ---------------------------------------------------------------- output checks


def _prepare(
    out: Path, recipe: Recipe, limit: int | None, layout: StepLayout, mode: str, workers: int, executor: str, only: Sequence[str] | None,
    handover: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Create, refuse, replace or reopen the output according to `mode`; return its manifest
    (`handover`: the provenance of `--handover-from`, recorded as its `handover_from`)."""
    has_content = out.is_dir() and any(p.name != LOCK_NAME for p in out.iterdir())
    if has_content and mode == "new":
        raise OutputError(f"{out} already exists; use --resume to continue it or --overwrite to replace it")
    if has_content and mode == "resume":
        try:
            manifest = load_manifest(out)
        except ManifestError as e:
            raise OutputError(f"cannot resume: {e}") from None
        if manifest["recipe_hash"] != recipe.content_hash():
            raise OutputError(
                f"{out} was built from a different recipe (hash {manifest['recipe_hash'][:12]}, this recipe "
                f"{recipe.content_hash()[:12]}); use --overwrite to rebuild it"
            )
        if manifest.get("limit") != limit:
            raise OutputError(f"{out} was built with --limit {manifest.get('limit')}, not {limit}; pass the same --limit or --overwrite")
        if manifest.get("only_splits") != (None if only is None else list(plan_shards(recipe, limit, only))):
            raise OutputError(f"{out} was built with --split {manifest.get('only_splits') or 'all'}, not {only or 'all'}; pass the same --split or --overwrite")
        was = (manifest.get(learner_stops.KEY) or {}).get("sha256")
        if was != (handover or {}).get("sha256"):
            raise OutputError(f"{out} was built with --handover-from {(manifest.get(learner_stops.KEY) or {}).get('file', 'none')} "
                              f"(sha256 {str(was)[:12]}), not this one; pass the same file or --overwrite")
        if read_marker(out) is None:  # built before the marker existed
            write_marker(out, DATASET, FORMAT_VERSION)
        manifest["build"].update({"workers": workers, "executor": executor})
        manifest["build"]["resumes"] = manifest["build"].get("resumes", 0) + 1
        return manifest
    if has_content and mode == "overwrite":
        try:  # every file is checked before the first is deleted
            files = dataset_files(out)
        except NotWrittenByUs as e:
            raise OutputError(str(e)) from None
        remove_written(out, files, keep=(LOCK_NAME,))  # all but the lock this build holds
    out.mkdir(parents=True, exist_ok=True)
    manifest = new_manifest(recipe, limit, layout, workers, executor, only)
    if handover is not None:
        manifest[learner_stops.KEY] = dict(handover)
    write_manifest(out, manifest)
    write_marker(out, DATASET, FORMAT_VERSION)  # after the manifest: a folder holding only a marker is never left
    return manifest


# ---------------------------------------------------------------- parent side


BAR_WIDTH = 20  # characters of the bar itself: the postfix (success, rates, sampling) never squeezes it


def build_bar(total: int, reused: int, name: str, disable: bool | None, file: Any = None) -> Any:
    """The build's tqdm bar over episodes. Its rate and ETA are the run's average
    (smoothing=0): the live bar moves by fractions of an episode every second, and tqdm's default
    moving average over those steps showed `463.49s/ep` and 30 minutes left for a 19 s build.
    `disable` None: no bar when stderr is no terminal (logs, pipes)."""
    from tqdm.auto import tqdm

    return tqdm(
        total=total, initial=reused, unit="ep", desc=f"build {name}", dynamic_ncols=True, smoothing=0, file=file,
        disable=disable, bar_format="{l_bar}{bar:" + str(BAR_WIDTH) + "}| {n:.1f}/{total_fmt} [{elapsed}<{remaining}, {rate_fmt}{postfix}]",
    )


class _LiveBar:
    """The build's bar: finished episodes plus the share done of the running ones (read from the
    workers' progress slots every second by a thread, so the bar and its ETA, which is over this
    run's episodes, i.e. `--limit`, move inside a long episode)."""

    def __init__(self, bar: Any, slots: Any, rate: _Rate) -> None:
        self.bar, self.slots, self.rate = bar, slots, rate
        self.done = float(bar.n)
        self.postfix = ""
        self.started = False
        self.lock = threading.Lock()
        self.stop = threading.Event()

    def _show(self) -> None:
        expected = self.rate.steps / self.rate.episodes if self.rate.episodes else None
        inside = episode_progress.running_fraction(self.slots, expected) if self.slots is not None else 0.0
        sampling = episode_progress.preparing(self.slots) if self.slots is not None else 0
        self.started = self.started or self.slots is None or any(self.slots[1::2])  # a worker has taken an episode
        with self.lock:
            note = f"{sampling} sampling (scene, acoustics)" if sampling else "" if self.started else "starting workers"
            self.bar.set_postfix_str("; ".join(p for p in (note, self.postfix) if p), refresh=False)
            self.bar.update(min(self.done + inside, self.bar.total) - self.bar.n)

    def _watch(self) -> None:
        while not self.stop.wait(1.0):
            self._show()

    def finished(self, postfix: str) -> None:
        with self.lock:
            self.done += 1
            self.postfix = postfix
        self._show()

    def __enter__(self) -> _LiveBar:
        self.thread = None
        if self.slots is not None and not self.bar.disable:
            self.thread = threading.Thread(target=self._watch, name="build-bar", daemon=True)
            self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        if self.thread is not None:
            self.thread.join()


class _Rate:
    """Steps/s of this run and, when this run is smaller than the recipe (--limit, --split), the
    projected time the rest of the recipe would take at this rate; this run's own time left is
    the bar's ETA (its total is this run's episodes)."""

    def __init__(self, recipe_todo: int, run_todo: int) -> None:
        self.t0 = time.monotonic()
        self.recipe_todo = recipe_todo
        self.run_todo = run_todo
        self.episodes = self.steps = 0

    def add(self, steps: int) -> None:
        self.episodes += 1
        self.steps += steps

    def __str__(self) -> str:
        dt = max(time.monotonic() - self.t0, 1e-9)
        rate = f"{self.steps / dt:.0f} steps/s"
        if self.recipe_todo <= self.run_todo:
            return rate
        rest = (self.recipe_todo - self.run_todo) * dt / max(self.episodes, 1)
        return f"{rate}; the rest of the recipe (beyond this run) ~{_duration(rest)} more"


def _duration(seconds: float) -> str:
    s = int(round(max(seconds, 0.0)))
    return f"{s // 3600}h{s % 3600 // 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"


def _default_generate() -> Generate:
    try:
        from echo_data.app.pipeline import generate_episode
    except ImportError as e:
        raise BuildError(f"the episode pipeline is not available: {e}") from None
    return generate_episode


def build(
    recipe: Recipe,
    recipe_path: Path,
    out: Path,
    workers: int = 1,
    limit: int | None = None,
    mode: BuildMode = "new",
    executor: Literal["local", "ray"] = "local",
    generate: Generate | None = None,
    progress: bool = True,
    make_library: Callable[[Recipe, Path], SoundLibrary] | None = None,
    address: str | None = None,
    only: Sequence[str] | None = None,
    handover_from: Path | None = None,
) -> BuildSummary:
    """Build (or resume) the dataset of `recipe` in the directory `out`.

    `generate(recipe, split, index, library, recipe_dir, attempt=0) -> EpisodeResult` defaults
    to `echo_data.app.pipeline.generate_episode`; `make_library(recipe, recipe_dir)` defaults to the
    recipe's `SoundLibrary`; `address` is a Ray cluster's (with executor "ray"); `only` names the
    splits to build (default: all); `handover_from`: an `evaluate` run whose learner's hand-overs
    the Navigate expert stops at (`echo_data.app.handover_from`). Raises
    `OutputError` (bad input, nothing written) or `BuildError`.
    """
    t0 = time.monotonic()
    out = Path(out)
    if mode not in ("new", "resume", "overwrite"):
        raise OutputError(f"unknown build mode {mode!r}")
    if limit is not None and limit < 1:
        raise OutputError(f"--limit must be >= 1, got {limit}")
    if workers < 1:
        raise OutputError(f"--workers must be >= 1, got {workers}")
    check_output_path(out)
    if executor == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise OutputError("--executor ray needs Ray: pip install 'echo-data[ray]' (or use --executor local)") from None
    elif executor != "local":
        raise OutputError(f"unknown executor {executor!r} (use local or ray)")
    if address and executor != "ray":
        raise OutputError("--address names a Ray cluster: use it with --executor ray")
    if only is not None and (not only or set(only) - set(recipe.splits)):
        raise OutputError(f"--split {','.join(only)}: the recipe's splits are {', '.join(recipe.splits)}")
    run = load_handover_run(Path(handover_from), recipe) if handover_from is not None else None
    layout = StepLayout.from_recipe(recipe)
    plans = plan_shards(recipe, limit, only)
    gen = generate or _default_generate()
    # Read the sound library once before anything is written: an unreadable user WAV is bad
    # input (exit 2, nothing written), not a crash inside a worker halfway through the build.
    try:
        library = (make_library or default_library)(recipe, Path(recipe_path).resolve().parent)
        if hasattr(library, "check_covers"):  # protocols.SoundLibrary does not require the check of a caller's library
            library.check_covers(recipe)
    except Exception as e:
        if type(e).__name__ != "SoundLibraryError":
            raise
        raise OutputError(str(e).splitlines()[0]) from None
    missing = [d for d in (out, *out.absolute().parents) if not d.exists()]  # folders the lock creates
    had_lock = (out / LOCK_NAME).exists()
    lock = BuildLock(out)
    try:
        lock.acquire()
    except BuildLockedError as e:
        raise OutputError(str(e)) from None
    except OSError as e:
        raise OutputError(f"{out}: cannot create the build lock ({e.strerror or e})") from None
    try:
        return _build_locked(recipe, recipe_path, out, workers, limit, mode, executor, gen, progress, make_library, layout, plans, t0, address, only, run)
    except OSError as e:
        if e.errno not in _OUTPUT_ERRNOS:
            raise
        where = e.filename or out
        raise OutputWriteError(
            f"{where}: {e.strerror or e}; every finished episode is kept: "
            f"{'free space' if e.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG) else 'make the folder writable'} and rerun with --resume"
        ) from None
    except OutputError:
        if missing and [p.name for p in out.iterdir()] == [LOCK_NAME]:  # refused before writing: leave no trace
            (out / LOCK_NAME).unlink()
            for d in missing:
                d.rmdir()
        elif not had_lock:  # refused in a folder that is not ours: leave it as it was
            (out / LOCK_NAME).unlink(missing_ok=True)
        raise
    finally:
        lock.release()


# Errors of the output device, not of the program: a full disk or quota, a read-only or
# vanished folder. They end a build with one line (exit 2); finished episodes stay on disk.
_OUTPUT_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EIO, errno.EFBIG})


def _build_locked(
    recipe: Recipe,
    recipe_path: Path,
    out: Path,
    workers: int,
    limit: int | None,
    mode: BuildMode,
    executor: str,
    gen: Generate,
    progress: bool,
    make_library: Callable[[Recipe, Path], SoundLibrary] | None,
    layout: StepLayout,
    plans: dict[str, ShardPlans],
    t0: float,
    address: str | None,
    only: Sequence[str] | None,
    run: HandoverRun | None = None,
) -> BuildSummary:
    """The build proper, run while this process holds the folder's build lock."""
    job = Job(recipe, Path(recipe_path).resolve().parent, layout, gen, make_library, run.jobs() if run is not None else {})
    # Ray workers cannot share memory with us: their bar moves per finished episode only.
    slots, counter = episode_progress.make_slots(workers, get_context("spawn")) if executor == "local" and progress else (None, None)
    try:  # before anything is written: a cluster that cannot be joined is bad input
        ex = make_executor(executor, workers, init_job, (job, slots, counter), address)
    except ExecutorError as e:
        raise OutputError(str(e)) from None
    bar = None
    try:
        manifest = _prepare(out, recipe, limit, layout, mode, workers, executor, only, run.provenance if run is not None else None)
        writer = DatasetWriter(out, recipe, layout, manifest, plans)
        writer.verify_shards()
        writer.remove_leftovers()
        for split in plans:
            writer.flush(split)
        total = sum(ps.episodes for ps in plans.values())
        reused = sum(len(p.indices) if p.file in writer.done else sum(writer.stored(s, i) for i in p.indices) for s, ps in plans.items() for p in ps)
        todo = (  # streamed: the plan never holds one item per episode
            (split, i)
            for split, ps in plans.items()
            for p in ps
            if p.file not in writer.done
            for i in p.indices
            if not writer.stored(split, i)
        )
        bar = build_bar(total, reused, recipe.name, None if progress else True)
        rate = _Rate(sum(split_sizes(recipe, None).values()) - reused, total - reused)
        attempts = successes = 0
        with _LiveBar(bar, slots, rate) as live:
            for res in ex.imap_unordered(run_task, todo):
                if isinstance(res, FailedEpisode) and res.error:
                    raise BuildError(f"{res.split} episode {res.index}: {res.error}")
                if isinstance(res, FailedEpisode):
                    reasons = "; ".join(f"attempt {f['attempt']}: {f['reason']}" for f in res.failures[-3:])
                    raise BuildError(
                        f"{res.split} episode {res.index}: no success in {len(res.failures)} attempts "
                        f"(max_attempts_per_episode); last: {reasons}"
                    )
                writer.store(res)
                attempts += 1 + len(res.failures)
                successes += 1
                rate.add(int(res.episode["n_steps"]))
                live.finished(f"success {successes / attempts:.0%}, {rate}")
                writer.flush(res.split)
    except BuildError:
        raise
    except Exception as e:
        if type(e).__name__ == "BrokenProcessPool" or type(e).__module__.startswith("ray."):
            raise BuildError(f"a worker process or node died ({one_line(str(e))[:300]}); finished episodes are kept: rerun with --resume") from e
        raise
    finally:
        ex.close()
        episode_progress.uninstall()  # the inline executor installed it in this process
        if bar is not None:
            bar.close()
    for split in plans:
        writer.flush(split)
    writer.finalize()
    m = writer.manifest
    return BuildSummary(
        out=out,
        episodes=dict(m["counts"]["episodes"]),
        steps=dict(m["counts"]["steps"]),
        generated=total - reused,
        reused=reused,
        failed_attempts=len(m["failed_episodes"]),
        rejected=sum(m["rejected"].values()),
        shards=len(m["shards"]),
        bytes=sum(e["bytes"] for e in m["shards"]),
        seconds=time.monotonic() - t0,
        success_rate=m["counts"]["episode_success_rate"],
        skills=m["skills"],
    )
