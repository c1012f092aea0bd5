"""Scripted experts and success tests of the skill space {Navigate, Pick, Place, OpenDoor, CloseSink}.

Each expert is a generator `expert(world, call, spec)` that yields one action per control step
and returns a `SkillOutcome`. Every skill is declared once in `echo_data.skill_table`;
`EXPERTS` maps skill names to their experts, imported on first use so that importing the
package does not load mplib.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping

from echo_data.skill_table import SKILLS


class _Experts(Mapping[str, Callable]):
    def __getitem__(self, skill: str) -> Callable:
        return SKILLS[skill].expert_fn()

    def __iter__(self) -> Iterator[str]:
        return iter(SKILLS)

    def __len__(self) -> int:
        return len(SKILLS)


EXPERTS: Mapping[str, Callable] = _Experts()
