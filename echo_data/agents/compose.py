"""One policy per skill: `--policy Navigate=runs/nav --policy oracle` drives Navigate with a trained
run and every other skill with the scripted experts.

Why: behaviour cloning trains one policy per skill, but an episode is a chain (Navigate, Pick,
Navigate, Place, ...). To score a Navigate policy closed loop the other skills must still be
done, so a composition dispatches on `info["skill"]` at each skill's reset. A spec is
`SKILL=TARGET` (TARGET as `load_policy` takes it: a built-in, `module:Class` or a checkpoint
folder) or a plain TARGET, the fallback for skills not named (default: `oracle`).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from echo_data.protocols import PRIVILEGED_INFO, is_privileged

DEFAULT_FALLBACK = "oracle"


class PolicySpecError(ValueError):
    """A `--policy` list that does not describe one policy per skill (one line, names the spec)."""


def parse_specs(specs: Sequence[str]) -> tuple[dict[str, str], str]:
    """(skill -> target, fallback target) of a list of `SKILL=TARGET` / `TARGET` specs."""
    from echo_data.skills import EXPERTS

    by_skill: dict[str, str] = {}
    plain: list[str] = []
    for s in specs:
        skill, eq, target = s.partition("=")
        if not eq or Path(s).is_dir():  # a folder whose name holds "=" is a plain target
            if not s.strip():
                raise PolicySpecError("--policy '': empty policy")
            plain.append(s)
            continue
        skill, target = skill.strip(), target.strip()
        if skill not in EXPERTS:
            raise PolicySpecError(f"--policy {s!r}: unknown skill {skill!r} (skills: {', '.join(EXPERTS)})")
        if not target:
            raise PolicySpecError(f"--policy {s!r}: no policy after '='")
        if skill in by_skill:
            raise PolicySpecError(f"--policy {s!r}: skill {skill} is given twice")
        by_skill[skill] = target
    if len(plain) > 1:
        raise PolicySpecError(f"--policy: {len(plain)} fallback policies ({', '.join(plain)}); give at most one without SKILL=")
    return by_skill, plain[0] if plain else DEFAULT_FALLBACK


def is_composite(specs: str | Sequence[str]) -> bool:
    """Whether a policy argument needs a `SkillDispatch` (more than one spec, or any SKILL=)."""
    if isinstance(specs, str):
        return False
    return len(specs) > 1 or any("=" in s and not Path(s).is_dir() for s in specs)


def spec_name(specs: str | Sequence[str]) -> str:
    """The policy argument as one string (results files, tables)."""
    return specs if isinstance(specs, str) else ",".join(specs)


class SkillDispatch:
    """Routes each skill to its own policy; reports the active one's `ends_itself` and `outcome`."""

    name = "per-skill"

    def __init__(self, by_skill: dict[str, Any], fallback: Any, names: dict[str, str] | None = None) -> None:
        self.by_skill = by_skill
        self.fallback = fallback
        self.names = names or {}
        self.active: Any = fallback
        members = [*by_skill.values(), fallback]
        # the runtime hands the world to the composition if any member needs it; `reset` passes
        # it on to privileged members only (echo_data.protocols)
        self.privileged = any(is_privileged(m) for m in members)
        keys: set[str] = set()
        for m in members:
            obs = getattr(m, "observations", None)
            if obs is None:  # a member that reads everything makes the composition read everything
                keys = set()
                self.observations: tuple[str, ...] | None = None
                break
            keys.update(obs)
        else:
            self.observations = tuple(sorted(keys))

    @property
    def ends_itself(self) -> bool:
        return bool(getattr(self.active, "ends_itself", False))

    @property
    def outcome(self) -> Any:
        return getattr(self.active, "outcome", None)

    def policy_for(self, skill: str) -> Any:
        return self.by_skill.get(skill, self.fallback)

    def reset(self, info: dict[str, Any]) -> None:
        self.active = self.policy_for(info["skill"])
        self.active.reset(info if is_privileged(self.active) else {k: v for k, v in info.items() if k not in PRIVILEGED_INFO})

    def act(self, obs: dict[str, Any]) -> Any:
        return self.active.act(obs)

    def close(self) -> None:
        for m in {id(m): m for m in [*self.by_skill.values(), self.fallback]}.values():
            close = getattr(m, "close", None)
            if callable(close):
                close()
