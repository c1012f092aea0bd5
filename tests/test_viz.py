"""The one map and the one spectrogram picture: what they show is where it physically is."""

from __future__ import annotations

import numpy as np
import pytest

from echo_data.floorplan import FloorPlan
from echo_data.recipe import Recipe
from echo_data.scene.generate import generate_floorplan
from echo_data.viz import palette
from echo_data.viz.frames import HEIGHT, PANEL, WIDTH, EpisodeFrames
from echo_data.viz.spectrogram import GAP_ROWS, spectrogram_db, spectrogram_picture
from echo_data.viz.topdown import TopDownMap, target_point

FS = 16000


@pytest.fixture(scope="module")
def plan() -> FloorPlan:
    return generate_floorplan(Recipe(name="t"), np.random.default_rng(3))


def test_tone_lands_in_its_frequency_bin_and_ear() -> None:
    t = np.arange(FS) / FS
    left = np.sin(2 * np.pi * 1000.0 * t)
    db, cols_per_s = spectrogram_db(np.stack([left, 1e-3 * left], axis=1), FS)
    assert cols_per_s == pytest.approx(100.0)
    n_fft = 2 * (db.shape[1])  # bins 1 .. n_fft/2 are kept (DC dropped)
    peak_hz = (int(np.argmax(db[0].mean(axis=1))) + 1) * FS / n_fft
    assert peak_hz == pytest.approx(1000.0, abs=FS / n_fft)
    assert db[0].max() - db[1].max() == pytest.approx(60.0, abs=0.5)  # 20 log10(1e3)


def test_picture_puts_the_left_ear_on_top_low_frequencies_at_the_bottom() -> None:
    t = np.arange(FS) / FS
    x = np.stack([np.sin(2 * np.pi * 7000.0 * t), np.sin(2 * np.pi * 300.0 * t)], axis=1)
    pic, _ = spectrogram_picture(x, FS)
    bins = (pic.shape[0] - GAP_ROWS) // 2
    brightness = pic.astype(float).sum(axis=(1, 2))
    top, bottom = brightness[:bins], brightness[bins + GAP_ROWS :]
    assert np.argmax(top) < bins // 4  # 7 kHz near the top of the left ear's half
    assert np.argmax(bottom) > 3 * bins // 4  # 300 Hz near the bottom of the right ear's half


def test_map_marks_sources_by_category_and_state(plan: FloorPlan) -> None:
    o = plan.objects[0]
    events = [{"category": "phone", "source": [o.position[0], o.position[1], 1.0]}]
    m = TopDownMap(plan, events, size=PANEL)
    x, y = (int(round(v)) for v in m.px(o.position[0], o.position[1]))
    assert tuple(m.draw(sounding=[True])[y, x]) == palette.source("phone")
    silent = m.draw(sounding=[False])[y, x]
    assert tuple(silent) != palette.source("phone")
    # the same plan gives the same picture size with or without what moves
    assert m.draw().shape == m.draw(path=[(o.position[0], o.position[1])] * 2, yaw=0.0).shape == (PANEL, PANEL, 3)


def test_north_is_up(plan: FloorPlan) -> None:
    m = TopDownMap(plan, size=PANEL)
    b = plan.bounds
    (_, y_south), (_, y_north) = m.px(b.xmin, b.ymin), m.px(b.xmin, b.ymax)
    assert y_north < y_south
    assert y_north >= 0 and y_south <= PANEL


def test_frame_layout(plan: FloorPlan) -> None:
    audio = np.zeros((3 * FS, 2), np.float32)
    audio[FS:, 0] = np.random.default_rng(0).normal(size=2 * FS)
    frames = EpisodeFrames(TopDownMap(plan, size=PANEL), audio, FS)
    f = frames.frame(np.zeros((128, 128, 3), np.uint8), np.full((128, 128), 2.0), [(0.0, 0.0)], 0.0, FS, "x")
    assert f.shape == (HEIGHT, WIDTH, 3)
    with pytest.raises(ValueError, match="map panel"):
        EpisodeFrames(TopDownMap(plan, size=PANEL + 1), audio, FS)


def test_target_points_read_the_target_text_through_target(plan: FloorPlan) -> None:
    """`Target` owns the "kind:index" text: what it refuses has no point on the map (a hand-made
    parser took "door:-1" for the last door)."""
    assert plan.doors and target_point(plan, "door:0") is not None
    assert target_point(plan, "door:-1") is None
    assert target_point(plan, "window:0") is None and target_point(plan, "door:x") is None
    assert target_point(plan, f"door:{len(plan.doors)}") is None
    name = plan.objects[0].name
    assert target_point(plan, name) == tuple(plan.objects[0].position[:2])
