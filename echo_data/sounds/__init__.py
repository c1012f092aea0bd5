"""Sound library: synthesised instances per category, the user's WAV folders, train/test splits.

Public API: `SoundLibrary` (`builtin()`, `from_recipe()`, `instances()`, `get()`, `waveform()`),
`SoundInstance`, `SoundLibraryError`, `CATEGORY_COUNTS`, `PEAK_DBFS`.
"""

from echo_data.categories import CATEGORY_COUNTS
from echo_data.sounds.library import CATEGORIES, SPLITS, SoundInstance, SoundLibrary
from echo_data.sounds.synth import PEAK_DBFS
from echo_data.sounds.user_folders import SoundLibraryError

__all__ = ["CATEGORIES", "CATEGORY_COUNTS", "PEAK_DBFS", "SPLITS", "SoundInstance", "SoundLibrary", "SoundLibraryError"]
