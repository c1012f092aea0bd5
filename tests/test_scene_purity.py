"""The plan side of `echo_data.scene` (floor plan, layouts, generation, surfaces, object catalogue,
navigation, the episode draw) is pure by its import graph: it imports and draws whole episodes
in a process where SAPIEN cannot be imported at all."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PLAN_SIDE = ("layouts", "structure", "furniture", "soft_furnishings", "generate", "surfaces", "objects", "nav", "door_handle", "draw")

PROBE = f"""
import sys
sys.modules["sapien"] = None  # any import of sapien now raises ImportError
import importlib
for name in {PLAN_SIDE!r}:
    importlib.import_module("echo_data.scene." + name)
from echo_data.episode import attempt_draws
from echo_data.recipe import Recipe
from echo_data.scene.draw import Reject, draw_episode
from echo_data.sounds import SoundLibrary
recipe = Recipe(name="purity", setting="multi_event")
drawn = rejected = 0
for k, seed in attempt_draws(recipe.seed, "train", 0, 0, 8):
    try:
        spec = draw_episode(recipe, "train", 0, k, seed, SoundLibrary.builtin())
        drawn += 1
    except Reject:
        rejected += 1
assert "sapien" not in {{m.split(".")[0] for m, v in sys.modules.items() if v is not None}}
print(drawn, rejected, len(spec.chain) if drawn else 0)
"""


def test_plan_side_runs_without_sapien() -> None:
    r = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    drawn, rejected, chain = (int(v) for v in r.stdout.split())
    assert drawn >= 1 and drawn + rejected == 8 and chain >= 4


def test_probe_fails_when_a_plan_module_needs_sapien() -> None:
    r = subprocess.run([sys.executable, "-c", 'import sys; sys.modules["sapien"] = None; import echo_data.scene.sampling'], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert r.returncode != 0 and "sapien" in r.stderr  # the SAPIEN side really does need it
