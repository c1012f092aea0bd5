"""One episode in a build worker: its attempts in order until one succeeds, then its encoding
(the worker side of `echo_data.app.build`; the parent alone writes). An attempt that crashes or
fails is recorded with its reason and draws and retried; a result that breaks the dataset
contract is a `FailedEpisode` with the error, never retried away.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from echo_data.app import episode_progress
from echo_data.app.handover_from import LearnerStops
from echo_data.dataset.encode import EncodedEpisode
from echo_data.dataset.schema import StepLayout
from echo_data.episode import attempt_draws
from echo_data.pcm import ClippingError
from echo_data.protocols import SoundLibrary
from echo_data.recipe import Recipe
from echo_data.records import EpisodeResult

Generate = Callable[..., EpisodeResult]


@dataclass(frozen=True)
class Job:
    """What every worker needs, sent once per worker."""

    recipe: Recipe
    recipe_dir: Path
    layout: StepLayout
    generate: Generate
    make_library: Callable[[Recipe, Path], SoundLibrary] | None
    # build --handover-from: a learner's hand-overs by (split, index) (`app.handover_from`)
    learner: dict[tuple[str, int], LearnerStops] = field(default_factory=dict)


@dataclass
class FailedEpisode:
    """No attempt of an episode succeeded within `max_attempts_per_episode`."""

    split: str
    index: int
    failures: list[dict[str, Any]]
    error: str = ""  # set when the episode broke the EpisodeResult contract (not retried)


_UNSET = object()
_JOB: Job | None = None
_LIBRARY: Any = _UNSET


def init_job(job: Job, slots: Any = None, counter: Any = None) -> None:
    global _JOB, _LIBRARY
    _JOB, _LIBRARY = job, _UNSET
    if slots is not None:
        episode_progress.install(slots, counter)


def default_library(recipe: Recipe, recipe_dir: Path) -> SoundLibrary:
    """The recipe's sound library (built once per worker)."""
    try:
        from echo_data.sounds import SoundLibrary
    except ImportError:
        from echo_data.sounds.library import SoundLibrary
    return SoundLibrary.from_recipe(recipe, recipe_dir)


def _is_sampling_error(e: BaseException) -> bool:
    # By name: importing echo_data.scene.sampling would pull SAPIEN into every process.
    return any(c.__name__ == "SamplingError" for c in type(e).__mro__)


def one_line(text: str) -> str:
    return " ".join(str(text).split())[:500]


def run_task(task: tuple[str, int]) -> EncodedEpisode | FailedEpisode:
    """Try attempts 0, 1, ... of one episode until one succeeds; encode it (runs in a worker).
    The worker's progress slot is cleared before the result leaves (episode_progress)."""
    try:
        episode_progress.prepare()
        return _attempt_episode(task)
    finally:
        episode_progress.end()


def _attempt_episode(task: tuple[str, int]) -> EncodedEpisode | FailedEpisode:
    global _LIBRARY
    from echo_data.dataset.encode import encode_episode

    assert _JOB is not None, "worker not initialised"
    job = _JOB
    split, index = task
    if _LIBRARY is _UNSET:
        _LIBRARY = (job.make_library or default_library)(job.recipe, job.recipe_dir)
    failures: list[dict[str, Any]] = []
    rejected: Counter[str] = Counter()
    skills: dict[str, list[int]] = {}
    budget = job.recipe.max_attempts_per_episode
    learner = {"learner": job.learner[(split, index)]} if (split, index) in job.learner else {}
    for attempt in range(budget):
        draws = attempt_draws(job.recipe.seed, split, index, attempt, budget)
        # Until a spec names the draw it used, the attempt is known by its draws (a sampling
        # failure used them all); `attempt` alone redoes it: generate(..., attempt=attempt).
        record: dict[str, Any] = {
            "split": split, "index": index, "attempt": attempt, "draws": [draws[0][0], draws[-1][0] + 1], "seed": draws[0][1],
        }
        try:
            result = job.generate(job.recipe, split, index, _LIBRARY, job.recipe_dir, attempt=attempt, **learner)
        except ClippingError as e:  # the track is too loud to store: a calibration problem, never retried away
            return FailedEpisode(split, index, failures, f"cannot be stored: {one_line(str(e))}")
        except Exception as e:  # an attempt that crashed is recorded and retried, never half-written
            counts = getattr(e, "counts", None) or getattr(e, "rejected", None) or {}  # SamplingError.counts
            rejected.update({str(k): int(v) for k, v in counts.items()})
            kind = "sampling" if _is_sampling_error(e) else f"error: {type(e).__name__}"
            failures.append({**record, "reason": one_line(f"{kind}: {e}"), "outcomes": []})
            continue
        spec = result.spec
        if (spec.split, int(spec.index)) != (split, index):
            return FailedEpisode(split, index, failures, f"generator returned episode {spec.split}/{spec.index}")
        record.update(draw=int(spec.attempt), seed=int(spec.seed))  # what was simulated
        rejected.update({str(k): int(v) for k, v in result.rejected.items()})
        for o in result.outcomes:
            s = skills.setdefault(o.skill, [0, 0])
            s[0] += 1
            s[1] += int(bool(o.success))
        if result.complete:  # succeeded, or cut by outputs.max_frames with no expert failure before the cut
            try:
                enc = encode_episode(result, job.layout)
            except ValueError as e:  # the result does not fit the dataset contract: a bug, not bad luck
                return FailedEpisode(split, index, failures, f"cannot be stored: {one_line(str(e))}")
            enc.failures, enc.rejected, enc.skills = failures, dict(sorted(rejected.items())), dict(sorted(skills.items()))
            return enc
        bad = next((o for o in result.outcomes if not o.success), None)
        reason = f"{bad.skill}({bad.target}): {bad.reason or 'failed'}" if bad else "episode unsuccessful"
        outcomes = [{"skill": o.skill, "target": o.target, "success": bool(o.success), "reason": o.reason} for o in result.outcomes]
        failures.append({**record, "reason": one_line(reason), "outcomes": outcomes})
    return FailedEpisode(split, index, failures)
