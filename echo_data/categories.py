"""The sound categories of the task and the paper's instance counts: the one place they are written.

Two kinds of sounding event exist. A relocation category sounds from a small object the robot
must pick up and put away (the event ends when it is held); a state category sounds from the home
itself (a doorbell rings until its door is opened, a sink runs until its faucet is closed).
Every module that names a category (the recipe's keys, the sampler, the synthesiser, the acoustic
levels, the environment's resolution rule) imports it from here.
"""

from __future__ import annotations

from typing import Literal

RelocationCategory = Literal["phone", "alarm", "furby"]
StateCategory = Literal["doorbell", "sink"]
Category = Literal["phone", "alarm", "furby", "doorbell", "sink"]

RELOCATION_CATEGORIES: tuple[RelocationCategory, ...] = ("phone", "alarm", "furby")
STATE_CATEGORIES: tuple[StateCategory, ...] = ("doorbell", "sink")
CATEGORIES: tuple[Category, ...] = (*RELOCATION_CATEGORIES, *STATE_CATEGORIES)

# Silent clutter (`objects.distractor_shapes`): written here too so that the recipe can refuse an
# unknown shape when it is loaded; scene/objects.py builds each of them.
DistractorShape = Literal["mug", "can", "box", "bowl", "bottle", "book"]
DISTRACTOR_SHAPES: tuple[DistractorShape, ...] = ("mug", "can", "box", "bowl", "bottle", "book")

# The paper's distinct sound instances per category, (train, test): 113 in all, split about 2:1
# so that test sounds are never heard in training.
CATEGORY_COUNTS: dict[str, tuple[int, int]] = {
    "alarm": (11, 5),
    "furby": (30, 14),
    "phone": (19, 9),
    "sink": (6, 3),
    "doorbell": (11, 5),
}
