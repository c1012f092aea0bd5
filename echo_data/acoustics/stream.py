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
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.fft as sfft

from echo_data.acoustics.binaural import binaural_irs, binaural_length
from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.types import AcousticResponse
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

    def rir(self, key: CacheKey) -> np.ndarray:
        """(length, 2) float32 binaural RIR for `key` (read-only)."""
        ir = self._rirs.get(key)
        if ir is None:
            _, yaw = self.receiver(key)
            self._store(key, binaural_irs(self.response(key), [yaw], self.hrtf)[0])
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
            irs = binaural_irs(self.response((*k5, 0)), yaws, self.hrtf)
            for key, ir in zip(ks, irs):
                if key not in self._rirs:
                    self._store(key, np.ascontiguousarray(ir))
                    new += 1
        return new


def dry_signal(track: SourceTrack, n_play: int, fs: int) -> np.ndarray:
    """The source's dry input as rendered: played until its stop (or `n_play`), then a 20 ms fade.

    Returns float64 of length n_play + fade; zero after the fade.
    """
    fade = int(round(FADE_S * fs))
    stop = n_play if track.stop_sample is None else min(max(int(track.stop_sample), 0), n_play)
    x = np.zeros(n_play + fade)
    w = np.asarray(track.waveform, dtype=np.float64).ravel()[: stop + fade]
    x[: len(w)] = w
    ramp = 0.5 * (1 + np.cos(np.pi * (np.arange(fade) + 0.5) / fade))
    x[stop : stop + fade] *= ramp
    x[stop + fade :] = 0.0
    return x


def render_track(
    scene: Any,
    sources: list[SourceTrack],
    poses: np.ndarray,
    step_samples: int,
    cfg: AcousticsConfig,
    hrtf: Hrtf | None = None,
    cache: RirCache | None = None,
) -> np.ndarray:
    """Binaural track (n_steps * step_samples + fade + RIR length - 1, 2) float32, channel 0 = left.

    `poses[i]` = [x, y, z, yaw] of the head during step i (samples [i * step, (i + 1) * step)).
    Pass `cache` to reuse RIRs across calls with the same scene and sources.
    """
    fs = int(cfg.sample_rate)
    hrtf = hrtf or Hrtf.load(cfg.hrtf, fs)
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4)
    n_steps, S = len(poses), int(step_samples)
    if cache is None:
        cache = RirCache(scene, [s.position for s in sources], cfg, hrtf)
    elif cache.positions != [tuple(float(v) for v in s.position) for s in sources]:
        raise ValueError("the RIR cache was made for other source positions")
    if cache.hrtf.fs != fs:
        raise ValueError(f"HRTF at {cache.hrtf.fs} Hz but the config asks for {fs} Hz")
    fade = int(round(FADE_S * fs))
    n_play = n_steps * S
    dry = [dry_signal(s, n_play, fs) for s in sources]
    L = cache.expected_length()
    total = n_play + fade + L - 1
    out = np.zeros((total, 2))
    if not sources or n_steps == 0:
        return out.astype(np.float32)
    n_fft = sfft.next_fast_len(S + L - 1, real=True)
    # input history: L - 1 zeros before t = 0, then the signal, then zeros to the last block
    n_blocks = -(-total // S)
    padded = [np.concatenate([np.zeros(L - 1), x, np.zeros(n_blocks * S - len(x))]) for x in dry]
    ramp = 0.5 * (1 - np.cos(np.pi * (np.arange(S) + 0.5) / S))[:, None]
    prev: list[list[tuple[CacheKey, float]]] | None = None
    for j in range(n_blocks):
        pose = poses[min(j, n_steps - 1)]
        keys = [cache.keys(i, pose) for i in range(len(sources))]
        spectra = []
        for x in padded:
            seg = x[j * S : j * S + S + L - 1]
            spectra.append(sfft.rfft(seg, n_fft) if seg.any() else None)
        new = _block(cache, keys, spectra, n_fft, L, S)
        if prev is not None and prev != keys:
            old = _block(cache, prev, spectra, n_fft, L, S)
            new = old + ramp * (new - old)
        hi = min((j + 1) * S, total)
        out[j * S : hi] = new[: hi - j * S]
        prev = keys
    end = max(_support_end(x) for x in dry) + L - 1  # past every source's last sample + RIR
    out[end:] = 0.0
    return out.astype(np.float32)


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
            term = (w * X)[:, None] * cache.spectrum(key, n_fft)
            acc = term if acc is None else acc + term
    if acc is None:
        return np.zeros((S, 2))
    return sfft.irfft(acc, n_fft, axis=0)[L - 1 : L - 1 + S]


def _support_end(x: np.ndarray) -> int:
    nz = np.flatnonzero(x)
    return int(nz[-1]) + 1 if nz.size else 0
