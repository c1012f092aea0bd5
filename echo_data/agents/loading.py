"""Load an agent by name: a built-in, `module:Class`, or a checkpoint folder.

A checkpoint folder holds `agent.json`: {"class": "module:Class", "kwargs": {...}}; the class is
constructed as `Class(checkpoint=<folder>, **kwargs)` so it can read its weights from there.
Every failure is an `AgentLoadError` whose message is one line naming what was asked for.
"""

from __future__ import annotations

import importlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from echo_data.agents.builtin import BUILTIN_PLANNERS, BUILTIN_POLICIES
from echo_data.protocols import Planner, Policy

CHECKPOINT_FILE = "agent.json"


class AgentLoadError(ValueError):
    """An agent that cannot be loaded (unknown name, import error, bad checkpoint)."""


def _one_line(e: BaseException) -> str:
    return " ".join(f"{type(e).__name__}: {e}".split())


def _import(target: str, what: str) -> Any:
    module, _, cls = target.partition(":")
    if not module or not cls:
        raise AgentLoadError(f"{what} {target!r}: expected module:Class")
    try:
        obj = importlib.import_module(module)
        for part in cls.split("."):
            obj = getattr(obj, part)
    except Exception as e:  # any import-time failure of user code is reported, not raised through
        raise AgentLoadError(f"{what} {target!r}: cannot import ({_one_line(e)})") from None
    return obj


def _construct(cls: Any, what: str, target: str, **kwargs: Any) -> Any:
    try:
        return cls(**kwargs)
    except Exception as e:
        raise AgentLoadError(f"{what} {target!r}: constructor failed ({_one_line(e)})") from None


def _load(target: str, builtins: dict[str, Any], what: str, methods: tuple[str, ...]) -> Any:
    if target in builtins:
        agent = builtins[target]()
    elif Path(target).is_dir():
        f = Path(target) / CHECKPOINT_FILE
        try:
            meta = json.loads(f.read_text())
            cls_name, kwargs = meta["class"], dict(meta.get("kwargs", {}))
        except FileNotFoundError:
            raise AgentLoadError(f"{what} {target}: checkpoint folder has no {CHECKPOINT_FILE}") from None
        except (ValueError, KeyError, TypeError, AttributeError) as e:
            raise AgentLoadError(f"{f}: not a checkpoint description ({_one_line(e)})") from None
        agent = _construct(_import(cls_name, f"{f}: class"), what, target, checkpoint=Path(target), **kwargs)
    elif ":" in target:
        agent = _construct(_import(target, what), what, target)
    else:
        known = ", ".join(sorted(builtins))
        raise AgentLoadError(f"{what} {target!r}: not a built-in ({known}), a module:Class or a checkpoint folder")
    missing = [m for m in methods if not callable(getattr(agent, m, None))]
    if missing:
        raise AgentLoadError(f"{what} {target!r}: has no {', '.join(missing)}() method")
    check_observations(agent, f"{what} {target!r}")
    return agent


def check_observations(agent: Any, name: str, known: Sequence[str] | None = None) -> None:
    """An agent's `observations` (what the environment must render for it): absent/None, or a
    tuple or list of observation keys, each in `known` when given; else `AgentLoadError` naming
    the agent and the key, before any episode runs."""
    keys = getattr(agent, "observations", None)
    if keys is None:
        return
    if not isinstance(keys, (tuple, list)):
        raise AgentLoadError(f"{name}: observations must be a tuple of observation keys, got {type(keys).__name__} {keys!r}"[:300])
    for k in keys:
        if not isinstance(k, str) or not k.startswith("observation."):
            raise AgentLoadError(f"{name}: observations: {k!r} is not an observation key (observation.*)"[:300])
        if known is not None and k not in known:
            raise AgentLoadError(f"{name}: observations: {k!r} is not an observation of this recipe ({', '.join(sorted(known))})")


def load_policy(target: str | Sequence[str]) -> Policy:
    """A low-level skill policy: `reset(info)`, `act(obs) -> action | None`.

    A list of specs (`["Navigate=runs/nav", "oracle"]`) gives one policy per skill
    (`echo_data.agents.compose`)."""
    from echo_data.agents.compose import PolicySpecError, SkillDispatch, is_composite, parse_specs
    from echo_data.learn.reference import NAME as REFERENCE

    one = target if isinstance(target, str) else target[0]
    if not is_composite(target) and one != REFERENCE:
        if one.startswith(REFERENCE + ":"):
            raise AgentLoadError(f"--policy {one}: a reference learner drives its own skill: give SKILL={one}")
        return _load(one, BUILTIN_POLICIES, "policy", ("reset", "act"))
    try:
        by_skill, fallback = parse_specs([target] if isinstance(target, str) else target)
    except PolicySpecError as e:
        raise AgentLoadError(str(e)) from None
    if fallback == REFERENCE:  # every skill not named: its shipped learner
        from echo_data.skills import EXPERTS

        by_skill = {**{s: REFERENCE for s in EXPERTS}, **by_skill}
    loaded: dict[str, Any] = {}  # one instance per distinct target (a reference learner: per skill)

    def get(t: str, skill: str) -> Any:
        shipped = t == REFERENCE or t.startswith(REFERENCE + ":")
        key = f"{t}@{skill}" if shipped else t
        if key not in loaded:
            loaded[key] = _reference(skill, t) if shipped else _load(t, BUILTIN_POLICIES, "policy", ("reset", "act"))
        return loaded[key]

    agents = {s: get(t, s) for s, t in by_skill.items()}
    rest = next(iter(agents.values())) if fallback == REFERENCE else get(fallback, "*")  # reference: every skill is named, the fallback never asked
    return SkillDispatch(agents, rest, {**by_skill, "*": fallback})


def _reference(skill: str | None, target: str) -> Any:
    """The shipped reference learner `target` names for `skill` (None: the planner): `reference`,
    the one serving it, or `reference:NAME`; checked against its SHA256SUMS."""
    from echo_data.learn.reference import ReferenceError, ReferenceSet

    try:
        folder = ReferenceSet.load().learner(skill, target.partition(":")[2] or None)
    except ReferenceError as e:
        raise AgentLoadError(f"{'--planner' if skill is None else '--policy'} {target}: {e}") from None
    what = "planner" if skill is None else "policy"
    agent = _load(str(folder), BUILTIN_PLANNERS if skill is None else BUILTIN_POLICIES, what, ("plan",) if skill is None else ("reset", "act"))
    agent.reference = folder.name  # `identity` names the learner, not the folder of this machine
    return agent


def load_planner(target: str) -> Planner:
    """A high-level planner: `plan(first_obs) -> [{"skill": ..., "target": ...}, ...]` (optional `reset(info)`);
    `reference`: the shipped one, `reference:NAME` a listed one (echo_data.learn.reference)."""
    from echo_data.learn.reference import NAME as REFERENCE

    shipped = target == REFERENCE or target.startswith(REFERENCE + ":")
    return _reference(None, target) if shipped else _load(target, BUILTIN_PLANNERS, "planner", ("plan",))


def identity(agent: Any, target: str | Sequence[str]) -> dict[str, Any]:
    """What was evaluated, for the results file: the name asked for, the class, its version if any
    (per skill for a composition)."""
    from echo_data.agents.compose import SkillDispatch, spec_name

    if isinstance(agent, SkillDispatch):
        skills = {s: identity(agent.policy_for(s) if s != "*" else agent.fallback, t) for s, t in agent.names.items()}
        return {"name": spec_name(target), "class": "echo_data.agents.compose:SkillDispatch", "skills": skills}
    if not isinstance(target, str):
        target = target[0]
    cls = type(agent)
    out: dict[str, Any] = {"name": target, "class": f"{cls.__module__}:{cls.__qualname__}"}
    reference = getattr(agent, "reference", None)
    for attr in ("version", "reference") if reference is not None else ("version", "checkpoint"):
        v = getattr(agent, attr, None)
        if v is not None:
            out[attr] = str(v)
    if getattr(agent, "weights_sha256", None) is not None:
        out["weights_sha256"] = agent.weights_sha256  # the weights file acted with (evaluation.provenance)
    # the folder acted from, by content (a shipped learner's too: `--adopt` and the stale check compare it with a run folder)
    folder = Path(agent.checkpoint) if reference is not None and getattr(agent, "checkpoint", None) is not None else Path(target)
    if folder.is_dir():
        out["checkpoint_sha256"] = folder_sha256(folder)
    return out


def folder_sha256(folder: Path) -> str:
    """SHA-256 over a run folder's file names and bytes: the same value means the same weights,
    wherever the folder lies (what `identity` records and the paper table checks on adopting an
    evaluation)."""
    import hashlib

    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            h.update(p.relative_to(folder).as_posix().encode())
            h.update(p.read_bytes())
    return h.hexdigest()
