"""What a skill acts on, typed: an object by name, or a door, faucet or piece of furniture by index.

Episode specs, datasets and planner exports store a target as text ("phone_0", "door:1",
"faucet:0", "furniture:3"); that text is read and written here only (`Target.parse`, `str()`),
so no other module splits strings on ":" to learn what a skill acts on.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

TargetKind = Literal["object", "door", "faucet", "furniture"]
INDEXED: tuple[TargetKind, ...] = ("door", "faucet", "furniture")


@dataclass(frozen=True)
class Target:
    """An object (`name` set, `index` -1) or an indexed door / faucet / furniture (`name` empty)."""

    kind: TargetKind
    index: int = -1
    name: str = ""

    @classmethod
    def parse(cls, text: str | Target) -> Target:
        """"phone_0" -> object; "door:1" / "faucet:0" / "furniture:3" -> that kind and index."""
        if isinstance(text, Target):
            return text
        kind, sep, idx = str(text).partition(":")
        if not sep:
            return cls("object", name=kind)
        if kind not in INDEXED or not idx.isdigit():
            raise ValueError(f"target {text!r}: expected an object name or one of {', '.join(k + ':<i>' for k in INDEXED)}")
        return cls(kind, int(idx))

    @classmethod
    def door(cls, i: int) -> Target:
        return cls("door", int(i))

    @classmethod
    def faucet(cls, i: int) -> Target:
        return cls("faucet", int(i))

    @classmethod
    def furniture(cls, i: int) -> Target:
        return cls("furniture", int(i))

    @classmethod
    def object(cls, name: str) -> Target:
        return cls("object", name=name)

    def __str__(self) -> str:
        return self.name if self.kind == "object" else f"{self.kind}:{self.index}"

    def spoken(self, plan: Any) -> str:
        """What a listener would call it: phone_0 -> phone, door -> door, faucet -> sink,
        furniture -> its kind (table, counter, ...)."""
        if self.kind == "door":
            return "door"
        if self.kind == "faucet":
            return "sink"
        if self.kind == "furniture":
            return next((str(f.kind) for f in getattr(plan, "furniture", ()) if f.index == self.index), "furniture")
        return next((str(o.category) for o in getattr(plan, "objects", ()) if o.name == self.name), self.name.rsplit("_", 1)[0])
