"""The recipe: its schema (the sections are in `recipe_sections`), loading (the file reading,
`extends:` included, is in `recipe_yaml`), defaults and content hash.

A recipe is validated completely before any work starts; every problem becomes a
`RecipeError` whose one-line message names the file and the key path.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:
    import numpy as np
from pydantic import Field, ValidationError, field_validator, model_validator

from echo_data.categories import (
    CATEGORIES,
    RELOCATION_CATEGORIES,
    STATE_CATEGORIES,
)

# The sections and the file reader live beside this module; their names that other modules import
# from here stay importable from here.
from echo_data.recipe_sections import (
    AcousticsConfig,
    CameraConfig,
    EventsConfig,
    ExpertsConfig,
    ObjectsConfig,
    OutputsConfig,
    Perturbation,
    RobotConfig,
    SceneConfig,
    SoundsConfig,
    _Strict,
)
from echo_data.recipe_yaml import MAX_EXTENDS_DEPTH, MAX_NESTING, RecipeError, _read_yaml

__all__ = ["AcousticsConfig", "CameraConfig", "ExpertsConfig", "MAX_EXTENDS_DEPTH", "MAX_NESTING", "OutputsConfig", "Perturbation",
           "Recipe", "RecipeError", "RobotConfig", "SETTINGS", "SoundsConfig", "load_recipe", "recipe_from_mapping", "resolve_folder"]

SETTINGS = ("object_relocation", "state_transition", "multi_event")

# Largest split a recipe may ask for: episode ids have six digits, and a plan this size builds
# for months on a workstation (a typo of a few zeros should not start such a build).
MAX_SPLIT_EPISODES = 1_000_000
MAX_NAME_LENGTH = 100  # the name becomes a folder and file names (at most 255 bytes each)


class Recipe(_Strict):
    """A whole, validated recipe."""

    name: str = Field(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$", max_length=MAX_NAME_LENGTH)
    seed: int = Field(0, ge=0)
    splits: dict[str, int] = Field(default_factory=lambda: {"train": 8, "test": 4})
    setting: Literal["object_relocation", "state_transition", "multi_event"] | dict[
        Literal["object_relocation", "state_transition", "multi_event"], float
    ] = "object_relocation"
    # Exact episode counts per setting and split (the STMM-1.9K table); when given, `splits`
    # is derived from it and each episode's setting is fixed by its index (see setting_for).
    composition: dict[
        Literal["object_relocation", "state_transition", "multi_event"], dict[str, int]
    ] | None = None
    max_attempts_per_episode: int = Field(8, ge=1, le=100)
    scene: SceneConfig = SceneConfig()
    objects: ObjectsConfig = ObjectsConfig()
    sounds: SoundsConfig = SoundsConfig()
    events: EventsConfig = EventsConfig()
    robot: RobotConfig = Field(default_factory=RobotConfig)  # made per recipe: its max_steps reads the skill table then
    acoustics: AcousticsConfig = AcousticsConfig()
    outputs: OutputsConfig = OutputsConfig()
    experts: ExpertsConfig = ExpertsConfig()

    @field_validator("splits")
    @classmethod
    def _splits(cls, v: dict[str, int]) -> dict[str, int]:
        if not v:
            raise ValueError("at least one split is required")
        for k, n in v.items():
            if k not in ("train", "test", "val"):
                raise ValueError(f"unknown split {k!r} (use train, val, test)")
            if not isinstance(n, int) or n < 0 or n > MAX_SPLIT_EPISODES:
                raise ValueError(f"split {k!r} must be an integer within [0, {MAX_SPLIT_EPISODES}], got {n}")
        if sum(v.values()) == 0:
            raise ValueError("every split has 0 episodes: nothing to build")
        return v

    @field_validator("composition")
    @classmethod
    def _composition(cls, v: dict[str, dict[str, int]] | None) -> dict[str, dict[str, int]] | None:
        for setting, per_split in (v or {}).items():
            for k, n in per_split.items():
                if k not in ("train", "test", "val"):
                    raise ValueError(f"{setting}: unknown split {k!r} (use train, val, test)")
                if n < 0 or n > MAX_SPLIT_EPISODES:
                    raise ValueError(f"{setting}.{k} must be an integer within [0, {MAX_SPLIT_EPISODES}], got {n}")
        return v

    @field_validator("setting")
    @classmethod
    def _setting(cls, v: Any) -> Any:
        if isinstance(v, dict) and not all(math.isfinite(w) for w in v.values()):
            raise ValueError("setting weights must be finite numbers")
        if isinstance(v, dict) and (any(w < 0 for w in v.values()) or sum(v.values()) <= 0):
            raise ValueError("setting weights must be >= 0 with a positive sum")
        return v

    @model_validator(mode="before")
    @classmethod
    def _derive_splits(cls, data: Any) -> Any:
        if isinstance(data, dict) and isinstance(data.get("composition"), dict):
            totals: dict[str, int] = {}
            for per_split in data["composition"].values():
                if not isinstance(per_split, dict):  # `object_relocation: 5`: the validator names composition.object_relocation
                    return data
                for split, n in per_split.items():
                    if isinstance(n, int) and not isinstance(n, bool) and 0 <= n <= MAX_SPLIT_EPISODES:
                        totals[split] = totals.get(split, 0) + n
                    else:  # let the composition validator name the bad count
                        return data
            if "splits" in data and data["splits"] != totals:
                raise ValueError(f"splits {data['splits']} disagree with composition totals {totals}; give one of them")
            data = {**data, "splits": totals}
        return data

    def setting_for(self, split: str, index: int, rng: np.random.Generator) -> str:
        """The setting of episode `index` of `split`.

        With `composition`, settings are laid out in a fixed interleaved order so that any
        prefix (e.g. `--limit`) keeps the proportions; otherwise drawn from the weights.
        """
        if self.composition:
            counts = {s: c.get(split, 0) for s, c in self.composition.items() if c.get(split, 0) > 0}
            total = sum(counts.values())
            if index >= total:
                raise ValueError(f"index {index} beyond {total} episodes of split {split!r}")
            # Largest-remainder interleave: episode i goes to the setting furthest behind its share.
            done = {s: 0 for s in counts}
            for i in range(index + 1):
                pick = max(counts, key=lambda s: (counts[s] * (i + 1) / total - done[s], -list(counts).index(s)))
                done[pick] += 1
            return pick
        weights = self.setting_weights()
        names = sorted(weights)
        return str(rng.choice(names, p=[weights[n] for n in names]))

    def settings_drawn(self) -> list[str]:
        """The settings an episode of this recipe can have (positive weight or count)."""
        if self.composition:
            return [s for s in SETTINGS if any(n > 0 for n in self.composition.get(s, {}).values())]  # type: ignore[call-overload]
        return [s for s in SETTINGS if s in self.setting_weights()]

    def categories_drawn(self) -> list[str]:
        """The sound categories an event of this recipe can have (drawn setting, positive weight)."""
        drawn = self.settings_drawn()
        pool: list[str] = []
        if {"object_relocation", "multi_event"} & set(drawn):
            pool += [c for c in self.objects.targets if c in RELOCATION_CATEGORIES]
        if {"state_transition", "multi_event"} & set(drawn):
            pool += list(STATE_CATEGORIES)
        return [c for c in CATEGORIES if c in pool and self.events.categories.get(c, 0.0) > 0]

    def setting_weights(self) -> dict[str, float]:
        """The setting mix as normalised weights."""
        if isinstance(self.setting, str):
            return {self.setting: 1.0}
        total = sum(self.setting.values())
        return {k: w / total for k, w in self.setting.items() if w > 0}

    def content_hash(self) -> str:
        """sha256 of the canonical JSON of the resolved recipe."""
        data = self.model_dump(mode="json")
        if data["outputs"]["max_frames"] is None:  # whole episodes: the hash recipes had before the key existed
            del data["outputs"]["max_frames"]
        if data["experts"] == ExpertsConfig().model_dump(mode="json"):  # noiseless experts: as before the key existed
            del data["experts"]
        if data["robot"]["grasp"] == "physical":  # the physical grasp: as before the key existed
            del data["robot"]["grasp"]
        if not data["sounds"]["fresh_train_instances"]:  # library voices only: as before the key existed
            del data["sounds"]["fresh_train_instances"]
        if data["robot"]["action_space"] == "joint":  # the env's default action form: as before the key existed
            del data["robot"]["action_space"]
        blob = json.dumps(data, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(blob.encode()).hexdigest()


def _loc(loc: tuple[Any, ...]) -> str:
    parts = [str(p) for p in loc if not str(p).startswith(("function-", "literal[", "dict[", "tuple["))]
    # pydantic reports union branches by type name; keep only the real path.
    return ".".join(p for p in parts if p not in ("str", "int", "float", "list", "dict")) or "<root>"


def recipe_from_mapping(data: dict[str, Any], source: str = "<recipe>") -> Recipe:
    """Validate a mapping; raise a one-line `RecipeError` naming `source` and the key."""
    try:
        recipe = Recipe.model_validate(data)
    except ValidationError as e:
        errors = e.errors()
        # Of a union's branch errors (e.g. `setting` as a name or as weights) the deepest says most.
        err = max((x for x in errors if x["loc"][:1] == errors[0]["loc"][:1]), key=lambda x: len(x["loc"]))
        key = _loc(tuple(err["loc"]))
        msg = err["msg"].removeprefix("Value error, ")
        if err["type"] == "extra_forbidden":
            msg = "unknown key"
        elif err["type"] == "missing":
            msg = "required key is missing"
        more = f" (+{len(e.errors()) - 1} more)" if len(e.errors()) > 1 else ""
        raise RecipeError(f"{source}: {key}: {msg}{more}") from None
    _check_sound_folders(recipe, source)
    _check_draws(recipe, source)
    return recipe


def _check_draws(recipe: Recipe, source: str) -> None:
    """Weights that leave a drawn setting nothing to draw: refused, never replaced by a uniform
    draw (a category given weight 0 must never appear in an episode)."""
    weights = recipe.events.categories
    for setting in recipe.settings_drawn():
        if setting in ("object_relocation", "multi_event"):
            targets = [c for c in recipe.objects.targets if c in RELOCATION_CATEGORIES]
            if not targets:
                raise RecipeError(f"{source}: objects.targets: empty, but setting {setting} draws a sounding object")
            if not any(weights.get(c, 0.0) > 0 for c in targets):
                raise RecipeError(
                    f"{source}: events.categories.{targets[0]}: every target of objects.targets ({', '.join(targets)}) "
                    f"has weight 0, but setting {setting} draws one of them"
                )
        if setting in ("state_transition", "multi_event") and not any(weights.get(c, 0.0) > 0 for c in STATE_CATEGORIES):
            raise RecipeError(
                f"{source}: events.categories.{STATE_CATEGORIES[0]}: {' and '.join(STATE_CATEGORIES)} have weight 0, "
                f"but setting {setting} draws one of them"
            )


def _check_sound_folders(recipe: Recipe, source: str) -> None:
    base = Path(source).parent if source != "<recipe>" else Path.cwd()
    for cat, folder in recipe.sounds.folders.items():
        p = (base / folder) if not Path(folder).is_absolute() else Path(folder)
        if not p.is_dir():
            raise RecipeError(f"{source}: sounds.folders.{cat}: not a readable folder: {folder}")
    if recipe.sounds.fresh_train_instances and not recipe.sounds.builtin:
        raise RecipeError(f"{source}: sounds.fresh_train_instances: needs builtin: true (fresh instances come from the built-in synthesiser)")
    if not recipe.sounds.builtin and not recipe.sounds.folders:
        raise RecipeError(f"{source}: sounds: builtin is false and no folders are given")


def load_recipe(path: str | Path) -> Recipe:
    """Load, resolve `extends:`, validate. Raises `RecipeError` with a one-line message."""
    p = Path(path)
    data = _read_yaml(p)
    recipe = recipe_from_mapping(data, str(p))
    return recipe


def resolve_folder(recipe_path: str | Path, folder: str) -> Path:
    """A sound folder path as given in a recipe, resolved against the recipe's directory."""
    f = Path(folder)
    return f if f.is_absolute() else (Path(recipe_path).resolve().parent / f)
