"""The camera learners per manipulation skill (issue 29's goal rows "each skill alone, from cameras
and proprioception"), closed loop: build the sanity episodes with the head and wrist depth cameras
on (recipes/cameras_*.yaml), train ACT on head depth, wrist depth, base-frame proprioception and
the target kind (no privileged column, no target position), choose the checkpoint closed loop on
the validation split, then score it on the test split (test sounds) alone and after a hand-over,
into studies/learners/results/camera_learners.json.

The same path, episodes and learner as studies/learners/sanity_learners.py (whose `CAMERAS` study this
runs): set beside its privileged rows, the two rows of a skill separate what the cameras cost from
what the demonstrations cannot teach. Resumable the same way.

Usage:
  python studies/learners/camera_learners.py --skills CloseSink OpenDoor --workers 2
  python studies/learners/camera_learners.py --tiny --skills CloseSink --work /tmp/c --out /tmp/c.json
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from sanity_learners import CAMERAS, main  # noqa: E402

if __name__ == "__main__":
    main(CAMERAS, __doc__)
