"""A skill added as docs/adding_a_skill.md says: this one module (its expert and its success
test) plus one line in the skill table (`TOY`, put into `echo_data.skill_table.SKILLS` by the test
that uses it). "TurnTapOff" resolves a running faucet, in place of CloseSink, with that skill's
motion under its own name; its success test counts its calls, so a test sees the environment
evaluate it."""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

from echo_data.skill_table import Skill, lazy_test

CHECKED: list[str] = []  # the targets the success test was asked about, call by call


def turn_tap_off(world: Any, call: Any, spec: Any) -> Generator[Any, None, Any]:
    """The expert: the shipped faucet motion (it reads its step limit and name from `call`)."""
    from echo_data.skills.close_sink import close_sink

    return (yield from close_sink(world, call, spec))


def tap_is_off(world: Any, call: Any, at: Any) -> bool:
    from echo_data.skills.success import sink_closed

    CHECKED.append(str(call.target))
    return sink_closed(world, call, at)


# The one registry line.
TOY = Skill("TurnTapOff", "support.toy_skill:turn_tap_off", lazy_test("support.toy_skill:tap_is_off"), True, ("TurnTapOff",),
            ("faucet",), 200, "resolve", description="turn the running tap off with one push")
