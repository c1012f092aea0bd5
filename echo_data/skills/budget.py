"""A scripted expert's step budget and its way of giving up, shared by the Pick and Place experts."""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

import numpy as np


class SkillFailed(Exception):
    """An expert stops with this reason."""


class Budget:
    """Counts the actions an expert yields and stops it at the step limit ("timeout")."""

    def __init__(self, max_steps: int) -> None:
        self.max_steps = max_steps
        self.steps = 0

    def run(self, gen: Generator[np.ndarray, None, Any]) -> Generator[np.ndarray, None, Any]:
        try:
            while True:
                action = next(gen)
                if self.steps >= self.max_steps:
                    raise SkillFailed("timeout")
                self.steps += 1
                yield action
        except StopIteration as stop:
            return stop.value
