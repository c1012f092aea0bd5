"""Every derived random stream, named once: a salt per purpose, appended to the keys it is derived
from (`numpy.random.SeedSequence([*keys, salt])`).

Two streams with different salts are independent even from the same seed, so adding a draw for
one purpose never shifts another's. An episode's own seeds come from
`echo_data.episode.attempt_draws`; everything random inside it (lighting, wet floors, the
reverberant tail's noise, the diffuse-field noise, the noise floor) is salted here, and so are
the learners' splits. Changing a salt changes the bytes of every dataset: never reuse or edit one.
"""

from __future__ import annotations

import numpy as np

LIGHTING = 0x11647  # scene/lighting: light colours and directions (keys: plan seed)
FURNISHINGS = 0x50F7  # scene/generate: rugs and curtains (keys: plan seed)
WET_FLOORS = 0x3E7F  # scene/generate: tiles in kitchens and bathrooms (keys: plan seed)
TAIL_NOISE = 0x7A11  # acoustics/tail: band noises of the late reverberation (keys: scene seed mod 2^32)
DIFFUSE_NOISE = 0xD1FF  # acoustics/hrtf: diffuse-field binaural noise (keys: seed mod 2^63)
NOISE_FLOOR = 0x0F10  # acoustics/noise: noise-floor blocks (keys: seed, block + 2^40)
HELD_OUT_SOUNDS = 0x50D5  # learn/planner: sounds held out of training (keys: seed)
SUBSET = 0x5EB5E7  # learn/planner: nested training subsets (keys: seed)
FRESH_SOUND = 0xF8E5  # episode.fresh_sound_seed: a train event's fresh sound instance (keys: draw seed, event)
ACTION_NOISE = 0xDA27  # agents/dart: the experts' DART action noise (keys: episode seed)
EE_PERTURBATION = 0xEE9E  # agents/dart: the experts' end-effector perturbation (keys: episode seed)
HANDOVER = 0x4A0D  # skills/navigate: the build's Navigate stop point in its success region (keys: episode seed, chain index)


def derived_rng(salt: int, *keys: int) -> np.random.Generator:
    """The generator of purpose `salt` for `keys` (see the module docstring)."""
    return np.random.default_rng(np.random.SeedSequence([*(int(k) for k in keys), salt]))
