"""What the robot hears in an episode: the acoustics' one renderer set up with the episode's rules.

`OnlineTrack` is the episode's binaural track as a stream: `echo_data.acoustics.stream.StreamRenderer`
(the same `RirCache` lattice, overlap-save blocks, whole-step crossfades between cached RIRs and
20 ms stop fades) fed the episode's sources, one control step per call, knowing nothing of later
poses. The environment, `echo_data.app.pipeline.render_episode_audio` and `echo-data preview` use it;
`render_track` is the same renderer fed a whole path.

Episode-level rules live here:
- a pre-roll: every event has sounded for `PRE_ROLL_SECONDS` (head at its start pose) when the
  robot takes its first observation, so the first spectrogram already holds a second of sound;
- a source stops (its dry signal fades over 20 ms; its reverberation rings on) from the control
  step after its event is resolved;
- levels are calibrated: each source plays at the level its spec carries (`SoundEvent.level_db`,
  dB SPL at 1 m, drawn by `echo_data.acoustics.levels`), a seeded room-noise bed is added, and samples are
  pressure over the full-scale pressure (`ClippingError` rather than a clipped sample);
- an opened door changes the acoustic geometry: each door state is its own `AcousticScene`
  (epoch), joined to the previous one by a raised-cosine crossfade one control step long,
  centred on the step boundary at which the door was found open.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator, Sequence
from concurrent.futures import Future
from typing import Any

import numpy as np

from echo_data.acoustics.features import FeatureStream
from echo_data.acoustics.hrtf import Hrtf
from echo_data.acoustics.levels import pascal_gain
from echo_data.acoustics.noise import NoiseFloor
from echo_data.acoustics.room import AcousticScene
from echo_data.acoustics.stream import CacheKey, StreamRenderer, epoch_window  # noqa: F401  (epoch_window re-exported)
from echo_data.episode import EpisodeSpec
from echo_data.recipe import Recipe

# The event has been sounding for this long when the robot's first observation is taken.
PRE_ROLL_SECONDS = 1.0

Heard = tuple[np.ndarray, np.ndarray, np.ndarray]  # (block (hop, 2), spectrogram, log-mel) of one control step


def step_samples(recipe: Recipe) -> int:
    """Audio samples per control step."""
    return recipe.acoustics.sample_rate // recipe.robot.control_hz


def pre_roll_steps(recipe: Recipe) -> int:
    """Control periods of pre-roll before the first observation."""
    return int(round(PRE_ROLL_SECONDS * recipe.robot.control_hz))


def event_gain(spec: EpisodeSpec, e: int, library: Any, fs: int) -> float:
    """Factor from event `e`'s library loop to pascals at 1 m at its drawn source level."""
    return pascal_gain(library.waveform(spec.events[e].sound_id, fs), fs, spec.source_level(e))


def event_waveform(spec: EpisodeSpec, e: int, library: Any, fs: int, seconds: float) -> np.ndarray:
    """Event `e`'s dry signal in pascals at 1 m, `seconds` long (float32), at its calibrated level."""
    gain = event_gain(spec, e, library, fs)
    return library.waveform(spec.events[e].sound_id, fs, seconds) * np.float32(gain)


class _Loop:
    """A source's calibrated looped waveform in pascals, grown on demand (the loop is
    prefix-stable, so any prefix equals `event_waveform` sample for sample)."""

    def __init__(self, library: Any, sound_id: str, gain: np.float32, fs: int) -> None:
        self.library, self.sound_id, self.gain, self.fs = library, sound_id, gain, fs
        self.w = np.zeros(0)

    def __call__(self, n: int) -> np.ndarray:
        if len(self.w) < n:
            want = max(n, 2 * len(self.w), 60 * self.fs)
            self.w = np.asarray(self.library.waveform(self.sound_id, self.fs, want / self.fs) * self.gain, dtype=np.float64)
        return self.w[:n]


class OnlineTrack(StreamRenderer):
    """The binaural track of one episode, rendered causally, one control step per call, as written."""

    def __init__(self, spec: EpisodeSpec, recipe: Recipe, library: Any, hrtf: Hrtf | None = None) -> None:
        cfg = recipe.acoustics
        fs = int(cfg.sample_rate)
        hrtf = hrtf or Hrtf.load(cfg.hrtf, fs)
        waves = [_Loop(library, ev.sound_id, np.float32(event_gain(spec, e, library, fs)), fs) for e, ev in enumerate(spec.events)]
        super().__init__(
            AcousticScene(spec.plan, cfg),
            [ev.source for ev in spec.events],
            waves,
            cfg,
            step_samples(recipe),
            hrtf,
            noise=NoiseFloor(fs, cfg.noise_floor_dba, spec.plan.seed, hrtf),
            full_scale_db_spl=cfg.full_scale_db_spl,
            name=f"episode {spec.episode_id}",
        )
        self.plan = spec.plan
        self.pre_steps = pre_roll_steps(recipe)
        self._features = FeatureStream(fs, cfg.mel_bands)
        self._lock = threading.RLock()  # the listening thread's idle work and the caller take turns
        self._turn = 0.0  # the head's last yaw change (rad): which way the next yaw bins lie

    def step(self, pose: Sequence[float]) -> np.ndarray:
        with self._lock:
            if self._last_pose is not None:
                self._turn = math.remainder(float(pose[3]) - float(self._last_pose[3]), 2 * math.pi)
            return super().step(pose)

    def stop(self, i: int, at: int | None = None) -> None:
        with self._lock:
            super().stop(i, at)

    def new_epoch(self, scene: Any, at: int) -> None:
        with self._lock:
            super().new_epoch(scene, at)

    def finish(self) -> np.ndarray:
        with self._lock:
            return super().finish()

    def open_doors(self, door_angles: dict[int, float], at: int) -> None:
        """The doors stand at `door_angles` from sample `at` on (a new acoustic epoch, crossfaded over
        one control step centred on `at`; `at` must lie half a step past what is rendered)."""
        if at - self.hop // 2 < self.samples:
            raise ValueError(f"door change at sample {at} is not in the future (rendered {self.samples})")
        self.new_epoch(AcousticScene(self.plan, self.cfg, door_angles=dict(door_angles)), int(at))

    def pre_roll(self, pose: Sequence[float]) -> None:
        """Render the pre-roll with the head at `pose` [x, y, z, yaw]."""
        for _ in range(self.pre_steps):
            self.step(pose)

    def hear(self, pose: Sequence[float], doors: Sequence[dict[int, float]] = (), silenced: Sequence[int] = ()) -> Heard:
        """One control step as the environment hears it: the doors found open at this step's end
        (one new epoch each, from the next step boundary), the block heard at `pose` [x, y, z, yaw],
        the events resolved at this step falling silent from the next block, and the features of
        the last second. The same calls, in the same order, as a caller making them one by one."""
        for angles in doors:
            self.open_doors(angles, at=self.samples + self.hop)
        block = self.step(pose)
        for e in silenced:
            self.stop(e)
        spec, mel = self.features()
        return block, spec, mel

    def hear_soon(self, pose: Sequence[float], doors: Sequence[dict[int, float]] = (), silenced: Sequence[int] = ()) -> Future[Heard]:
        """`hear` on this process's listening thread; the caller renders meanwhile and takes
        `.result()` before touching the track again (values identical to `hear`: same calls,
        same order, one thread at a time)."""
        from echo_data.envs.listener import listener, listener_enabled, run_now

        args = (tuple(float(v) for v in pose), [dict(d) for d in doors], list(silenced))
        if not listener_enabled():
            return run_now(self.hear, *args)
        return listener().submit(self.hear, *args, idle=self)

    def prefetch_one(self) -> bool:
        """Idle-time work (`echo_data.envs.listener`): the RIR and spectrum of one key the head will
        probably need next (at the last pose's cell, the yaw bins beyond the two in use, nearest
        first, ahead of the last turn before behind it); False when they are all cached. A key's
        RIR is a pure function of the key, so this changes when it is computed, never its value."""
        with self._lock:
            if self._last_pose is None:
                return False
            cache = self.epochs[-1].cache
            for key in self._next_keys():
                if not cache.has_spectrum(key, self.n_fft):
                    cache.spectrum(key, self.n_fft)
                    return True
            return False

    def _next_keys(self) -> Iterator[CacheKey]:
        """Per source, the bins next to the pair in use: +1, +2 in the direction of the last turn, then -1."""
        assert self._last_pose is not None
        cache, n = self.epochs[0].cache, int(self.cfg.yaws)
        ahead = 1 if self._turn >= 0 else -1
        in_use = [cache.keys(i, self._last_pose) for i in range(len(self.positions))]
        for offset in (1, 2, -1):
            for kw in in_use:
                bins = [k[5] for k, _ in kw]  # ascending yaw (mod n): one bin, or the pair around the yaw
                edge = bins[-1] if offset * ahead > 0 else bins[0]
                yield (*kw[0][0][:5], (edge + offset * ahead) % n)

    def heard(self) -> Future[Heard]:
        """The last block rendered and the features of the last second, as a finished `Future`
        (the observation of a reset, after the pre-roll)."""
        from echo_data.envs.listener import run_now

        return run_now(lambda: (self.blocks[-1], *self.features()))

    def last_second(self) -> np.ndarray:
        """The last second rendered, (fs, 2) float32, zero-padded in front."""
        out = np.zeros((self.fs, 2), dtype=np.float32)
        k = -(-self.fs // self.hop)
        tail = np.concatenate(self.blocks[-k:]) if self.blocks else np.zeros((0, 2), np.float32)
        n = min(len(tail), self.fs)
        if n:
            out[self.fs - n :] = tail[len(tail) - n :]
        return out

    def features(self) -> tuple[np.ndarray, np.ndarray]:
        """(spectrogram, log-mel) of the last second heard: what `step_features` gives at this
        offset of the finished track, with the frames of earlier steps reused."""
        return self._features.features(self.last_second(), self.samples)

    def offsets(self, n_steps: int) -> np.ndarray:
        """Sample index of each observation's step start (after the pre-roll)."""
        return (self.pre_steps + np.arange(n_steps, dtype=np.int64)) * self.hop
