"""`echo-data trial`: run N episodes of a recipe without writing a dataset, and report how the experts did."""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from echo_data.recipe import Recipe


@dataclass
class TrialEpisode:
    index: int
    setting: str
    success: bool
    outcomes: list[tuple[str, bool, str]]  # (skill, success, reason)
    rejected: dict[str, int]
    steps: int
    seconds: float
    error: str = ""


@dataclass
class TrialReport:
    episodes: int = 0
    success_rate: float = 0.0
    skills: dict[str, dict[str, int]] = field(default_factory=dict)
    rejected: dict[str, int] = field(default_factory=dict)
    failures: dict[str, int] = field(default_factory=dict)
    seconds_per_episode: float = 0.0
    steps_per_second: float = 0.0
    per_setting: dict[str, dict[str, float]] = field(default_factory=dict)


def run_trial_episode(recipe: Recipe, recipe_dir: str | None, index: int, observe: bool) -> TrialEpisode:
    """Sample and simulate episode `index` of the train split; never raises for expert failures."""
    from echo_data.app.pipeline import simulate
    from echo_data.scene.sampling import SamplingError, sample_episode
    from echo_data.sounds import SoundLibrary

    t0 = time.perf_counter()
    library = SoundLibrary.from_recipe(recipe, Path(recipe_dir) if recipe_dir else None)
    try:
        spec, rejected = sample_episode(recipe, "train", index, library)
    except SamplingError as e:
        return TrialEpisode(index, "?", False, [], dict(getattr(e, "counts", {}) or {}), 0, time.perf_counter() - t0, str(e))
    ro = simulate(spec, recipe, observe=observe)
    return TrialEpisode(
        index=index,
        setting=spec.setting,
        success=ro.success,
        outcomes=[(o.skill, o.success, o.reason) for o in ro.outcomes],
        rejected=rejected,
        steps=len(ro.steps),
        seconds=time.perf_counter() - t0,
    )


def summarise(eps: list[TrialEpisode]) -> TrialReport:
    rep = TrialReport(episodes=len(eps))
    if not eps:
        return rep
    rep.success_rate = sum(e.success for e in eps) / len(eps)
    rej: Counter[str] = Counter()
    fails: Counter[str] = Counter()
    for e in eps:
        rej.update(e.rejected)
        for skill, ok, reason in e.outcomes:
            s = rep.skills.setdefault(skill, {"attempts": 0, "successes": 0})
            s["attempts"] += 1
            s["successes"] += int(ok)
            if not ok:
                fails[f"{skill}: {reason}"] += 1
        if e.error:
            fails[f"sampling: {e.error.split(':')[0]}"] += 1
        st = rep.per_setting.setdefault(e.setting, {"episodes": 0, "successes": 0})
        st["episodes"] += 1
        st["successes"] += int(e.success)
    rep.rejected = dict(rej)
    rep.failures = dict(fails)
    total_s = sum(e.seconds for e in eps)
    rep.seconds_per_episode = total_s / len(eps)
    rep.steps_per_second = sum(e.steps for e in eps) / total_s if total_s > 0 else 0.0
    return rep


def _no_setup() -> None:
    """Trial workers need nothing beyond the pool's own setup (one renderer thread)."""


def _trial_task(task: tuple[Recipe, str | None, int, bool]) -> TrialEpisode:
    return run_trial_episode(*task)


def run_trial(
    recipe: Recipe, recipe_dir: Path | None, n: int, workers: int = 1, observe: bool = True, progress: Any = None
) -> TrialReport:
    """Run episodes 0..n-1 of the train split on `workers` processes (the build's pool)."""
    from echo_data.app.executors import make_executor

    rd = str(recipe_dir) if recipe_dir else None
    pool = make_executor("local", workers, _no_setup, ())
    eps: list[TrialEpisode] = []
    try:
        for e in pool.imap_unordered(_trial_task, [(recipe, rd, i, observe) for i in range(n)]):
            eps.append(e)
            if progress:
                progress(e)
    finally:
        pool.close()
    return summarise(sorted(eps, key=lambda e: e.index))
