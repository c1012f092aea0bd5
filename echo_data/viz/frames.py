"""One video frame per control step, the same for a stored episode (`view`) and an evaluated one
(`evaluate --video`): head RGB, head depth, wrist depth and the top-down map side by side under
their titles, with a depth colour bar in metres under each depth panel (each camera on its own
scale: the wrist camera sees within a metre or two, the head camera across rooms) and the map's
legend and 1 m scale bar below them, the binaural spectrogram scrolling past a cursor at the step
(left ear above right, labelled L / R, a kHz axis per ear and a dB colour key), a caption and the
line that states the sound's playback level. Picture and sound stay in step: frame t shows the track at
the sample where step t's observation was taken.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from echo_data.viz.spectrogram import DB_RANGE, GAP_ROWS, scrolling_strip, spectrogram_picture
from echo_data.viz.topdown import Point, TopDownMap

PANEL = 256  # side of the image and map panels (pixels)
TITLES = ("head RGB", "head depth", "wrist depth", "top-down plan")
TITLE_H = 16  # panel titles above the panels
KEY_H = 32  # depth colour bars and the map legend below them
SPEC_HEAD_H = 16  # the strip's title and dB colour key, above it (drawn over it they hid the sound)
SPEC_H = 128  # spectrogram strip height
CAPTION_H = 36  # caption and sound level, one line each
WIDTH, HEIGHT = len(TITLES) * PANEL, TITLE_H + PANEL + KEY_H + SPEC_HEAD_H + SPEC_H + CAPTION_H
PANEL_TOP, KEY_TOP = TITLE_H, TITLE_H + PANEL
SPEC_HEAD_TOP = KEY_TOP + KEY_H
SPEC_TOP = SPEC_HEAD_TOP + SPEC_HEAD_H
CAPTION_TOP = SPEC_TOP + SPEC_H
WHITE = (255, 255, 255)
SPEC_SECONDS = 4.0  # spectrogram history shown left of the cursor
SPEC_AHEAD = 1.0  # and ahead of it
DEPTH_RANGE_M = 6.0  # head depth colour scale: 0 m .. this (rooms are a few metres across)
WRIST_DEPTH_RANGE_M = 2.0  # wrist depth colour scale: the gripper works within reach
SPEC_AXIS_W = 34  # left margin of the spectrogram strip for its L / R labels and kHz ticks
DB_KEY = (WIDTH - 250, WIDTH - 150)  # x range of the dB colour key in the strip's header
FONT_SIZE = 11


def frame_font() -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    """DejaVu Sans (matplotlib ships it): PIL's built-in font draws spaces so narrow that words
    ran together ("dBabove", "1 sahead"); the built-in one where the file cannot be found."""
    import matplotlib.font_manager as fm

    try:
        return ImageFont.truetype(fm.findfont("DejaVu Sans", fallback_to_default=False), FONT_SIZE)
    except (OSError, ValueError):
        return ImageFont.load_default()


def fit_panel(img: np.ndarray) -> np.ndarray:
    """A camera image scaled into a PANEL x PANEL square without distortion."""
    from echo_data.media import fit_nearest

    h, w = img.shape[:2]
    s = PANEL / max(h, w)
    fitted = fit_nearest(img, max(1, round(w * s)), max(1, round(h * s)))
    out = np.zeros((PANEL, PANEL, 3), dtype=np.uint8)
    y, x = (PANEL - fitted.shape[0]) // 2, (PANEL - fitted.shape[1]) // 2
    out[y : y + fitted.shape[0], x : x + fitted.shape[1]] = fitted
    return out


def depth_colours(depth_m: np.ndarray, range_m: float = DEPTH_RANGE_M) -> np.ndarray:
    """Depth in metres as turbo colours over 0 .. range_m."""
    from echo_data.media import colour_lut

    return colour_lut("turbo")[np.clip(np.asarray(depth_m, dtype=np.float64) / range_m * 255, 0, 255).astype(np.uint8)]


def _depth_key(d: ImageDraw.ImageDraw, x0: int, range_m: float = DEPTH_RANGE_M) -> None:
    """A turbo colour bar of 0 .. range_m under a depth panel, ticked every metre (every 0.5 m up to 3 m)."""
    from echo_data.media import colour_lut

    lut = colour_lut("turbo")
    left, right, top = x0 + 12, x0 + PANEL - 24, KEY_TOP + 4
    for px in range(left, right):
        d.line([(px, top), (px, top + 8)], fill=tuple(int(c) for c in lut[round((px - left) / (right - left - 1) * 255)]))
    step = 0.5 if range_m <= 3 else 1.0
    for k in range(int(round(range_m / step)) + 1):
        m = k * step
        tick = left + m / range_m * (right - left - 1)
        d.line([(tick, top + 8), (tick, top + 11)], fill=WHITE)
        label = f"{m:g}"
        d.text((tick, top + 12), f"{label} m" if k == int(round(range_m / step)) else label, fill=WHITE, anchor="ma")


def _spectrogram_axes(d: ImageDraw.ImageDraw, rows: int, fs: int) -> None:
    """L / R labels, a kHz axis for each ear and a dB colour key on the spectrogram strip
    (`rows`: the picture's rows, both ears and the gap between them, as `spectrogram_picture` stacks them)."""
    from echo_data.media import colour_lut

    d.rectangle([0, SPEC_TOP, SPEC_AXIS_W - 1, CAPTION_TOP - 1], fill=(0, 0, 0))
    bins = (rows - GAP_ROWS) // 2
    per_row = SPEC_H / rows
    top_khz = fs / 2000
    for ear, label in enumerate(("L", "R")):
        first = ear * (bins + GAP_ROWS)  # picture row of this ear's top (highest frequency)
        y_top, y_bottom = SPEC_TOP + first * per_row, SPEC_TOP + (first + bins) * per_row
        d.text((2, (y_top + y_bottom) / 2), label, fill=WHITE, anchor="lm")
        for khz in range(0, int(top_khz) + 1, 2 if top_khz > 4 else 1):
            y = y_bottom - khz / top_khz * (y_bottom - y_top)
            d.line([(SPEC_AXIS_W - 4, y), (SPEC_AXIS_W - 1, y)], fill=WHITE)
            if khz < top_khz:  # the top label would run into the ear above (or the key row)
                d.text((SPEC_AXIS_W - 5, y), str(khz), fill=WHITE, anchor="rm")
    d.text((SPEC_AXIS_W - 5, SPEC_TOP), f"{top_khz:g}", fill=WHITE, anchor="ra")  # the top of the axis, once
    d.text((12, CAPTION_TOP - 2), "kHz", fill=WHITE, anchor="mb")
    lut = colour_lut("magma")
    (left, right), y = DB_KEY, SPEC_HEAD_TOP + 5
    for px in range(left, right):
        d.line([(px, y), (px, y + 6)], fill=tuple(int(c) for c in lut[round((px - left) / (right - left - 1) * 255)]))
    d.text((left - 4, y + 3), f"-{DB_RANGE:g}", fill=WHITE, anchor="rm")
    d.text((right + 4, y + 3), "0 dB re loudest bin", fill=WHITE, anchor="lm")


def _map_key(d: ImageDraw.ImageDraw, topdown: TopDownMap, x0: int) -> None:
    """The map's legend (robot, each source category, a silenced source) and a 1 m scale bar."""
    from echo_data.viz import palette

    bar = topdown.scale  # pixels per metre of the map panel
    d.line([(x0 + 8, KEY_TOP + 22), (x0 + 8 + bar, KEY_TOP + 22)], fill=WHITE, width=3)
    d.text((x0 + 14 + bar, KEY_TOP + 21), "1 m", fill=WHITE, anchor="ls")  # on its baseline: clear of the bar's row
    entries = [("robot", palette.ROBOT, True)] + [(c, palette.source(c), True) for c in dict.fromkeys(c for c, _ in topdown.events)] + [("silenced", palette.SILENT, False)]
    x: float = x0 + 8
    y = KEY_TOP + 4
    for name, colour, filled in entries:
        width = 11 + int(d.textlength(name)) + 10
        if x + width > x0 + PANEL and y == KEY_TOP + 4:  # many categories: go on right of the scale bar
            x, y = x0 + 40 + bar, KEY_TOP + 17
        d.ellipse([x, y + 1, x + 8, y + 9], fill=colour if filled else None, outline=colour if not filled else (0, 0, 0), width=2 if not filled else 1)
        d.text((x + 11, y), name, fill=WHITE)
        x += width


FONT = frame_font()


class EpisodeFrames:
    """Composes the frames of one episode from its map and its whole binaural track."""

    def __init__(self, topdown: TopDownMap, audio: np.ndarray, fs: int, sound_note: str = "") -> None:
        self.map = topdown
        self.fs = fs
        self.sound_note = sound_note
        self.picture, self.cols_per_s = spectrogram_picture(audio, fs)
        if topdown.width != PANEL or topdown.height != PANEL:
            raise ValueError(f"the map panel must be {PANEL} x {PANEL} px, got {topdown.width} x {topdown.height}")

    def frame(
        self,
        rgb: np.ndarray | None,
        depth_m: np.ndarray | None,
        path: Sequence[Point],
        yaw: float,
        sample: int,
        caption: str,
        sounding: Sequence[bool] | None = None,
        wrist_depth_m: np.ndarray | None = None,
        moved: dict[int, Point] | None = None,
    ) -> np.ndarray:
        """(HEIGHT, WIDTH, 3) uint8: the step whose observation was taken at `sample` of the track
        (`sounding`, `moved`: the sources' state, as `TopDownMap.draw` takes them)."""
        canvas = np.zeros((HEIGHT, WIDTH, 3), dtype=np.uint8)
        panels = (
            None if rgb is None else fit_panel(np.asarray(rgb, dtype=np.uint8)),
            None if depth_m is None else fit_panel(depth_colours(depth_m)),
            None if wrist_depth_m is None else fit_panel(depth_colours(wrist_depth_m, WRIST_DEPTH_RANGE_M)),
            self.map.draw(path, yaw, sounding, moved=moved),
        )
        for i, panel in enumerate(panels):
            if panel is not None:
                canvas[PANEL_TOP : PANEL_TOP + PANEL, i * PANEL : (i + 1) * PANEL] = panel
        canvas[SPEC_TOP:CAPTION_TOP] = scrolling_strip(self.picture, self.cols_per_s, sample / self.fs, WIDTH, SPEC_H, SPEC_SECONDS, SPEC_AHEAD)
        img = Image.fromarray(canvas)
        d = ImageDraw.Draw(img)
        d.font = FONT
        for i, (title, panel) in enumerate(zip(TITLES, panels)):
            d.text((i * PANEL + 8, 3), title if panel is not None else f"{title} (not stored)", fill=WHITE)
        for i, range_m in ((1, DEPTH_RANGE_M), (2, WRIST_DEPTH_RANGE_M)):
            if panels[i] is not None:
                _depth_key(d, i * PANEL, range_m)
        _map_key(d, self.map, 3 * PANEL)
        _spectrogram_axes(d, self.picture.shape[0], self.fs)
        d.text((SPEC_AXIS_W + 6, SPEC_HEAD_TOP + 2), f"binaural spectrogram, left ear (L) above right (R), {SPEC_SECONDS:g} s back to {SPEC_AHEAD:g} s ahead of the cursor", fill=WHITE)
        d.text((8, CAPTION_TOP + 6), caption, fill=WHITE)
        d.text((8, CAPTION_TOP + 21), self.sound_note, fill=WHITE)
        return np.asarray(img)
