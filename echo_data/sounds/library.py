"""The sound library: which instances exist, their splits, and their dry looped waveforms.

The built-in instances are synthesised (`synth`); a recipe may add folders of the user's own
files per category (`user_folders`). Train and test instances are disjoint by id, so a sampler
that draws train episodes from `instances(split="train")` never plays a test sound. With
`sounds.fresh_train_instances` a train episode plays fresh synthesised instances instead of the
built-in train ones (`get` resolves their ids; they are train instances by construction).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from echo_data.categories import CATEGORY_COUNTS
from echo_data.sounds import synth
from echo_data.sounds.dsp import peak_normalise
from echo_data.sounds.user_folders import (
    AUDIO_SUFFIXES,
    SoundLibraryError,
    audio_files,
    check_samples,
    crossfade_loop,
    file_duration,
    read_mono,
    slug,
    split_files,
)

if TYPE_CHECKING:
    from echo_data.recipe import Recipe

CATEGORIES: tuple[str, ...] = tuple(CATEGORY_COUNTS)
SPLITS: tuple[str, ...] = ("train", "test")
ONSET_FADE_S = 0.005  # raised-cosine fade-in when a sound starts, so an event never clicks on


@dataclass(frozen=True)
class SoundInstance:
    """One sound: `duration` is one loop period (built-in) or the file's length; `source` is "builtin" or a path."""

    id: str
    category: str
    split: str
    duration: float
    source: str

    @property
    def builtin(self) -> bool:
        return self.source == "builtin"


class SoundLibrary:
    """An ordered, immutable set of sound instances with cached dry loops."""

    def __init__(self, instances: list[SoundInstance] | tuple[SoundInstance, ...]) -> None:
        self._instances = tuple(instances)
        self._by_id = {s.id: s for s in self._instances}
        if len(self._by_id) != len(self._instances):
            raise SoundLibraryError("duplicate sound instance ids")

    @classmethod
    def builtin(cls) -> SoundLibrary:
        """The 113 synthesised instances (the paper's counts, `echo_data.categories.CATEGORY_COUNTS`)."""
        return cls(_builtin_instances())

    @classmethod
    def from_recipe(cls, recipe: Recipe, recipe_dir: Path | None = None) -> SoundLibrary:
        """Built-ins if `recipe.sounds.builtin`, plus each user folder (relative to `recipe_dir`, default cwd)."""
        cfg = recipe.sounds
        out: list[SoundInstance] = list(_builtin_instances()) if cfg.builtin else []
        base = Path(recipe_dir) if recipe_dir is not None else Path.cwd()
        for cat in CATEGORIES:  # fixed category order keeps ids and order stable
            if cat in cfg.folders:
                folder = Path(cfg.folders[cat])
                out += folder_instances(cat, folder if folder.is_absolute() else base / folder, cfg.folder_test_fraction)
        return cls(out)

    def check_covers(self, recipe: Recipe) -> None:
        """Every category `recipe` can draw has a sound for every split it has (val plays train
        sounds), or `SoundLibraryError`: the build and `evaluate` ask before the first episode,
        so a folder of one file is bad input, not an episode that can never be sampled."""
        needed = sorted({"test" if s == "test" else "train" for s, n in recipe.splits.items() if n > 0}, key=SPLITS.index)
        for cat in recipe.categories_drawn():
            for split in needed:
                if self.instances(cat, split):
                    continue
                folder = recipe.sounds.folders.get(cat)  # type: ignore[call-overload]
                if folder is None:
                    raise SoundLibraryError(f"sounds: category {cat} has no sounds (builtin is false and sounds.folders names no {cat} folder)")
                n = len(self.instances(cat))
                raise SoundLibraryError(
                    f"sounds.folders.{cat}: {folder} holds {n} file{'s' if n != 1 else ''}, which leaves no {split} sound for the "
                    f"{'test' if split == 'test' else 'train/val'} split (give at least 2 files, or set sounds.builtin: true)"
                )

    def __len__(self) -> int:
        return len(self._instances)

    def __iter__(self) -> Iterator[SoundInstance]:
        return iter(self._instances)

    def __contains__(self, instance_id: object) -> bool:
        return instance_id in self._by_id

    def instances(self, category: str | None = None, split: str | None = None) -> list[SoundInstance]:
        """Instances in library order, optionally filtered by category and/or split."""
        if category is not None and category not in CATEGORIES:
            raise ValueError(f"unknown sound category {category!r} (use one of {', '.join(CATEGORIES)})")
        if split is not None and split not in SPLITS:
            raise ValueError(f"unknown sound split {split!r} (use train or test)")
        return [s for s in self._instances if (category is None or s.category == category) and (split is None or s.split == split)]

    def get(self, instance_id: str) -> SoundInstance:
        """The instance of an id; a fresh synthesised training instance (`synth.fresh_id`) is made
        from its id alone, in any library that holds the built-in synthesiser's instances."""
        try:
            return self._by_id[instance_id]
        except KeyError:
            if synth.is_fresh_id(instance_id) and any(s.builtin for s in self._instances):
                return fresh_instance(instance_id)
            raise KeyError(f"unknown sound instance id {instance_id!r}") from None

    def waveform(self, instance_id: str, sample_rate: int = 16000, seconds: float | None = None) -> np.ndarray:
        """Dry mono float32 in [-1, 1] at `sample_rate`.

        `seconds=None`: exactly one loop period (tile it to loop). Otherwise the loop repeated to
        round(seconds * sample_rate) samples with a 5 ms fade-in at the onset; repeats join without
        a click. Same bytes for the same (id, sample_rate, seconds) in any process.
        """
        inst = self.get(instance_id)
        if int(sample_rate) != sample_rate or sample_rate < 1000:
            raise ValueError(f"sample_rate must be an integer >= 1000, got {sample_rate}")
        base = _base_loop(inst, int(sample_rate))
        if seconds is None:
            return base.copy()
        if seconds <= 0:
            raise ValueError(f"seconds must be > 0, got {seconds}")
        out = np.resize(base, int(round(seconds * sample_rate)))  # cyclic repetition of the loop
        fade = min(len(out), int(ONSET_FADE_S * sample_rate))
        if fade > 0:
            out[:fade] *= (0.5 - 0.5 * np.cos(np.pi * np.arange(fade) / fade)).astype(np.float32)
        return out


@lru_cache(maxsize=1)
def _builtin_instances() -> tuple[SoundInstance, ...]:
    out = []
    for iid in synth.builtin_ids():
        cat, split, _ = synth.parse_builtin_id(iid)
        out.append(SoundInstance(iid, cat, split, synth.design(iid)["duration"], "builtin"))
    return tuple(out)


def fresh_instance(instance_id: str) -> SoundInstance:
    """A fresh training instance of the synthesiser (`synth.fresh_id`), never one of the 113."""
    cat, split, _ = synth.parse_builtin_id(instance_id)
    return SoundInstance(instance_id, cat, split, synth.design(instance_id)["duration"], "builtin")


def folder_instances(category: str, folder: Path, test_fraction: float) -> list[SoundInstance]:
    """Instances for the user's files of one category, ids "<category>-<split>-file-<name>"."""
    files = audio_files(folder)
    if not files:
        raise SoundLibraryError(f"{folder}: no audio files ({', '.join(AUDIO_SUFFIXES)}) for category {category}")
    splits = split_files(files, test_fraction)
    out, used = [], set()
    for p in files:  # sorted by name: stable order
        base = f"{category}-{splits[p]}-file-{slug(p.stem)}"
        iid, i = base, 2
        while iid in used:
            iid, i = f"{base}-{i}", i + 1
        used.add(iid)
        duration = file_duration(p)
        check_samples(p)
        out.append(SoundInstance(iid, category, splits[p], round(duration, 4), str(p)))
    return out


@lru_cache(maxsize=256)
def _base_loop(inst: SoundInstance, sr: int) -> np.ndarray:
    """The dry loop period of an instance at `sr` (read-only; cached per process)."""
    if inst.builtin:
        x = synth.render(inst.id, sr)
    else:
        x = crossfade_loop(read_mono(Path(inst.source), sr), sr)
        x = peak_normalise(x, synth.PEAK_DBFS[inst.category]).astype(np.float32)
    x.setflags(write=False)
    return x
