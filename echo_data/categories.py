"""The sound categories of the task, the paper's instance counts and each category's source level:
the one place they are written.

Two kinds of sounding event exist. A relocation category sounds from a small object the robot
must pick up and put away (the event ends when it is held); a state category sounds from the home
itself (a doorbell rings until its door is opened, a sink runs until its faucet is closed).
Every module that names a category (the recipe's keys, the sampler, the synthesiser, the acoustic
levels, the environment's resolution rule) imports it from here.
"""

from __future__ import annotations

import hashlib
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

# Source levels, dB SPL at 1 m (maximum RMS over 125 ms, `acoustics.levels.level_db`); each event
# draws its level uniformly in its category's range (`source_level_db`):
# - phone: 65-78. Purdue University's noise-level chart (the table most sound-level guides
#   reproduce) lists a ringing telephone at 80 dB; a smartphone ringtone at full volume is of
#   that order close to the phone, some dB less at 1 m.
# - alarm: 65-80, the alarm-clock range of the same chart.
# - furby: 60-75. ASTM F963 caps the sound of table-top toys at 85 dB(A) at 50 cm, i.e. at most
#   79 dB at 1 m; a talking toy's speech sits below the cap.
# - doorbell: 70-85 (our estimate: a chime must be heard through a home, above the alarm range).
# - sink: 50-65 (our estimate: water from a tap into a sink, quieter than signalling devices).
SOURCE_LEVELS_DB: dict[str, tuple[float, float]] = {
    "phone": (65.0, 78.0),
    "alarm": (65.0, 80.0),
    "furby": (60.0, 75.0),
    "doorbell": (70.0, 85.0),
    "sink": (50.0, 65.0),
}


def source_level_db(category: str, seed: int, event: int) -> float:
    """The level (dB SPL at 1 m) of event `event` of the episode with plan seed `seed`: uniform in
    the category's range, a pure function of its arguments (here, beside the categories, so that an
    `EpisodeSpec` fills in its events' levels without reaching into the acoustics)."""
    if category not in SOURCE_LEVELS_DB:
        raise ValueError(f"no source level for sound category {category!r} (known: {sorted(SOURCE_LEVELS_DB)})")
    lo, hi = SOURCE_LEVELS_DB[category]
    h = hashlib.blake2b(f"{int(seed)}:{int(event)}:{category}".encode(), digest_size=8).digest()
    u = int.from_bytes(h, "little") / 2.0**64
    return lo + u * (hi - lo)
