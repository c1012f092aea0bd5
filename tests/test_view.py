"""`echo-data view`: an MP4 of one episode with its binaural sound track at a stated listening
gain, and a Rerun recording of it read back with rerun's own API."""

from __future__ import annotations

import hashlib
import io
import json
import math
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import soundfile as sf
from PIL import Image
from typer.testing import CliRunner

from echo_data.camera import depth_to_world
from echo_data.cli import app
from echo_data.media import colour_lut, probe_mp4
from echo_data.view import render_episode_video
from echo_data.viz.frames import CAPTION_TOP, DEPTH_RANGE_M, HEIGHT, KEY_TOP, PANEL, PANEL_TOP, TITLE_H, WIDTH, EpisodeFrames
from echo_data.viz.listening import TARGET_PEAK_DBFS, TARGET_RMS_DBFS, listening
from echo_data.viz.recording import _grid_step
from echo_data.viz.topdown import TopDownMap


@pytest.fixture(scope="module")
def ds(synth_dataset: Callable[[dict[str, int]], Path]) -> Path:
    return synth_dataset({"train": 2, "test": 1})


def test_view_writes_video_with_binaural_sound(ds: Path, tmp_path: Path) -> None:
    out = tmp_path / "ep.mp4"
    r = CliRunner().invoke(app, ["view", str(ds), "--episode", "1", "--out", str(out)])
    assert r.exit_code == 0, r.output
    ep = next(e for e in pq.read_table(ds / "meta" / "episodes.parquet").to_pylist() if e["split"] == "train" and e["episode_index"] == 1)
    p = probe_mp4(out)
    assert sorted(p["streams"]) == ["audio", "video"]
    assert p["video_frames"] == ep["n_steps"] and p["fps"] == 10.0
    assert p["audio_channels"] == 2 and p["audio_rate"] == 16000
    assert p["duration_s"] == pytest.approx(ep["n_steps"] / 10, abs=0.05)
    assert (p["width"], p["height"]) == (1024, 484)


def test_view_bad_episode_is_exit_2_and_writes_nothing(ds: Path, tmp_path: Path) -> None:
    out = tmp_path / "none.mp4"
    r = CliRunner().invoke(app, ["view", str(ds), "--episode", "7", "--out", str(out)])
    assert r.exit_code == 2 and "no train episode 7" in r.output and not out.exists()
    r = CliRunner().invoke(app, ["view", str(tmp_path), "--out", str(out)])
    assert r.exit_code == 2 and "manifest.json" in r.output and not out.exists()


def _mp4_audio(path: Path) -> np.ndarray:
    """The decoded sound track of an MP4, (samples, channels) float."""
    import av

    with av.open(str(path)) as c:
        return np.concatenate([f.to_ndarray().reshape(f.layout.nb_channels, -1).T for f in c.decode(audio=0)]).astype(np.float64)


def test_view_plays_at_the_stated_gain_and_leaves_the_wav_alone(ds: Path, tmp_path: Path) -> None:
    ep = next(e for e in pq.read_table(ds / "meta" / "episodes.parquet").to_pylist() if e["split"] == "train" and e["episode_index"] == 0)
    wav = ds / ep["audio_path"]
    before = hashlib.sha256(wav.read_bytes()).hexdigest()
    summary = render_episode_video(ds, 0, tmp_path / "ep.mp4")
    assert hashlib.sha256(wav.read_bytes()).hexdigest() == before
    stored, sr = sf.read(wav, dtype="float64", always_2d=True)
    first = pq.read_table(ds / "data" / ep["shard"], filters=[("episode_index", "=", 0)])["audio_offset"][0].as_py()
    stored = stored[first : first + ep["n_steps"] * sr // 10]
    played = _mp4_audio(tmp_path / "ep.mp4")[: len(stored)]
    rms_db = [20 * math.log10(np.sqrt(np.mean(x**2))) for x in (stored, played)]
    assert rms_db[1] - rms_db[0] == pytest.approx(summary["gain_db"], abs=1.0)  # AAC keeps the level to well under 1 dB
    assert 20 * math.log10(np.abs(played).max()) < -0.5


def test_listening_gain_brings_a_calibrated_room_level_to_the_target() -> None:
    """A 1 kHz tone at 60 dB SPL RMS (full scale 120 dB SPL): -60 dBFS RMS, peak 3 dB above
    (a sine's crest factor is sqrt 2); played 40 dB up, at the -20 dBFS target."""
    fs = 16_000
    t = np.arange(fs) / fs
    tone = np.sqrt(2) * 10 ** (-60 / 20) * np.sin(2 * np.pi * 1000 * t)
    level = listening(np.c_[tone, tone], 120.0)
    assert level.rms_dbfs == pytest.approx(-60.0, abs=0.01) and level.peak_dbfs == pytest.approx(-56.99, abs=0.01)
    assert level.gain_db == 40.0
    out = level.apply(np.c_[tone, tone])
    assert 20 * math.log10(np.sqrt(np.mean(out.astype(np.float64) ** 2))) == pytest.approx(TARGET_RMS_DBFS, abs=0.01)
    assert "+40 dB" in level.note() and "120 dB SPL" in level.note() and "60 dB SPL RMS" in level.note()
    click = np.c_[tone, tone]
    click[100] = 10 ** (-10 / 20)  # one click at -10 dBFS: the peak limit decides, not the RMS
    assert listening(click, 120.0).gain_db == math.floor(TARGET_PEAK_DBFS + 10.0) == 9


def test_frame_titles_depth_bars_in_metres_wrist_panel_and_map_key() -> None:
    topdown = TopDownMap(None, [{"category": "phone", "source": (1.0, 1.0, 0.8)}], size=PANEL, extent=[(0.0, 0.0), (4.0, 4.0)])
    video = EpisodeFrames(topdown, np.zeros((16_000, 2), np.float32), 16_000, sound_note="sound +30 dB")
    depth = np.full((16, 16), 3.0)
    rgb = np.full((16, 24, 3), 200, np.uint8)
    with_wrist = video.frame(rgb, depth, [(0.5, 0.5)], 0.0, 0, "caption", wrist_depth_m=np.full((16, 16), 6.0))
    without = video.frame(rgb, depth, [(0.5, 0.5)], 0.0, 0, "caption")
    assert with_wrist.shape == (HEIGHT, WIDTH, 3) == (484, 1024, 3)
    mid = PANEL_TOP + PANEL // 2
    assert not without[PANEL_TOP:KEY_TOP, 2 * PANEL : 3 * PANEL].any()  # no wrist depth: an empty panel
    lut = colour_lut("turbo")
    assert tuple(with_wrist[mid, 2 * PANEL + PANEL // 2]) == tuple(lut[255])  # 6 m: the end of the scale
    bar_y = KEY_TOP + 6
    for x0 in (PANEL, 2 * PANEL):  # each depth panel has its bar: 0 m at the left end, 6 m at the right
        left, right = x0 + 12, x0 + PANEL - 25
        assert tuple(with_wrist[bar_y, left]) == tuple(lut[0]) and tuple(with_wrist[bar_y, right]) == tuple(lut[255])
    # the 3 m tick of the bar shows the colour of the 3 m depth panel
    tick3 = PANEL + 12 + round(3 / DEPTH_RANGE_M * (PANEL - 37))
    assert np.abs(with_wrist[bar_y, tick3].astype(int) - with_wrist[mid, PANEL + PANEL // 2].astype(int)).max() <= 8
    assert with_wrist[:TITLE_H].any() and with_wrist[:TITLE_H, 3 * PANEL :].any()  # titles over every panel
    bar = np.flatnonzero((with_wrist[KEY_TOP + 22, 3 * PANEL :] == 255).all(axis=1))
    assert bar[-1] - bar[0] + 1 == pytest.approx(topdown.scale, abs=1.5)  # the scale bar is 1 m of the map
    assert with_wrist[CAPTION_TOP + 20 :].any()  # the sound-level line


def test_rerun_recording_reads_back(ds: Path, tmp_path: Path) -> None:
    import rerun as rr

    out = tmp_path / "rec" / "ep.rrd"
    r = CliRunner().invoke(app, ["view", str(ds), "--episode", "1", "--rerun", str(out)])
    assert r.exit_code == 0, r.output
    assert out.is_file() and not list(out.parent.glob(".*")) and not list(Path.cwd().glob("train-*.mp4"))  # --rerun alone: no MP4
    ep = next(e for e in pq.read_table(ds / "meta" / "episodes.parquet").to_pylist() if e["split"] == "train" and e["episode_index"] == 1)
    rows = pq.read_table(ds / "data" / ep["shard"], filters=[("episode_index", "=", 1)]).to_pylist()
    rec = rr.dataframe.load_recording(out)
    entities = {c.entity_path for c in rec.schema().component_columns()}
    want = {"/world/head/rgb", "/world/head/depth", "/world/wrist/depth", "/world/points/head", "/world/points/wrist", "/world/path", "/world/sources",
            "/plan/map", "/plan/path", "/plan/robot", "/audio/spectrogram", "/skill", "/state/base_x", "/action/base_vx", "/state/gripper"}
    assert want <= entities
    table = rec.view(index="step", contents="/**").select().read_all()
    assert table.column("step").to_pylist() == list(range(ep["n_steps"]))
    secs = [t.total_seconds() if hasattr(t, "total_seconds") else t / 1e9 for t in table.column("time").to_pylist()]
    assert secs == pytest.approx([row["timestamp"] for row in rows], abs=1e-6)
    # the point cloud is the stored depth lifted with the stored camera pose
    info = json.loads((ds / "meta" / "info.json").read_text())["cameras"]["wrist"]
    t0 = rec.view(index="step", contents="/world/points/wrist").filter_range_sequence(0, 0).select().read_all()
    got = np.array(t0.column("/world/points/wrist:Position3D")[0].as_py(), dtype=np.float64)
    depth = np.asarray(Image.open(io.BytesIO(rows[0]["observation.images.wrist_depth"]["bytes"])))
    pts = depth_to_world(depth, np.array(info["K"]), np.array(rows[0]["camera_pose.wrist"]), info["depth_unit_m"])
    pts = pts[:: _grid_step(*depth.shape), :: _grid_step(*depth.shape)]
    pts = pts[np.isfinite(pts[..., 0])]
    assert got.shape == pts.shape and np.allclose(got, pts, atol=1e-4)
    # and rerun's own checker accepts every chunk against its archetypes (what the viewer loads)
    check = subprocess.run([sys.executable, "-m", "rerun", "rrd", "verify", str(out)], capture_output=True, text=True, timeout=120)
    assert check.returncode == 0 and "without error" in check.stdout + check.stderr, check.stdout + check.stderr


@pytest.mark.parametrize("bad", ["ep.mp4", "folder.rrd", "afile/ep.rrd"])
def test_bad_rerun_target_is_one_line_exit_2_and_writes_nothing(ds: Path, tmp_path: Path, bad: str) -> None:
    (tmp_path / "folder.rrd").mkdir()
    (tmp_path / "afile").write_text("x")
    target = tmp_path / bad
    r = CliRunner().invoke(app, ["view", str(ds), "--rerun", str(target)])
    assert r.exit_code == 2 and "--rerun" in r.output and len(r.output.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "folder.rrd"] and not any((tmp_path / "folder.rrd").iterdir())


def test_rerun_for_a_missing_episode_leaves_no_file(ds: Path, tmp_path: Path) -> None:
    r = CliRunner().invoke(app, ["view", str(ds), "--episode", "7", "--rerun", str(tmp_path / "ep.rrd")])
    assert r.exit_code == 2 and "no train episode 7" in r.output and list(tmp_path.iterdir()) == []


def test_sources_fall_silent_when_resolved_and_ride_in_the_hand() -> None:
    """A relocation chain: the furby sounds until the step after Pick's success test holds, then
    is silent; it is in the hand while the state's `holding` is set after that, and the map draws
    it at the robot (not on its shelf)."""
    from echo_data.view import source_states
    from echo_data.viz import palette

    chain = [{"skill": "Navigate", "event": 0}, {"skill": "Pick", "event": 0}, {"skill": "Place", "event": 0}]
    flags = np.zeros((6, 5), bool)
    flags[1:, 0] = True  # reached after step 1
    flags[3:, 1] = True  # picked up after step 3
    flags[5:, 2] = True  # placed after step 5
    holding = np.array([0, 0, 0, 1, 1, 0], float) > 0.5
    sounding, carried = source_states(chain, 1, flags, holding)
    assert [s[0] for s in sounding] == [True, True, True, True, False, False]
    assert carried == [[], [], [], [], [0], []]
    topdown = TopDownMap(None, [{"category": "furby", "source": (3.5, 3.5, 0.8)}], size=PANEL, extent=[(0.0, 0.0), (4.0, 4.0)])
    shelf = tuple(int(v) for v in topdown.px(3.5, 3.5))
    sounding_map = topdown.draw([(0.5, 0.5)], 0.0, [True])
    assert tuple(sounding_map[shelf[1], shelf[0]]) == palette.source("furby")
    in_hand = topdown.draw([(0.5, 0.5)], 0.0, [False], moved={0: (0.85, 0.5)})
    assert tuple(in_hand[shelf[1], shelf[0]]) != palette.source("furby") and not (in_hand == palette.source("furby")).all(axis=2).any()
    ring = (in_hand == palette.SILENT).all(axis=2)
    ys, xs = np.nonzero(ring)
    hand = topdown.px(0.5 + 0.35, 0.5)
    assert abs(xs.mean() - hand[0]) < 3 and abs(ys.mean() - hand[1]) < 3  # the silenced ring is where the hand is, over the robot


def test_wrist_depth_has_its_own_scale_and_the_strip_its_axes() -> None:
    from echo_data.viz.frames import DB_KEY, SPEC_AXIS_W, SPEC_HEAD_TOP, SPEC_TOP, WRIST_DEPTH_RANGE_M

    topdown = TopDownMap(None, [], size=PANEL, extent=[(0.0, 0.0), (4.0, 4.0)])
    video = EpisodeFrames(topdown, np.zeros((16_000, 2), np.float32), 16_000)
    frame = video.frame(None, None, [(0.5, 0.5)], 0.0, 0, "c", wrist_depth_m=np.full((16, 16), 1.0))
    lut = colour_lut("turbo")
    mid = PANEL_TOP + PANEL // 2
    assert WRIST_DEPTH_RANGE_M < DEPTH_RANGE_M
    assert tuple(frame[mid, 2 * PANEL + PANEL // 2]) == tuple(lut[int(1.0 / WRIST_DEPTH_RANGE_M * 255)])  # 1 m mid-scale, not dark
    axis = frame[SPEC_TOP:CAPTION_TOP, :SPEC_AXIS_W]
    assert (axis.min(axis=2) > 128).sum() > 40  # L / R letters, kHz ticks and labels in white
    key = frame[SPEC_HEAD_TOP + 4 : SPEC_HEAD_TOP + 12, DB_KEY[0] : DB_KEY[1]]
    magma = colour_lut("magma")
    assert tuple(key[2, 0]) == tuple(magma[0]) and tuple(key[2, -1]) == tuple(magma[255])  # the dB key, -80 .. 0 dB
    # the title and the key sit in the strip's header: the strip itself is the spectrogram only (silent here: black)
    from echo_data.viz.frames import SPEC_AHEAD, SPEC_H, SPEC_SECONDS
    from echo_data.viz.spectrogram import scrolling_strip

    strip = scrolling_strip(video.picture, video.cols_per_s, 0.0, WIDTH, SPEC_H, SPEC_SECONDS, SPEC_AHEAD)
    assert DB_KEY[1] < WIDTH and np.array_equal(frame[SPEC_TOP:CAPTION_TOP, SPEC_AXIS_W:], strip[:, SPEC_AXIS_W:])
    assert (frame[SPEC_HEAD_TOP:SPEC_TOP, SPEC_AXIS_W:].min(axis=2) > 128).sum() > 100  # the title is in the header


def test_topdown_picture_has_legend_and_chain_targets(tmp_path: Path) -> None:
    """preview's topdown.png: the chain's targets as numbered squares, and a legend under the plan."""
    from echo_data.episode import SkillCall
    from echo_data.recipe import load_recipe
    from echo_data.scene.generate import generate_floorplan_from_seed
    from echo_data.viz import palette
    from echo_data.viz.topdown import draw_topdown, target_point

    plan = generate_floorplan_from_seed(load_recipe(Path(__file__).parents[1] / "recipes" / "quickstart.yaml"), 3)
    events = [{"category": "phone", "source": (*plan.furniture[0].center, 0.8)}]
    with_chain, without = tmp_path / "t.png", tmp_path / "p.png"
    draw_topdown(plan, with_chain, events=events, chain=[SkillCall("Navigate", "furniture:1", 0), SkillCall("Place", "furniture:1", 0)])
    draw_topdown(plan, without, events=events)
    a, b = (np.asarray(Image.open(p).convert("RGB")) for p in (with_chain, without))
    magenta = lambda img: (img == palette.TARGET).all(axis=2)  # noqa: E731
    assert magenta(a).sum() > magenta(b).sum() > 0  # the legend names targets; the chain adds its square and label
    assert target_point(plan, "furniture:1") == tuple(plan.furniture[1].center) and target_point(plan, "door:99") is None
    map_h = TopDownMap(plan, events, px_per_m=80.0, labels=True).height
    assert a.shape[0] > map_h + 16 and (a[map_h + 16 :] != np.asarray(palette.BACKGROUND)).any(axis=2).sum() > 100  # the legend rows


def test_frame_text_keeps_its_spaces() -> None:
    """The frame's font draws a space wide enough to part words (PIL's built-in one ran
    "dB above" into "dBabove"): a space is at least a third of an "a"."""
    from echo_data.viz.frames import FONT

    assert FONT.getlength(" ") >= FONT.getlength("a") / 3 and FONT.getlength(" ") >= 3


def test_topdown_room_label_stays_readable_over_the_start_ring() -> None:
    """Room names are drawn last on a backing: a start ring at a room's centre (where its name
    is) no longer crosses the name."""
    from PIL import ImageDraw as Draw

    from echo_data.recipe import load_recipe
    from echo_data.scene.generate import generate_floorplan_from_seed
    from echo_data.viz import palette

    plan = generate_floorplan_from_seed(load_recipe(Path(__file__).parents[1] / "recipes" / "quickstart.yaml"), 3)
    room = plan.rooms[0]
    cx, cy = room.rect.center
    m = TopDownMap(plan, [], px_per_m=100, labels=True)
    img = m.draw((), start=(cx, cy, 0.0))
    from PIL import Image

    left, top, right, bottom = (int(v) for v in Draw.Draw(Image.new("RGB", (1, 1))).textbbox(m.px(cx, cy), f"{room.kind} {room.index}", anchor="mm"))
    inside = img[top:bottom, left:right].reshape(-1, 3)
    assert (inside.max(axis=1) < 160).sum() > 10  # the name is there (grey text, antialiased)
    assert not (inside == palette.ROBOT).all(axis=1).any()  # and the ring does not cross it
