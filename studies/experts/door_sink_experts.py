"""OpenDoor and CloseSink experts alone: success from the interaction pose and from hand-over
starts anywhere in Navigate's success region, and how far their arm paths lie apart.

    python studies/experts/door_sink_experts.py recipes/state_transition.yaml -n 40 --start interaction
    python studies/experts/door_sink_experts.py recipes/state_transition.yaml -n 40 --start handover

For each train episode 0..n-1 of the recipe whose chain has an OpenDoor or CloseSink call (never
the test split: this is a development measurement), the expert runs alone in a physics-only
World (no cameras: the experts read the world, not images) from

- `interaction`: the target's interaction pose (`echo_data.scene.nav.interaction_pose`), where
  the scripted Navigate stops;
- `handover`: a point drawn (seeded by the episode) uniformly in the disc of Navigate's success
  radius around it, on free floor connected to it (not behind the closed door), facing the target up to the success test's heading tolerance
  (`echo_data.skills.success.navigate_success` holds there: a learned Navigate may stop anywhere
  it does).

It prints, per skill, successes k/n with Wilson 95 % intervals, the failure reasons, the steps
taken, and the path spread between episodes: the commanded arm joints aligned at the untuck's
first step, at phase steps 0, 10, ..., 60 the largest joint range across episodes (rad), and the
pairwise path gap of `echo_data.evaluation.path_spread.path_gap` (time shifts between phases do not count,
a detour does), over all episodes and per side (a door hinged on the robot's left is the mirror
image of one hinged on its right: its arm path is the mirrored one, a different but determined
path). `--json` writes the figures with the command and commit. `--expert SKILL=module:function`
runs another expert instead (a previous version, for a baseline measured the same way).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import math
import os
import subprocess
import time
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("LP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[2]
SKILLS = ("OpenDoor", "CloseSink")
PHASE_STEPS = (0, 10, 20, 30, 40, 50, 60)


def handover_start(world: Any, target: str, rng: np.random.Generator, tries: int = 200) -> tuple[float, float, float] | None:
    """A start drawn uniformly in Navigate's success disc around the interaction pose, on free
    floor connected to it and facing the target within the success test's tolerance; None when none is found."""
    from echo_data.scene.nav import interaction_pose, target_point
    from echo_data.skills.success import NAV_SUCCESS_DIST, NAV_SUCCESS_YAW, navigate_success

    x0, y0, _ = interaction_pose(world.plan, target)
    tx, ty = target_point(world.plan, target)
    for _ in range(tries):
        r = NAV_SUCCESS_DIST * math.sqrt(rng.uniform())
        a = rng.uniform(-math.pi, math.pi)
        x, y = x0 + r * math.cos(a), y0 + r * math.sin(a)
        if not world.nav.is_free(x, y) or not world.nav.connected((x, y), (x0, y0)):
            continue  # (the far side of the closed door is in the disc too, but no Navigate ends there)
        yaw = math.atan2(ty - y, tx - x) + rng.uniform(-1.0, 1.0) * 0.9 * NAV_SUCCESS_YAW
        world.robot.set_base_pose(x, y, yaw)
        if navigate_success(world, target):
            return (x, y, yaw)
    return None


def _side(spec: Any, call: Any) -> str:
    """Which hand of the scene the task is: a door hinged on the robot's left or right (mirror
    images, whose arm paths differ by the mirror, not by chance); one kind for a faucet."""
    from echo_data.target import Target

    if call.skill != "OpenDoor":
        return "faucet"
    return "hinge_right" if spec.plan.doors[Target.parse(call.target).index].open_sign > 0 else "hinge_left"


def run_one(recipe: Any, spec: Any, call: Any, start: str, expert: str | None = None) -> dict[str, Any]:
    """The expert of `call` alone from the chosen start; its outcome and commanded arm joints."""
    from echo_data.scene.nav import interaction_pose
    from echo_data.skill_table import Situation, skill
    from echo_data.world import World

    pose = interaction_pose(spec.plan, call.target)
    one = dataclasses.replace(spec, start=pose, chain=(call,))
    world = World(one, recipe, render=False)
    try:
        if start == "handover":
            drawn = handover_start(world, call.target, np.random.default_rng(spec.seed))
            if drawn is None:
                return {"skipped": "no hand-over start"}
            world.robot.set_base_pose(*drawn)
            pose = drawn
        world.settle(2)
        module, _, name = (expert or skill(call.skill).expert).partition(":")
        gen = getattr(importlib.import_module(module), name)(world, call, one)
        arms: list[list[float]] = []
        while True:
            try:
                a = np.asarray(next(gen), dtype=np.float32)
            except StopIteration as stop:
                outcome = stop.value
                break
            world.step(world.robot.ee.to_joint(a) if a.shape == (11,) else a)
            arms.append(world.robot.applied_action()[4:11].astype(float).tolist())
        ok = bool(skill(call.skill).success(world, call, Situation(one, lambda: None)))
        return {"success": bool(outcome.success and ok), "reason": outcome.reason, "steps": outcome.steps, "arms": arms,
                "start": list(pose), "side": _side(spec, call)}
    finally:
        world.close()


def spread(paths: list[np.ndarray]) -> dict[str, Any]:
    """Joint range across episodes at phase steps from the untuck's start, and pairwise path gaps."""
    from echo_data.evaluation.path_spread import joint_range_at_steps, path_gap

    gaps = [path_gap(a, b) for i, a in enumerate(paths) for b in paths[i + 1 :]]
    return {"joint_range_at_step": {str(k): round(v, 4) for k, v in joint_range_at_steps(paths, PHASE_STEPS).items()},
            "path_gap_median": round(float(np.median(gaps)), 4) if gaps else None,
            "path_gap_max": round(float(np.max(gaps)), 4) if gaps else None, "pairs": len(gaps)}


def main() -> None:
    from echo_data.evaluation.metrics import wilson
    from echo_data.recipe import load_recipe
    from echo_data.scene.sampling import SamplingError, sample_episode
    from echo_data.sounds import SoundLibrary

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe")
    ap.add_argument("-n", type=int, default=20, help="train episodes 0..n-1 (those with a door or sink call run)")
    ap.add_argument("--start", choices=("interaction", "handover"), default="interaction")
    ap.add_argument("--json", default=None, help="write the figures here")
    ap.add_argument("--expert", action="append", default=[], metavar="SKILL=module:function",
                    help="run another expert for SKILL (e.g. a previous version, as a baseline)")
    a = ap.parse_args()
    path = Path(a.recipe).resolve()
    recipe = load_recipe(path)
    library = SoundLibrary.from_recipe(recipe, path.parent)
    experts = dict(e.split("=", 1) for e in a.expert)
    per: dict[str, list[dict[str, Any]]] = {s: [] for s in SKILLS}
    t0 = time.perf_counter()
    for i in range(a.n):
        try:
            spec, _ = sample_episode(recipe, "train", i, library)
        except SamplingError:
            continue
        for call in spec.chain:
            if call.skill in SKILLS:
                r = run_one(recipe, spec, call, a.start, experts.get(call.skill))
                r["index"] = i
                per[call.skill].append(r)
                print(f"episode {i:4d} {call.skill:9s} {r.get('skipped') or ('ok' if r['success'] else 'FAILED ' + r['reason'])}"
                      f" steps {r.get('steps', 0)}", flush=True)
    extra = "".join(f" --expert {e}" for e in a.expert)
    out: dict[str, Any] = {"command": f"python studies/experts/door_sink_experts.py {a.recipe} -n {a.n} --start {a.start}{extra}",
                           "commit": subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip(),
                           "seconds": round(time.perf_counter() - t0, 1), "skills": {}}
    for s, runs in per.items():
        done = [r for r in runs if "skipped" not in r]
        if not done:
            continue
        k = sum(r["success"] for r in done)
        lo, hi = wilson(k, len(done))
        fails: dict[str, int] = {}
        for r in done:
            if not r["success"]:
                fails[r["reason"]] = fails.get(r["reason"], 0) + 1
        ok_paths = [np.asarray(r["arms"]) for r in done if r["success"]]
        out["skills"][s] = {
            "successes": k, "n": len(done), "low": round(lo, 3), "high": round(hi, 3), "skipped": len(runs) - len(done),
            "failures": fails, "failed_episodes": [r["index"] for r in done if not r["success"]],
            "steps_max": max(r["steps"] for r in done), "steps_median": float(np.median([r["steps"] for r in done])),
            "spread": spread(ok_paths) if len(ok_paths) > 1 else None,
            "spread_by_side": {side: spread(p) for side in sorted({r["side"] for r in done})
                               if len(p := [np.asarray(r["arms"]) for r in done if r["success"] and r["side"] == side]) > 1},
        }
        print(s, json.dumps(out["skills"][s]))
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
