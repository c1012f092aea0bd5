"""The colours every picture of echo-data uses (maps, videos, previews): one owner, so a phone is
the same red in `preview`, `view` and `evaluate --video`."""

from __future__ import annotations

RGB = tuple[int, int, int]

BACKGROUND: RGB = (250, 250, 247)
ROOMS: dict[str, RGB] = {
    "living": (243, 230, 200),
    "kitchen": (220, 239, 216),
    "bedroom": (221, 228, 245),
    "bathroom": (214, 238, 242),
    "hall": (238, 238, 238),
    "study": (242, 221, 232),
}
ROOM_OTHER: RGB = (245, 245, 245)
FURNITURE: dict[str, RGB] = {
    "table": (176, 136, 80),
    "counter": (154, 154, 138),
    "shelf": (140, 106, 68),
    "cabinet": (166, 124, 82),
    "sofa": (122, 143, 176),
    "bed": (192, 160, 184),
    "sink_cabinet": (232, 232, 240),
}
FURNITURE_OTHER: RGB = (153, 153, 153)
OUTLINE: RGB = (51, 51, 51)
EXTERIOR_WALL: RGB = (34, 34, 34)
INTERIOR_WALL: RGB = (68, 68, 68)
DOOR: RGB = (139, 90, 43)
RUG: RGB = (160, 138, 96)
CURTAIN: RGB = (60, 141, 60)
BASIN: RGB = (185, 215, 238)
# Sound sources by category while they sound; a resolved (silent) source is drawn hollow in grey.
SOURCES: dict[str, RGB] = {
    "phone": (214, 39, 40),
    "alarm": (255, 127, 14),
    "furby": (148, 103, 189),
    "doorbell": (227, 119, 194),
    "sink": (31, 119, 180),
}
SOURCE_OTHER: RGB = (0, 0, 0)
SILENT: RGB = (150, 150, 150)
ROBOT: RGB = (44, 160, 44)  # the robot, its path and its start pose
TEXT: RGB = (85, 85, 85)
TARGET: RGB = (200, 30, 200)  # the skill chain's targets (numbered squares)


def source(category: str) -> RGB:
    """The colour of a sound source of `category`."""
    return SOURCES.get(category, SOURCE_OTHER)
