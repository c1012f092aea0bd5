"""Streaming binaural rendering of an episode: sources x moving head -> one (n, 2) track.

The head pose of each control step picks cached binaural RIRs per source (`RirCache`: the
receiver snapped to a `cfg.grid` lattice; the head yaw between two of `cfg.yaws` bins, i.e.
360/yaws degrees, 5 by default, the RIR linearly interpolated between the two neighbours, so
the cues follow the actual yaw continuously). Each output block of one step is the exact
convolution of the dry input with the RIR of that step (overlap-save over the last
RIR-length of input); when the RIR changes, the block is a raised-cosine crossfade over the
whole step from the old RIR's output to the new one's. Everything is linear in the inputs,
so sources superpose exactly.

A source stops at `stop_sample` with a 20 ms raised-cosine fade of its dry signal; its
reverberation keeps ringing through the RIR, so the track is exactly zero from
stop + fade + RIR length on once every source has stopped. Sources that never stop are cut
the same way at the end of the episode; the track is long enough for every tail to decay.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.fft as sfft

from echo_data.acoustics.binaural import Binauraliser, binaural_length
from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.levels import to_full_scale
from echo_data.acoustics.noise import NoiseFloor
from echo_data.acoustics.types import AcousticResponse
from echo_data.pcm import as_written
from echo_data.recipe import AcousticsConfig

FADE_S = 0.020  # dry-signal fade-out when a source stops

CacheKey = tuple[int, int, int, int, int, int]  # (source, room, ix, iy, iz, yaw bin)


@dataclass(frozen=True)
class SourceTrack:
    """One sound source: where it is, its dry mono signal (fs of the config), when it stops."""

    position: tuple[float, float, float]
    waveform: np.ndarray
    stop_sample: int | None = None


class RirCache:
    """Binaural RIRs on the receiver grid x head-yaw bins, computed lazily and kept.

    Receivers are snapped to the `cfg.grid` lattice in x, y (and in z around `cfg.ear_height`);
    when the scene exposes its floor plan (`scene.plan`), the snapped point is clamped into
    the room the head is in (so a grid point never lands behind a wall); the room index is part
    of the key. Responses are head-independent, so one response per (source, cell) serves all
    yaw bins; the binaural IRs are made per yaw bin on first use.
    """

    def __init__(self, scene: Any, positions: Sequence[Sequence[float]], cfg: AcousticsConfig, hrtf: Hrtf) -> None:
        self.scene = scene
        self.positions = [tuple(float(v) for v in p) for p in positions]
        self.cfg = cfg
        self.hrtf = hrtf
        self.grid = float(cfg.grid)
        self.yaw_step = 2 * math.pi / int(cfg.yaws)
        self.plan = getattr(scene, "plan", None)
        self._margin = 0.1 + (max((w.thickness for w in self.plan.walls), default=0.0) / 2 if self.plan else 0.0)
        self._responses: dict[tuple[int, int, int, int, int], AcousticResponse] = {}
        self._binaural: dict[tuple[int, int, int, int, int], Binauraliser] = {}  # per response: its yaw-independent part
        self._rirs: dict[CacheKey, np.ndarray] = {}
        self._spectra: dict[tuple[CacheKey, int], np.ndarray] = {}
        self.length: int | None = None  # binaural RIR length, fixed by the first response
        self.responses_computed = 0
        self.rirs_computed = 0

    # -- keys ------------------------------------------------------------------------------
    def key(self, source: int, pose: Sequence[float]) -> CacheKey:
        """Cache key of source `source` heard from head pose [x, y, z, yaw]."""
        x, y, z, yaw = (float(v) for v in pose[:4])
        room = self._room_of(x, y)
        ix, iy = round(x / self.grid), round(y / self.grid)
        iz = round((z - self.cfg.ear_height) / self.grid)
        yb = round(yaw / self.yaw_step) % int(self.cfg.yaws)
        return (source, room, ix, iy, iz, yb)

    def keys(self, source: int, pose: Sequence[float] | np.ndarray) -> list[tuple[CacheKey, float]]:
        """The two yaw bins around the head's yaw with linear-interpolation weights (one key
        with weight 1 when the yaw sits on a bin): the RIR at the actual yaw is their weighted sum."""
        k = self.key(source, (*pose[:3], 0.0))
        pos = float(pose[3]) / self.yaw_step
        lo = math.floor(pos)
        w = pos - lo
        n = int(self.cfg.yaws)
        if w < 1e-9:
            return [((*k[:5], lo % n), 1.0)]
        if w > 1.0 - 1e-9:
            return [((*k[:5], (lo + 1) % n), 1.0)]
        return [((*k[:5], lo % n), 1.0 - w), ((*k[:5], (lo + 1) % n), w)]

    def receiver(self, key: CacheKey) -> tuple[tuple[float, float, float], float]:
        """(receiver position, head yaw) that the RIR of `key` is computed for."""
        _, room, ix, iy, iz, yb = key
        x, y = ix * self.grid, iy * self.grid
        if self.plan is not None and room >= 0:
            r = next(rm for rm in self.plan.rooms if rm.index == room).rect
            mx = min(self._margin, (r.xmax - r.xmin) / 2)
            my = min(self._margin, (r.ymax - r.ymin) / 2)
            x = min(max(x, r.xmin + mx), r.xmax - mx)
            y = min(max(y, r.ymin + my), r.ymax - my)
        z = self.cfg.ear_height + iz * self.grid
        return (x, y, z), yb * self.yaw_step

    def _room_of(self, x: float, y: float) -> int:
        if self.plan is None or not self.plan.rooms:
            return -1
        inside = self.plan.room_at(x, y)
        if inside >= 0:
            return inside

        def dist(r: Any) -> float:  # distance to a room's rectangle (0 inside)
            dx = max(r.rect.xmin - x, 0.0, x - r.rect.xmax)
            dy = max(r.rect.ymin - y, 0.0, y - r.rect.ymax)
            return math.hypot(dx, dy)

        return min(self.plan.rooms, key=lambda r: (dist(r), r.index)).index

    # -- values ----------------------------------------------------------------------------
    def response(self, key: CacheKey) -> AcousticResponse:
        rkey = key[:5]
        resp = self._responses.get(rkey)
        if resp is None:
            pos, _ = self.receiver(key)
            resp = self.scene.response(self.positions[key[0]], pos)
            self._responses[rkey] = resp
            self.responses_computed += 1
        return resp

    def binauraliser(self, key: CacheKey) -> Binauraliser:
        """The yaw-independent part of the binaural RIRs of `key`'s response (kept per response)."""
        b = self._binaural.get(key[:5])
        if b is None:
            b = self._binaural[key[:5]] = Binauraliser(self.response(key), self.hrtf)
        return b

    def rir(self, key: CacheKey) -> np.ndarray:
        """(length, 2) float32 binaural RIR for `key` (read-only)."""
        ir = self._rirs.get(key)
        if ir is None:
            _, yaw = self.receiver(key)
            self._store(key, self.binauraliser(key).irs([yaw])[0])
            ir = self._rirs[key]
        return ir

    def _store(self, key: CacheKey, ir: np.ndarray) -> None:
        if self.length is None:
            self.length = ir.shape[0]
        if ir.shape[0] != self.length:  # responses of one scene share a length; pad/cut defensively
            fixed = np.zeros((self.length, 2), dtype=np.float32)
            n = min(self.length, ir.shape[0])
            fixed[:n] = ir[:n]
            ir = fixed
        ir.setflags(write=False)
        self._rirs[key] = ir
        self.rirs_computed += 1

    def spectrum(self, key: CacheKey, n_fft: int) -> np.ndarray:
        """rfft of the RIR of `key` zero-padded to `n_fft`: (n_fft // 2 + 1, 2) complex128."""
        s = self._spectra.get((key, n_fft))
        if s is None:
            s = sfft.rfft(self.rir(key).astype(np.float64), n_fft, axis=0)
            self._spectra[(key, n_fft)] = s
        return s

    def has_spectrum(self, key: CacheKey, n_fft: int) -> bool:
        """Whether `spectrum(key, n_fft)` is already computed."""
        return (key, n_fft) in self._spectra

    def expected_length(self) -> int:
        """Binaural RIR length: fixed from cfg.rir_seconds unless an RIR already fixed it."""
        if self.length is None:
            n = int(round(self.cfg.rir_seconds * self.hrtf.fs))
            probe = AcousticResponse(self.hrtf.fs, [], np.zeros(0, dtype=np.float32), n)
            self.length = binaural_length(probe, self.hrtf)
        return self.length

    def precompute(self, source: int, receivers: Sequence[Sequence[float]]) -> int:
        """Compute RIRs for every yaw bin at each receiver position (x, y, z); returns how many are new.

        Uses the scene's batch method `responses(source_xyz, receivers)` when it has one.
        """
        keys = {self.key(source, (*r[:3], 0.0))[:5]: r for r in receivers}
        todo = [k for k in keys if k not in self._responses]
        batch = getattr(self.scene, "responses", None)
        if todo and callable(batch):
            pts = [self.receiver((*k, 0))[0] for k in todo]
            for k, resp in zip(todo, batch(self.positions[source], pts)):
                self._responses[k] = resp
                self.responses_computed += 1
        yaws = [b * self.yaw_step for b in range(int(self.cfg.yaws))]
        new = 0
        for k5 in keys:
            ks = [(*k5, b) for b in range(int(self.cfg.yaws))]
            if all(k in self._rirs for k in ks):
                continue
            irs = self.binauraliser((*k5, 0)).irs(yaws)
            for key, ir in zip(ks, irs):
                if key not in self._rirs:
                    self._store(key, np.ascontiguousarray(ir))
                    new += 1
        return new


def fade_ramp(fs: int) -> np.ndarray:
    """The 20 ms raised-cosine fade-out of a stopping source's dry signal (float64)."""
    fade = int(round(FADE_S * fs))
    return 0.5 * (1 + np.cos(np.pi * (np.arange(fade) + 0.5) / fade))


def dry_segment(wave: np.ndarray, stop: int | None, lo: int, hi: int, ramp: np.ndarray) -> np.ndarray:
    """Samples [lo, hi) of a source's dry input, float64: `wave` (its first samples; zero past
    them and before 0), faded by `ramp` from `stop` on and silent after the fade."""
    seg = np.zeros(hi - lo)
    a = max(lo, 0)
    end = hi if stop is None else min(hi, stop + len(ramp))
    w = wave[a:end]
    if len(w):
        seg[a - lo : a - lo + len(w)] = w
        if stop is not None:
            f0, f1 = max(stop, a), end
            if f1 > f0:
                seg[f0 - lo : f1 - lo] *= ramp[f0 - stop : f1 - stop]
    return seg


def dry_signal(track: SourceTrack, n_play: int, fs: int) -> np.ndarray:
    """The source's dry input as rendered: played until its stop (or `n_play`), then a 20 ms fade.

    Returns float64 of length n_play + fade; zero after the fade.
    """
    ramp = fade_ramp(fs)
    stop = n_play if track.stop_sample is None else min(max(int(track.stop_sample), 0), n_play)
    return dry_segment(np.asarray(track.waveform, dtype=np.float64).ravel(), stop, 0, n_play + len(ramp), ramp)


Wave = Callable[[int], np.ndarray]  # n -> at least the first n samples of a dry signal (float64; fewer = zeros after)


@dataclass
class _Epoch:
    start: int  # first sample of this acoustic geometry (the centre of its crossfade)
    cache: RirCache


class StreamRenderer:
    """The one sound renderer: sources heard by a moving head, one block of samples per call.

    `step(pose)` renders the next `block` samples with the head at pose [x, y, z, yaw] (exact
    overlap-save convolution of each source's dry input with the RIR of that pose, crossfaded
    over the block from the previous pose's RIR when it changed); `stop(i)` fades source i out
    from the next block on (its reverberation rings on); `new_epoch(scene, at)` switches to
    another acoustic geometry (an opened door) with a raised-cosine crossfade one block long
    centred on sample `at`; `finish()` stops everything and renders until every tail has rung
    out. With a `noise` bed and a `full_scale_db_spl`, blocks are calibrated WAV samples as
    written (16-bit values); otherwise they are the sources' part in the dry signals' units.
    Knows nothing of later poses, so the environment, the build, `preview` and `render_track`
    share it.
    """

    def __init__(
        self,
        scene: Any,
        positions: Sequence[Sequence[float]],
        waves: Sequence[Wave],
        cfg: AcousticsConfig,
        block: int,
        hrtf: Hrtf | None = None,
        cache: RirCache | None = None,
        noise: NoiseFloor | None = None,
        full_scale_db_spl: float | None = None,
        name: str = "track",
    ) -> None:
        self.cfg = cfg
        self.fs = int(cfg.sample_rate)
        self.hop = int(block)
        self.hrtf = hrtf or (cache.hrtf if cache is not None else Hrtf.load(cfg.hrtf, self.fs))
        if self.hrtf.fs != self.fs:
            raise ValueError(f"HRTF at {self.hrtf.fs} Hz but the config asks for {self.fs} Hz")
        self.positions = [tuple(float(v) for v in p) for p in positions]
        if cache is None:
            cache = RirCache(scene, self.positions, cfg, self.hrtf)
        elif cache.positions != self.positions:
            raise ValueError("the RIR cache was made for other source positions")
        self.epochs = [_Epoch(0, cache)]
        self.waves = list(waves)
        self.noise = noise
        self.full_scale_db_spl = full_scale_db_spl
        self.name = name
        self.length = cache.expected_length()  # binaural RIR length L
        self.n_fft = sfft.next_fast_len(self.hop + self.length - 1, real=True)
        self.ramp = fade_ramp(self.fs)
        self.fade = len(self.ramp)
        self._xfade = 0.5 * (1 - np.cos(np.pi * (np.arange(self.hop) + 0.5) / self.hop))[:, None]
        self.stops: list[int | None] = [None] * len(self.positions)
        self._support_end: list[int | None] = [None] * len(self.positions)
        self.blocks: list[np.ndarray] = []
        self._prev: list[list[tuple[CacheKey, float]]] | None = None
        self._last_pose: np.ndarray | None = None

    @property
    def samples(self) -> int:
        """Samples rendered so far (a whole number of blocks)."""
        return len(self.blocks) * self.hop

    def new_epoch(self, scene: Any, at: int) -> None:
        """Another acoustic geometry from sample `at` on (at least half a block past what is rendered)."""
        if at - self.hop // 2 < self.samples:
            raise ValueError(f"geometry change at sample {at} is not in the future (rendered {self.samples})")
        self.epochs.append(_Epoch(int(at), RirCache(scene, self.positions, self.cfg, self.hrtf)))

    def stop(self, i: int, at: int | None = None) -> None:
        """Source i stops at sample `at` (default: the next block); no-op if it already stopped."""
        if self.stops[i] is not None:
            return
        stop = self.samples if at is None else int(at)
        if stop < self.samples:
            raise ValueError(f"source {i}: stop at sample {stop} is in the past (rendered {self.samples})")
        self.stops[i] = stop
        nz = np.flatnonzero(self._dry(i, 0, stop + self.fade))
        self._support_end[i] = int(nz[-1]) + 1 if nz.size else 0

    def step(self, pose: Sequence[float]) -> np.ndarray:
        """Render the next block heard at head pose [x, y, z, yaw]; returns it (block, 2) float32."""
        head = np.asarray(pose, dtype=np.float64).reshape(4)
        self._last_pose = head
        out = self._render(len(self.blocks), head)
        self.blocks.append(out)
        return out

    def finish(self) -> np.ndarray:
        """The whole track: every source stopped at the end of the last block, rendered (last pose
        held) until every tail has rung out: (samples + fade + L - 1, 2) float32."""
        for i in range(len(self.positions)):
            self.stop(i)
        total = self.samples + self.fade + self.length - 1
        pose = self._last_pose if self._last_pose is not None else np.zeros(4)
        while self.samples < total:
            self.blocks.append(self._render(len(self.blocks), pose))
        return np.concatenate(self.blocks)[:total]

    def _dry(self, i: int, lo: int, hi: int) -> np.ndarray:
        end = hi if self.stops[i] is None else min(hi, self.stops[i] + self.fade)  # type: ignore[operator]
        return dry_segment(self.waves[i](max(end, 0)), self.stops[i], lo, hi, self.ramp)

    def _render(self, j: int, pose: np.ndarray) -> np.ndarray:
        S, L = self.hop, self.length
        lo = j * S
        keys = [self.epochs[0].cache.keys(i, pose) for i in range(len(self.positions))]
        spectra = []
        for i in range(len(self.positions)):
            seg = self._dry(i, lo - (L - 1), lo + S)
            spectra.append(sfft.rfft(seg, self.n_fft) if seg.any() else None)
        out = np.zeros((S, 2), dtype=np.float32)
        zero_from = self._zero_from()
        for e, ep in enumerate(self.epochs):
            if len(self.epochs) > 1:
                nxt = self.epochs[e + 1].start if e + 1 < len(self.epochs) else None
                w = epoch_window(np.arange(lo, lo + S), ep.start if e else None, nxt, S)
                if not w.any():
                    continue
            new = _block(ep.cache, keys, spectra, self.n_fft, L, S)
            if self._prev is not None and self._prev != keys:
                old = _block(ep.cache, self._prev, spectra, self.n_fft, L, S)
                new = old + self._xfade * (new - old)
            if zero_from is not None and zero_from < lo + S:
                new[max(zero_from - lo, 0) :] = 0.0
            part = new.astype(np.float32)
            if len(self.epochs) > 1:
                out = (out.astype(np.float64) + part.astype(np.float64) * w[:, None]).astype(np.float32)
            else:
                out = part
        self._prev = keys
        if self.full_scale_db_spl is None:
            return out
        pressure = out.astype(np.float64)
        if self.noise is not None:
            pressure += self.noise.render(lo, S)
        # What is heard is what the WAV holds: 16-bit samples (features are computed from them).
        return as_written(to_full_scale(pressure, self.full_scale_db_spl, what=self.name), self.name)

    def _zero_from(self) -> int | None:
        """Sample from which the sources' part is exactly zero: every source stopped and its tail
        rung out (a noise bed goes on)."""
        if not self.positions or any(s is None for s in self._support_end):
            return None
        return max(s for s in self._support_end if s is not None) + self.length - 1


def epoch_window(t: np.ndarray, start: int | None, end: int | None, ramp: int) -> np.ndarray:
    """Weight of one geometry epoch at samples `t`: 1 inside [start, end), raised-cosine ramps of
    `ramp` samples centred on the boundaries (None = open-ended); consecutive epochs sum to 1."""
    t = np.asarray(t, dtype=np.float64)
    w = np.ones(len(t))
    for edge, rising in ((start, True), (end, False)):
        if edge is None:
            continue
        x = np.clip((t - (edge - ramp / 2)) / ramp, 0.0, 1.0)
        up = 0.5 - 0.5 * np.cos(np.pi * x)
        w *= up if rising else 1.0 - up
    return w


def render_track(
    scene: Any,
    sources: list[SourceTrack],
    poses: np.ndarray,
    step_samples: int,
    cfg: AcousticsConfig,
    hrtf: Hrtf | None = None,
    cache: RirCache | None = None,
) -> np.ndarray:
    """Binaural track (n_steps * step_samples + fade + RIR length - 1, 2) float32, channel 0 = left:
    `StreamRenderer` fed the whole path.

    `poses[i]` = [x, y, z, yaw] of the head during step i (samples [i * step, (i + 1) * step)).
    Pass `cache` to reuse RIRs across calls with the same scene and sources.
    """
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4)
    waves = [np.asarray(s.waveform, dtype=np.float64).ravel() for s in sources]
    r = StreamRenderer(scene, [s.position for s in sources], [_prefix(w) for w in waves], cfg, step_samples, hrtf, cache)
    n_play = len(poses) * r.hop
    for i, s in enumerate(sources):
        if s.stop_sample is not None:
            r.stop(i, min(max(int(s.stop_sample), 0), n_play))
    for pose in poses:
        r.step(pose)
    return r.finish()


def _prefix(w: np.ndarray) -> Wave:
    """A fixed signal as a `Wave`: n -> its first n samples."""
    return lambda n: w[:n]


def _block(
    cache: RirCache,
    keys: list[list[tuple[CacheKey, float]]],
    spectra: list[np.ndarray | None],
    n_fft: int,
    L: int,
    S: int,
) -> np.ndarray:
    """One output block (S, 2): the sum over sources of input x RIR (the weighted sum of the
    RIRs of its keys), overlap-save."""
    acc = None
    for kw, X in zip(keys, spectra):
        if X is None:
            continue
        for key, w in kw:
            spec = cache.spectrum(key, n_fft)
            wx = w * X
            term = np.empty_like(spec)  # (w X) H per ear: long contiguous loops, not (F, 1) x (F, 2) broadcasting
            np.multiply(wx, spec[:, 0], out=term[:, 0])
            np.multiply(wx, spec[:, 1], out=term[:, 1])
            if acc is None:
                acc = term
            else:
                acc += term
    if acc is None:
        return np.zeros((S, 2))
    return sfft.irfft(acc, n_fft, axis=0)[L - 1 : L - 1 + S]
