"""What a recorded episode run holds (`Rollout`) and a digest that tells two runs apart.

Episodes are run by `echo_data.agents.runtime.run_episode` in the environment
(`echo_data.app.pipeline.simulate` records the experts' runs as `Rollout`s).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from echo_data.records import SkillOutcome, StepRecord


@dataclass
class Rollout:
    """What a chain produced: per-step records, per-skill outcomes, when each event resolved."""

    steps: list[StepRecord]
    outcomes: list[SkillOutcome]
    resolved_frame: list[int | None]  # per event: frame index at which its sound stops
    chain_length: int
    # (frame, hinge angles of every door) after each successful OpenDoor: the acoustics
    # switch to the opened geometry from that frame on.
    door_changes: list[tuple[int, dict[int, float]]] = field(default_factory=list)
    # What the robot heard (when the run had ears): the finished track, each step's sample
    # offset into it and the per-step features its observations carried.
    audio: np.ndarray | None = None
    audio_offsets: np.ndarray | None = None
    spectrogram: np.ndarray | None = None
    mel: np.ndarray | None = None
    truncated_at: int | None = None  # steps run when the recipe's `outputs.max_frames` cut the chain

    @property
    def success(self) -> bool:
        """The episode succeeds when every skill of the chain succeeded, in order."""
        return len(self.outcomes) == self.chain_length and all(o.success for o in self.outcomes)


def records_digest(steps: list[StepRecord]) -> str:
    """sha256 over every field of every step record: equal digests mean bit-identical rollouts."""
    import hashlib

    h = hashlib.sha256()
    for s in steps:
        h.update(f"{s.frame_index}|{s.timestamp!r}|{s.skill}|{s.skill_index}|{s.ear_position!r}|{s.ear_yaw!r}|{s.sounding}|{s.skill_success}|{s.done}".encode())
        for arr in (s.action, s.state, s.head_rgb, s.head_depth, s.wrist_depth):
            if arr is not None:
                a = np.ascontiguousarray(arr)
                h.update(f"{a.dtype}{a.shape}".encode())
                h.update(a.tobytes())
    return h.hexdigest()
