"""How far the scripted experts drive the base inside each manipulation skill, when the skill
starts at its target's interaction pose and when it starts anywhere in its stance (the hand-over
region, docs/handover.md).

Why: a manipulation learner clones its skill's segment, base motion included. Whatever the expert
drives inside the segment, the manipulation learner has to learn to drive; the drive learners
(Navigate) end where the segment starts. This measures, per skill, the base path and turn the
demonstrations hold after the hand-over, on the test split of the shipped setting recipes (the
experts with the scripted planner; nothing rendered, no audio: the motion does not depend on them).

Usage:
  python studies/handover/drives.py --episodes 10 --out studies/handover/results/drives.json
  python studies/handover/drives.py --episodes 1 --settings state_transition --out /tmp/d.json   # tiny
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from runner import ROOT, commit  # noqa: E402

sys.path.insert(0, str(ROOT))
SETTINGS = ("state_transition", "object_relocation")
NOISES = (0.0, 1.0)  # experts.handover_noise: the exact pose, anywhere in the stance


def segments(setting: str, noise: float, episodes: int) -> list[dict[str, Any]]:
    """One record per manipulation segment of the experts' episodes 0..episodes-1 (test split)."""
    from echo_data.agents.builtin import OraclePlanner, OracleSkills
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv, resolve_recipe
    from echo_data.skill_table import SKILLS
    from echo_data.skills.success import stance_offset

    recipe, _ = resolve_recipe(ROOT / "recipes" / f"{setting}.yaml")
    recipe = recipe.model_copy(update={"experts": recipe.experts.model_copy(update={"handover_noise": noise})})
    env = EchoDataEnv(recipe, split="test", images=False, audio=False)
    out = []
    try:
        for i in range(episodes):
            obs, info = env.reset(options={"split": "test", "index": i})
            poses: dict[int, list[tuple[float, float, float]]] = {}
            starts: dict[int, tuple[float, float] | None] = {}

            def hook(e: Any, o: Any, a: Any, k: int, call: Any, flags: Any, poses: dict = poses, starts: dict = starts) -> None:
                if k not in poses:
                    starts[k] = stance_offset(e.world, call.target, e.nav_grid())
                poses.setdefault(k, []).append(e.world.robot.base_pose())

            run = run_episode(env, obs, info, OraclePlanner(), OracleSkills(), on_step=hook)
            for k, p in poses.items():
                call = env.episode.chain[k]
                if SKILLS[call.skill].stance is None or k >= len(run.outcomes):
                    continue
                start = starts[k]
                out.append({
                    "episode": i, "skill": call.skill, "success": run.outcomes[k].success, "steps": len(p),
                    "path_m": sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(p, p[1:])),
                    "turn_deg": math.degrees(sum(abs(math.remainder(b[2] - a[2], 2 * math.pi)) for a, b in zip(p, p[1:]))),
                    "start_offset_m": None if start is None else start[0],
                    "start_heading_deg": None if start is None else math.degrees(start[1]),
                })
    finally:
        env.close()
    return out


def summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per skill: segments, expert successes, median and largest base path and turn."""
    def med(xs: list[float]) -> float:
        xs = sorted(xs)
        return xs[len(xs) // 2] if len(xs) % 2 else (xs[len(xs) // 2 - 1] + xs[len(xs) // 2]) / 2

    out = {}
    for s in sorted({r["skill"] for r in rows}):
        rs = [r for r in rows if r["skill"] == s]
        out[s] = {"segments": len(rs), "expert_success": sum(r["success"] for r in rs),
                  "path_m": {"median": med([r["path_m"] for r in rs]), "max": max(r["path_m"] for r in rs)},
                  "turn_deg": {"median": med([r["turn_deg"] for r in rs]), "max": max(r["turn_deg"] for r in rs)}}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=10, help="test episodes per setting and start")
    ap.add_argument("--settings", default=",".join(SETTINGS), help="setting recipes (recipes/<name>.yaml)")
    ap.add_argument("--out", type=Path, required=True, help="results JSON")
    a = ap.parse_args()
    t0 = time.perf_counter()
    runs = {}
    for noise in NOISES:
        rows = [r for s in a.settings.split(",") for r in segments(s, noise, a.episodes)]
        runs["exact pose" if noise == 0 else "anywhere in the stance"] = {"handover_noise": noise, "skills": summary(rows), "segments": rows}
    doc = {"commit": commit(), "command": f"python studies/handover/drives.py --episodes {a.episodes} --settings {a.settings} --out {a.out.name}",
           "episodes_per_setting": a.episodes, "settings": a.settings.split(","), "starts": runs, "seconds": round(time.perf_counter() - t0, 1)}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
