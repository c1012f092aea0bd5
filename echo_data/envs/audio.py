"""What the robot hears, rendered one control step at a time from the poses it actually reaches.

`OnlineTrack` is the episode's binaural track as a stream: each `step(pose)` renders the next
control period with the acoustics' streaming renderer (`echo_data.acoustics.stream`: the same
`RirCache` lattice, overlap-save blocks, whole-step crossfades between cached RIRs and 20 ms stop
fades), knowing nothing of later poses. It is the only way an episode track is made: the build
(through the environment), `echo_data.app.pipeline.render_episode_audio` and the environment all use
it, and a test checks it block for block against the offline `render_track`.

Episode-level rules live here too:
- a pre-roll: every event has sounded for `PRE_ROLL_SECONDS` (head at its start pose) when the
  robot takes its first observation, so the first spectrogram already holds a second of sound;
- a source stops (its dry signal fades over 20 ms; its reverberation rings on) from the control
  step after its event is resolved;
- levels are calibrated: each source plays at its drawn level in dB SPL at 1 m
  (`echo_data.acoustics.levels`), a seeded room-noise bed is added, and samples are pressure
  over the full-scale pressure (`ClippingError` rather than a clipped sample);
- an opened door changes the acoustic geometry: each door state is its own `AcousticScene`
  (epoch), joined to the previous one by a raised-cosine crossfade one control step long,
  centred on the step boundary at which the door was found open.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.fft as sfft

from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.levels import pascal_gain, source_level_db, to_full_scale
from echo_data.acoustics.noise import NoiseFloor
from echo_data.acoustics.room import AcousticScene
from echo_data.acoustics.stream import FADE_S, CacheKey, RirCache, _block
from echo_data.episode import EpisodeSpec
from echo_data.pcm import as_written
from echo_data.recipe import Recipe

# The event has been sounding for this long when the robot's first observation is taken.
PRE_ROLL_SECONDS = 1.0


def step_samples(recipe: Recipe) -> int:
    """Audio samples per control step."""
    return recipe.acoustics.sample_rate // recipe.robot.control_hz


def pre_roll_steps(recipe: Recipe) -> int:
    """Control periods of pre-roll before the first observation."""
    return int(round(PRE_ROLL_SECONDS * recipe.robot.control_hz))


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


def event_gain(spec: EpisodeSpec, e: int, library: Any, fs: int) -> float:
    """Factor from event `e`'s library loop to pascals at 1 m at its drawn source level."""
    ev = spec.events[e]
    return pascal_gain(library.waveform(ev.sound_id, fs), fs, source_level_db(ev.category, spec.plan.seed, e))


def event_waveform(spec: EpisodeSpec, e: int, library: Any, fs: int, seconds: float) -> np.ndarray:
    """Event `e`'s dry signal in pascals at 1 m, `seconds` long (float32), at its calibrated level."""
    gain = event_gain(spec, e, library, fs)
    return library.waveform(spec.events[e].sound_id, fs, seconds) * np.float32(gain)


@dataclass
class _Epoch:
    start: int  # first sample of this door state (boundary of the crossfade)
    cache: RirCache


class OnlineTrack:
    """The binaural track of one episode, rendered causally, one control step per call."""

    def __init__(self, spec: EpisodeSpec, recipe: Recipe, library: Any, hrtf: Hrtf | None = None) -> None:
        cfg = recipe.acoustics
        self.cfg = cfg
        self.fs = int(cfg.sample_rate)
        self.hop = step_samples(recipe)
        self.pre_steps = pre_roll_steps(recipe)
        self.hrtf = hrtf or Hrtf.load(cfg.hrtf, self.fs)
        self.plan = spec.plan
        self.library = library
        self.sound_ids = [ev.sound_id for ev in spec.events]
        self.positions = [tuple(float(v) for v in ev.source) for ev in spec.events]
        self.gains = [np.float32(event_gain(spec, e, library, self.fs)) for e in range(len(spec.events))]
        self.noise = NoiseFloor(self.fs, cfg.noise_floor_dba, spec.plan.seed, self.hrtf)
        self.episode_id = spec.episode_id
        self.epochs: list[_Epoch] = []
        self._new_epoch(0, None)
        self.length = self.epochs[0].cache.expected_length()  # binaural RIR length L
        self.n_fft = sfft.next_fast_len(self.hop + self.length - 1, real=True)
        self.fade = int(round(FADE_S * self.fs))
        self._fade_ramp = 0.5 * (1 + np.cos(np.pi * (np.arange(self.fade) + 0.5) / self.fade))
        self._xfade = 0.5 * (1 - np.cos(np.pi * (np.arange(self.hop) + 0.5) / self.hop))[:, None]
        self._waves: list[np.ndarray] = [np.zeros(0) for _ in self.sound_ids]
        self.stops: list[int | None] = [None] * len(self.sound_ids)
        self._support_end: list[int | None] = [None] * len(self.sound_ids)
        self.blocks: list[np.ndarray] = []
        self._prev: list[list[tuple[CacheKey, float]]] | None = None
        self._last_pose: np.ndarray | None = None

    # ------------------------------------------------------------------ episode events
    @property
    def samples(self) -> int:
        """Samples rendered so far (always a whole number of control periods)."""
        return len(self.blocks) * self.hop

    def _new_epoch(self, start: int, door_angles: dict[int, float] | None) -> None:
        scene = AcousticScene(self.plan, self.cfg, door_angles=door_angles)
        self.epochs.append(_Epoch(start, RirCache(scene, self.positions, self.cfg, self.hrtf)))

    def open_doors(self, door_angles: dict[int, float], at: int) -> None:
        """The doors stand at `door_angles` from sample `at` on (a new acoustic epoch, crossfaded over
        one control step centred on `at`; `at` must lie half a step past what is rendered)."""
        if at - self.hop // 2 < self.samples:
            raise ValueError(f"door change at sample {at} is not in the future (rendered {self.samples})")
        self._new_epoch(int(at), dict(door_angles))

    def stop(self, event: int) -> None:
        """Event `event`'s source stops sounding from the next control step on (no-op if stopped)."""
        if self.stops[event] is not None:
            return
        stop = self.samples
        self.stops[event] = stop
        dry = self._dry(event, 0, stop + self.fade)
        nz = np.flatnonzero(dry)
        self._support_end[event] = int(nz[-1]) + 1 if nz.size else 0

    # ------------------------------------------------------------------ rendering
    def pre_roll(self, pose: Sequence[float]) -> None:
        """Render the pre-roll with the head at `pose` [x, y, z, yaw]."""
        for _ in range(self.pre_steps):
            self.step(pose)

    def step(self, pose: Sequence[float]) -> np.ndarray:
        """Render the next control period heard at head pose [x, y, z, yaw]; returns it (hop, 2) float32."""
        head = np.asarray(pose, dtype=np.float64).reshape(4)
        self._last_pose = head
        block = self._render(len(self.blocks), head)
        self.blocks.append(block)
        return block

    def _wave(self, i: int, n: int) -> np.ndarray:
        """The first `n` samples of source i's calibrated looped waveform in pascals (float64; the
        loop is prefix-stable, so this equals `event_waveform` sample for sample)."""
        w = self._waves[i]
        if len(w) < n:
            want = max(n, 2 * len(w), 60 * self.fs)
            w = np.asarray(self.library.waveform(self.sound_ids[i], self.fs, want / self.fs) * self.gains[i], dtype=np.float64)
            self._waves[i] = w
        return w[:n]

    def _dry(self, i: int, lo: int, hi: int) -> np.ndarray:
        """Source i's dry input over samples [lo, hi) as `stream.dry_signal` defines it (zero before 0)."""
        seg = np.zeros(hi - lo)
        stop = self.stops[i]
        a = max(lo, 0)
        end = hi if stop is None else min(hi, stop + self.fade)
        if end > a:
            seg[a - lo : end - lo] = self._wave(i, end)[a:end]
            if stop is not None:
                f0, f1 = max(stop, a), end
                if f1 > f0:
                    seg[f0 - lo : f1 - lo] *= self._fade_ramp[f0 - stop : f1 - stop]
        return seg

    def _render(self, j: int, pose: np.ndarray) -> np.ndarray:
        S, L = self.hop, self.length
        lo = j * S
        keys = [self.epochs[0].cache.keys(i, pose) for i in range(len(self.positions))]
        spectra = []
        for i in range(len(self.positions)):
            seg = self._dry(i, lo - (L - 1), lo + S)
            spectra.append(sfft.rfft(seg, self.n_fft) if seg.any() else None)
        t = np.arange(lo, lo + S)
        out = np.zeros((S, 2), dtype=np.float32)
        zero_from = self._zero_from()
        for e, ep in enumerate(self.epochs):
            w = epoch_window(t, ep.start if e else None, self.epochs[e + 1].start if e + 1 < len(self.epochs) else None, S)
            if not w.any():
                continue
            new = _block(ep.cache, keys, spectra, self.n_fft, L, S)
            if self._prev is not None and self._prev != keys:
                old = _block(ep.cache, self._prev, spectra, self.n_fft, L, S)
                new = old + self._xfade * (new - old)
            if zero_from is not None and zero_from < lo + S:
                new[max(zero_from - lo, 0) :] = 0.0
            part = new.astype(np.float32)
            acc = out.astype(np.float64) + part.astype(np.float64) * w[:, None]
            out = acc.astype(np.float32)
        self._prev = keys
        pressure = out.astype(np.float64) + self.noise.render(lo, S)
        # What the robot hears is what the WAV holds: 16-bit samples (the features of every step
        # are computed from them, so stored spectrograms match the file and the env the dataset).
        what = f"episode {self.episode_id}"
        return as_written(to_full_scale(pressure, self.cfg.full_scale_db_spl, what=what), what)

    def _zero_from(self) -> int | None:
        """Sample from which the sources' part is exactly zero: every source stopped and its tail
        rung out (the noise bed goes on)."""
        if not self.positions or any(s is None for s in self._support_end):
            return None
        return max(s for s in self._support_end if s is not None) + self.length - 1

    # ------------------------------------------------------------------ read-out
    def last_second(self) -> np.ndarray:
        """The last second rendered, (fs, 2) float32, zero-padded in front."""
        out = np.zeros((self.fs, 2), dtype=np.float32)
        k = -(-self.fs // self.hop)
        tail = np.concatenate(self.blocks[-k:]) if self.blocks else np.zeros((0, 2), np.float32)
        n = min(len(tail), self.fs)
        if n:
            out[self.fs - n :] = tail[len(tail) - n :]
        return out

    def finish(self) -> np.ndarray:
        """The whole track: stop every source at the end of the last step, render until every tail
        has rung out (last head pose held). (n_steps * hop + 20 ms fade + RIR length - 1, 2) float32."""
        n_play = self.samples
        for i in range(len(self.positions)):
            self.stop(i)
        total = n_play + self.fade + self.length - 1
        pose = self._last_pose if self._last_pose is not None else np.zeros(4)
        while self.samples < total:
            self.blocks.append(self._render(len(self.blocks), pose))
        track = np.concatenate(self.blocks)[:total] if self.blocks else np.zeros((total, 2), np.float32)
        return track

    def offsets(self, n_steps: int) -> np.ndarray:
        """Sample index of each observation's step start (after the pre-roll)."""
        return (self.pre_steps + np.arange(n_steps, dtype=np.int64)) * self.hop
