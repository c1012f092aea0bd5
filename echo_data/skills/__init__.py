"""Scripted experts for the skill space {Navigate, Pick, Place, OpenDoor, CloseSink}.

Each expert is a generator `expert(world, call, spec)` that yields one action per control step
and returns a `SkillOutcome`. `EXPERTS` maps skill names to them; modules are imported on
first use so that importing the package does not load mplib.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator, Mapping

_WHERE = {
    "Navigate": ("echo_data.skills.navigate", "navigate"),
    "Pick": ("echo_data.skills.pick", "pick"),
    "Place": ("echo_data.skills.place", "place"),
    "OpenDoor": ("echo_data.skills.open_door", "open_door"),
    "CloseSink": ("echo_data.skills.close_sink", "close_sink"),
}


class _Experts(Mapping[str, Callable]):
    def __getitem__(self, skill: str) -> Callable:
        module, name = _WHERE[skill]
        return getattr(importlib.import_module(module), name)

    def __iter__(self) -> Iterator[str]:
        return iter(_WHERE)

    def __len__(self) -> int:
        return len(_WHERE)


EXPERTS: Mapping[str, Callable] = _Experts()
