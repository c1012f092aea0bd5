"""Reference learners: trained weights shipped with the package, so a row of the paper table is
reproduced with no training (`echo-data evaluate RECIPE --policy reference --planner reference`).

The reference set is a folder (the package's `echo_data/reference/`, or `$ECHO_DATA_REFERENCE`):

  manifest.json          {"format", "learners": {NAME: {...}}, "skills": {SKILL: [NAME, ...]}, "planner": NAME | null}
                         (a skill is served by one learner per training seed of one command:
                         `--policy reference` shares the episodes out over them, evaluation.seeds)
  NAME/
    weights.safetensors  the run's best weights: fp16 where the round trip leaves every action of
                         the check (its dataset's steps) within FP16_TOLERANCE std, fp32 elsewhere
    config.json          the run's config.json (algorithm, inputs, skill, normalisation...), the
                         dataset named by its folder name, not a path of the machine it ran on
    policy.json          the run's kind and class; agent.json: how `evaluate` constructs it
    recipe.yaml          the recipe of the dataset it was trained on
    SHA256SUMS           `sha256  file` of every file above (checked at every load)

A learner folder is also a checkpoint folder. `--policy reference` drives each skill by the learner
serving it, `--policy SKILL=reference:NAME` by a listed variant (a row's magic-grasp Pick, say).
`echo-data reference add RUN --name NAME` makes one from a training run folder.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.reader import is_dataset, read_manifest
from echo_data.dataset.storage import atomic_write_bytes, canonical_json
from echo_data.learn import runs

FORMAT = "echo-data-reference/1"
ENV = "ECHO_DATA_REFERENCE"  # a reference set elsewhere than the package's (tests, a user's own)
PACKAGE_DIR = Path(__file__).resolve().parents[1] / "reference"
MANIFEST = "manifest.json"
SUMS = "SHA256SUMS"
RECIPE = "recipe.yaml"
NAME = "reference"  # the name `--policy` / `--planner` take: the serving learner; `reference:LEARNER` a listed one
BUDGET_BYTES = 30 * 2**20  # every shipped weights file together (issue 45)
# Largest change of any action entry an fp16 round trip may cause on the check's steps, in units
# of that entry's standard deviation in the training actions (a planner: of its logits, and no
# plan may change): far below what a learner's own error is. A binary entry that flips or a
# STOP that moves changes by two std or more, and keeps its tensors in fp32.
FP16_TOLERANCE = 1e-2
CHECK_STEPS = 200  # dataset steps the fp16 check acts on
COPIED = (runs.POLICY, runs.AGENT)


class ReferenceError(ValueError):
    """A reference set or learner that cannot be used as asked (one line, names the file or skill)."""


def reference_dir() -> Path:
    """The reference set in use: `$ECHO_DATA_REFERENCE` when set, else the package's."""
    env = os.environ.get(ENV)
    return Path(env) if env else PACKAGE_DIR


@dataclass
class ReferenceSet:
    """A reference set's manifest: which learner serves which skill, and the planner."""

    root: Path
    learners: dict[str, dict[str, Any]] = field(default_factory=dict)
    skills: dict[str, list[str]] = field(default_factory=dict)  # skill -> its serving learners, one per training seed
    planner: str | None = None

    @classmethod
    def load(cls, root: Path | None = None) -> ReferenceSet:
        root = reference_dir() if root is None else Path(root)
        path = root / MANIFEST
        if not path.is_file():
            return cls(root)  # no set yet: every skill unserved
        try:
            doc = json.loads(path.read_text())
            if doc.get("format") != FORMAT:
                raise ReferenceError(f"{path}: format {doc.get('format')!r} is not {FORMAT}")
            learners, planner = dict(doc["learners"]), doc["planner"]
            skills = {k: [v] if isinstance(v, str) else [str(n) for n in v] for k, v in dict(doc["skills"]).items()}
        except (ValueError, KeyError, TypeError, AttributeError) as e:
            raise ReferenceError(f"{path}: not a reference manifest ({type(e).__name__}: {e})".splitlines()[0]) from None
        if any(not names for names in skills.values()):
            raise ReferenceError(f"{path}: skills: a skill served by no learner")
        for served in [*(n for names in skills.values() for n in names), *([planner] if planner else [])]:
            if served not in learners:
                raise ReferenceError(f"{path}: serves {served!r}, which learners does not list")
        return cls(root, learners, skills, planner)

    def to_dict(self) -> dict[str, Any]:
        return {"format": FORMAT, "learners": self.learners, "skills": self.skills, "planner": self.planner}

    def learner(self, skill: str | None, name: str | None = None) -> Path:
        """The checked folder of learner `name`, which must act as `skill` (None: the planner);
        without a name, the one serving `skill` (its first training seed)."""
        what = "planner" if skill is None else f"learner for skill {skill}"
        if name is None:
            name = self.planner if skill is None else next(iter(self.served(skill)), None)
            if name is None:
                raise ReferenceError(f"the reference set {self.root / MANIFEST} ships no {what} (echo-data reference add RUN --name NAME adds one)")
        elif name not in self.learners:
            raise ReferenceError(f"the reference set {self.root / MANIFEST} has no learner {name!r} ({', '.join(sorted(self.learners)) or 'none'})")
        elif name not in self.of(skill):
            raise ReferenceError(f"{self.root / MANIFEST}: learner {name!r} is not a {what}")
        folder = self.root / name
        verify(folder)
        return folder

    def of(self, skill: str | None) -> list[str]:
        """Every listed learner that acts as `skill` (None: every planner), served or not."""
        return [n for n, e in self.learners.items() if (e.get("kind") == "planner" if skill is None else e.get("skill") == skill)]

    def served(self, skill: str) -> list[str]:
        """The learners serving `skill`, one per training seed ([] if unserved)."""
        return list(self.skills.get(skill, []))

    def weights_sha256(self, skill: str | None) -> str | None:
        """The SHA-256 of the weights serving `skill` (None: the planner; a skill served by several
        seeds: the first's); None if unserved."""
        name = self.planner if skill is None else next(iter(self.served(skill)), None)
        return None if name is None else str(self.learners[name]["weights_sha256"])

    def shipped(self, skill: str | None) -> set[str]:
        """The SHA-256 of every shipped learner's weights for `skill` (None: the planners): a
        row's variant (a magic-grasp Pick, a starred Place) is shipped without serving its skill."""
        return {str(self.learners[n]["weights_sha256"]) for n in self.of(skill)}


def _check_seed_of(refs: ReferenceSet, skill: str, name: str, entry: Mapping[str, Any]) -> None:
    """A learner joining `skill`'s seeds is the same command: the same algorithm, inputs and
    training dataset as the learners serving it."""
    for other in refs.served(skill):
        if other == name:
            continue
        have = refs.learners[other]
        for key in ("algo", "inputs", "dataset"):
            if have.get(key) != entry.get(key):
                raise ReferenceError(f"--join: {name}'s {key} {entry.get(key)!r} differs from {other}'s {have.get(key)!r}: "
                                     f"the seeds serving {skill} are trainings of one command")


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def verify(folder: Path) -> None:
    """Every file SHA256SUMS lists is there with its recorded hash: the weights evaluated are
    the weights shipped."""
    sums = folder / SUMS
    try:
        lines = sums.read_text().splitlines()
    except OSError:
        raise ReferenceError(f"{sums}: missing (not a reference learner folder)") from None
    for line in lines:
        want, _, name = line.partition("  ")
        try:
            got = _sha256((folder / name).read_bytes())
        except OSError:
            raise ReferenceError(f"{folder / name}: missing (listed in {sums})") from None
        if got != want:
            raise ReferenceError(f"{folder / name}: SHA-256 {got[:12]} is not the {want[:12]} {sums} records")


def shipped_bytes(root: Path | None = None) -> int:
    """Bytes of the weights files of every learner the set's manifest lists (the budget is BUDGET_BYTES)."""
    refs = ReferenceSet.load(root)
    return sum((refs.root / name / runs.WEIGHTS).stat().st_size for name in refs.learners if (refs.root / name / runs.WEIGHTS).is_file())


# --- making a reference learner from a run folder ---------------------------------------------

def _portable(obj: Any) -> Any:
    """The config without this machine's paths: an absolute path becomes its last name."""
    if isinstance(obj, dict):
        return {k: _portable(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_portable(v) for v in obj]
    if isinstance(obj, str) and os.path.isabs(obj) and os.sep in obj:
        return Path(obj).name
    return obj


@dataclass
class Probe:
    """A run's model and `act(state_dict)`: load those weights and return (every output on the
    check's observations, the decisions taken from them, each output column's scale)."""

    model: Any
    act: Callable[[Mapping[str, Any]], tuple[np.ndarray, Any]]
    scale: np.ndarray
    unit: str  # what the outputs are, for the report


def _probe(run: Path, kind: str, dataset: Path) -> Probe:
    import torch

    if kind == "planner":
        from echo_data.learn.planner import decode, load_episodes
        from echo_data.learn.policy import PlannerModel

        planner = PlannerModel.from_run(run)
        ep = load_episodes(dataset, _splits(dataset)[0], planner.spec)

        def plans(state: Mapping[str, Any]) -> tuple[np.ndarray, Any]:
            planner.model.load_state_dict(state)
            with torch.no_grad():
                logits, scores = planner.model(ep.inputs)
            out = np.concatenate([logits.numpy().reshape(len(ep.events), -1), scores.numpy().reshape(len(ep.events), -1)], axis=1)
            return out.astype(np.float64), [decode(logits[n].numpy(), scores[n].numpy(), planner.categories, planner.sets, planner.priority)
                                             for n in range(len(ep.events))]

        return Probe(planner.model, plans, np.ones(1), f"logits of the first frames of {len(ep.events)} episodes")

    from echo_data.learn.policy import SkillPolicy

    policy = SkillPolicy.from_run(run)
    steps = _skill_steps(dataset, policy.skill)

    def actions(state: Mapping[str, Any]) -> tuple[np.ndarray, Any]:
        policy.model.load_state_dict(state)
        out, segment = [], None
        for key, obs in steps:
            if key != segment:
                policy.reset({})
                segment = key
            a = policy.act(obs)
            out.append(np.full(policy.action_dim, np.inf, np.float32) if a is None else a)  # a STOP that moves changes by inf
        return np.stack(out).astype(np.float64), None

    spread = np.maximum(np.abs(policy.std[: policy.action_dim]).astype(np.float64), 1e-6)
    return Probe(policy.model, actions, spread, f"actions of {len(steps)} dataset steps, in units of the training actions' std")


def _splits(dataset: Path) -> list[str]:
    """The splits the check reads, in order: test (never trained on) first."""
    splits = read_manifest(dataset).get("splits", {})
    return [s for s in ("test", "val", "train") if splits.get(s)]


def _skill_steps(dataset: Path, skill: str) -> list[tuple[tuple[str, int, int], dict[str, Any]]]:
    """Up to CHECK_STEPS steps of `skill`'s segments, the test split's first, keyed by (split,
    episode, skill index); a run that reads the target position gets the segment's last base pose
    as its goal, as in training."""
    from echo_data.dataset.schema import STATE
    from echo_data.dataset.torch import StepDataset
    from echo_data.records import GOAL_POSE

    items: list[tuple[tuple[str, int, int], dict[str, Any]]] = []
    for split in _splits(dataset):
        data = StepDataset(dataset, split, skill=skill)
        for i in range(min(len(data), CHECK_STEPS - len(items))):
            it = data[i]
            items.append(((split, int(it["episode_index"]), int(it["skill_index"])), it))
    goal = {k: np.asarray(it[STATE])[:3] for k, it in items}  # the last step of each segment wins
    steps = [(k, {**{c: v for c, v in it.items() if c.startswith("observation.")}, GOAL_POSE: goal[k]}) for k, it in items]
    if not steps:
        raise ReferenceError(f"{dataset}: holds no {skill} step to check the fp16 weights on")
    return steps


def fp16_weights(run: Path, kind: str, dataset: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """(the tensors to store, the check's report): each floating tensor in fp16 unless its round
    trip moves an output of the learner by more than FP16_TOLERANCE of its scale on the dataset's
    steps (a planner: or changes a plan); those stay fp32, the largest effects first, until the
    whole set is within it."""
    probe = _probe(run, kind, dataset)
    full = {k: v.detach().clone() for k, v in probe.model.state_dict().items()}
    ref, decided = probe.act(full)

    def rounded(keys: set[str]) -> dict[str, Any]:
        return {k: v.half().float() if k in keys else v for k, v in full.items()}

    def change(state: dict[str, Any]) -> tuple[float, float]:
        """(largest change in units of the scale, in the outputs' own units)."""
        out, plans = probe.act(state)
        if plans != decided or out.shape != ref.shape:
            return float("inf"), float("inf")
        d = np.abs(np.where(out == ref, 0.0, out - ref))  # inf == inf: the same STOP
        return float((d / probe.scale).max(initial=0.0)), float(d.max(initial=0.0))

    floats = {k for k, v in full.items() if v.is_floating_point()}
    half = set(floats)
    diff = change(rounded(half))
    if diff[0] > FP16_TOLERANCE:
        for k in sorted(floats, key=lambda k: change(rounded({k}))[0], reverse=True):
            half.discard(k)
            diff = change(rounded(half))
            if diff[0] <= FP16_TOLERANCE:
                break
    stored = {k: (v.half() if k in half else v).contiguous() for k, v in full.items()}
    name = "max_output_difference" if kind == "planner" else "max_action_difference"
    report = {"on": probe.unit, name: diff[1], "max_relative_difference": diff[0], "tolerance": FP16_TOLERANCE,
              "fp32_tensors": sorted(floats - half), "fp16_tensors": len(half)}
    return stored, report


def add(run: Path, name: str, root: Path | None = None, dataset: Path | None = None, overwrite: bool = False, serve: bool = True,
        join: bool = False) -> dict[str, Any]:
    """Make reference learner `name` from the run folder `run` (its best weights) in the set at
    `root` and, with `serve`, let it serve its skill (or be the planner; else it is a variant,
    `reference:NAME`); `join`: it serves its skill beside the learners already serving it (another
    training seed of their command) instead of replacing them; returns its manifest entry. The folder is written beside and renamed in,
    then the manifest: a failure leaves the set as it was."""
    import yaml
    from safetensors.torch import save

    root = reference_dir() if root is None else Path(root)
    if not name or any(c in name for c in "/\\:") or name.startswith(".") or name != name.strip():
        raise ReferenceError(f"--name {name!r}: a plain folder name (no '/', '\\' or ':', which `reference:NAME` reads)")
    refs = ReferenceSet.load(root)
    target = root / name
    if target.exists() and not (overwrite and name in refs.learners):
        raise ReferenceError(f"{target}: exists; pass --overwrite to replace the reference learner {name}" if name in refs.learners
                             else f"{target}: exists and is no reference learner of {root / MANIFEST}")
    policy = runs.read_json(run / runs.POLICY)
    kind = policy.get("kind")
    if kind not in ("policy", "planner"):
        raise ReferenceError(f"{run / runs.POLICY}: kind {kind!r} is neither a skill policy nor a planner")
    config = runs.read_json(run / runs.CONFIG)
    data = Path(config["dataset"]) if dataset is None else dataset
    if not is_dataset(data):
        raise ReferenceError(f"{data}: not the dataset {run} was trained on (no manifest.json); give it with --data")
    recipe = read_manifest(data)["recipe"]
    stored, report = fp16_weights(run, kind, data)
    files = {runs.WEIGHTS: save(stored, metadata={"format": FORMAT}),
             runs.CONFIG: canonical_json(_portable(config)),
             RECIPE: yaml.safe_dump(recipe, sort_keys=False).encode(),
             **{f: (run / f).read_bytes() for f in COPIED}}
    files[SUMS] = "".join(f"{_sha256(b)}  {f}\n" for f, b in sorted(files.items())).encode()
    skill = config.get("skill") if kind == "policy" else None
    entry = {"kind": kind, "skill": skill, "algo": config.get("algo"), "inputs": config.get("inputs"), "dataset": Path(data).name,
             "weights_sha256": _sha256(files[runs.WEIGHTS]), "bytes": len(files[runs.WEIGHTS]), "fp16_check": report}
    others = shipped_bytes(root) - ((target / runs.WEIGHTS).stat().st_size if (target / runs.WEIGHTS).is_file() else 0)
    if others + entry["bytes"] > BUDGET_BYTES:
        raise ReferenceError(f"{name}: {entry['bytes'] / 2**20:.1f} MB of weights would take the set past its {BUDGET_BYTES // 2**20} MB budget "
                             f"({others / 2**20:.1f} MB shipped)")
    if join and (kind != "policy" or not serve):
        raise ReferenceError(f"--join: only a skill learner that serves its skill joins the seeds serving it ({name} is {'a variant' if serve is False else kind})")
    if join:
        _check_seed_of(refs, str(skill), name, entry)
    root.mkdir(parents=True, exist_ok=True)
    tmp = root / f".{name}.partial"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    for f, b in files.items():
        (tmp / f).write_bytes(b)
    old = root / f".{name}.old"
    if target.exists():
        shutil.rmtree(old, ignore_errors=True)
        target.rename(old)
    tmp.rename(target)
    shutil.rmtree(old, ignore_errors=True)
    refs.skills = {k: [n for n in v if n != name] for k, v in refs.skills.items()}  # a replaced learner serves only what it now is
    refs.skills = {k: v for k, v in refs.skills.items() if v}
    refs.planner = None if refs.planner == name else refs.planner
    refs.learners[name] = entry
    if serve and kind == "planner":
        refs.planner = name
    elif serve:
        refs.skills[str(skill)] = [*(refs.served(str(skill)) if join else []), name]
    atomic_write_bytes(root / MANIFEST, canonical_json(refs.to_dict()))
    return {"name": name, **entry}
