"""What the Pick and Place demonstrations show a learner: the figures issue 28 asks to re-measure.

Runs train-split episodes of a recipe with the scripted experts (the build's way: the
environment, the runtime, `OracleSkills`), cameras on, and for every Pick and Place row reads:

- whether the target object is in the picture of some camera: its segmentation id among the
  pixels of the head or wrist camera's last picture (the observation of that row; occlusion
  by the arm counts as not visible);
- the share of head pixels the robot itself covers (the arm in the head camera's view);
- the Pick phase of the row: `base` (the base moves), `untuck` (until the commanded TCP reaches
  the approach pose beside the head: object-independent), `object` (every row after: hover,
  descent, close, lift, carry, each computed from the object's pose);
- the arm joints at the end of the untuck, at the hover and at the grasp, for the spread between
  episodes (largest joint range across episodes at each of these points).

    python studies/experts/pick_place_figures.py recipes/object_relocation.yaml -n 10 [--json out.json]

Development tool: the train split only. Prints one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("LP_NUM_THREADS", "1")

APPROACH_TOL = 0.01  # m: the commanded TCP is at the approach pose (the untuck is over)


def _segmentation(comp: Any) -> np.ndarray:
    from echo_data.robot.robot import POSITION_PICTURE

    return np.asarray(comp.get_picture(POSITION_PICTURE)[..., 3])


def measure(recipe_path: str, n: int) -> dict[str, Any]:
    from echo_data.agents.builtin import OraclePlanner, OracleSkills
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv
    from echo_data.robot.ee_control import world_to_base
    from echo_data.skills.pick import APPROACH_TCP, TORSO_UP

    env = EchoDataEnv(recipe_path, split="train", images=True)
    episodes: list[dict[str, Any]] = []
    t0 = time.perf_counter()
    for index in range(n):
        obs, info = env.reset(options={"split": "train", "index": index})
        rows: list[dict[str, Any]] = []

        def hook(env: Any, obs: Any, action: Any, k: int, call: Any, flags: Any, rows: list = rows) -> None:
            if call.skill not in ("Pick", "Place"):
                return
            world = env.world
            robot = world.robot
            name = call.target if call.skill == "Pick" else env.episode.chain[k - 1].target
            oid = world.handles.objects[name].per_scene_id
            robot_ids = [ln.entity.per_scene_id for ln in robot.articulation.links]
            seen = {}
            head_robot = 0.0
            for cam, (comp, _) in robot.cameras.items():
                seg = _segmentation(comp)
                seen[cam] = int(np.count_nonzero(seg == oid))
                if cam == "head":
                    head_robot = float(np.isin(seg, robot_ids).mean())
            ref = robot.applied_action().astype(np.float64)
            tcp_cmd = robot.ee.tcp_in_base(float(ref[3]), ref[4:11])
            obj_in_base = world_to_base(world.object_pose(name).to_transformation_matrix(), robot.base_pose())
            rows.append({
                "skill": call.skill, "seen": seen, "head_robot": head_robot,
                "base_moves": bool(np.any(np.abs(action[:3]) > 1e-6)),
                "at_approach": bool(abs(ref[3] - TORSO_UP) < 1e-4 and np.linalg.norm(tcp_cmd[:3, 3] - APPROACH_TCP) < APPROACH_TOL),
                "arm": ref[4:11].tolist(), "gripper_closed": bool(ref[11] < 0.05),
                "held": robot.holding == name, "tcp_obj": (tcp_cmd[:3, 3] - obj_in_base[:3, 3]).tolist(),
            })

        policy = OracleSkills()
        run = run_episode(env, obs, info, OraclePlanner(), policy, on_step=hook)
        policy.close()
        episodes.append({"index": index, "failure": run.failure, "outcomes": [(o.skill, o.success, o.reason) for o in run.outcomes], "rows": rows})
    env.close()
    return summarise(episodes, time.perf_counter() - t0)


def _pick_phases(rows: list[dict[str, Any]]) -> list[str]:
    """base / untuck / object for each Pick row (see the module docstring)."""
    phases: list[str] = []
    untucked = False
    for r in rows:
        if untucked:
            phases.append("object")
        elif r["at_approach"]:
            untucked = True
            phases.append("object")
        elif r["base_moves"] and "untuck" not in phases:
            phases.append("base")
        else:
            phases.append("untuck")
    return phases


def summarise(episodes: list[dict[str, Any]], seconds: float) -> dict[str, Any]:
    pick_rows, place_rows = [], []
    phase_counts: list[dict[str, int]] = []
    marks: dict[str, list[list[float]]] = {"untuck_end": [], "hover": [], "grasp": []}
    for e in episodes:
        pr = [r for r in e["rows"] if r["skill"] == "Pick"]
        pl = [r for r in e["rows"] if r["skill"] == "Place"]
        pick_rows += pr
        place_rows += pl
        if not pr:
            continue
        phases = _pick_phases(pr)
        phase_counts.append({p: phases.count(p) for p in ("base", "untuck", "object")} | {"rows": len(pr)})
        obj = [i for i, p in enumerate(phases) if p == "object"]
        if obj:
            marks["untuck_end"].append(pr[obj[0]]["arm"])
        closed = [i for i, r in enumerate(pr) if r["gripper_closed"]]
        if closed:
            marks["grasp"].append(pr[closed[0]]["arm"])
            # the hover: the last row before the close whose TCP is >= 10 cm above the object
            above = [i for i in range(closed[0]) if pr[i]["tcp_obj"][2] >= 0.10 and phases[i] == "object"]
            if above:
                marks["hover"].append(pr[above[-1]]["arm"])

    def visible(rows: list[dict[str, Any]]) -> dict[str, float]:
        if not rows:
            return {}
        head = np.array([r["seen"].get("head", 0) > 0 for r in rows])
        wrist = np.array([r["seen"].get("wrist", 0) > 0 for r in rows])
        return {"rows": len(rows), "some_camera": float(np.mean(head | wrist)), "head": float(head.mean()), "wrist": float(wrist.mean()), "none": int(np.sum(~(head | wrist)))}

    def pick_rows_in(phase: str) -> list[dict[str, Any]]:
        out = []
        for e in episodes:
            pr = [x for x in e["rows"] if x["skill"] == "Pick"]
            out += [r for r, p in zip(pr, _pick_phases(pr)) if p == phase]
        return out

    pick_obj = pick_rows_in("object")
    # where the object is in no camera: rows before the first close of each Pick segment
    unseen_before_close: dict[int, int] = {}
    for e in episodes:
        pr = [x for x in e["rows"] if x["skill"] == "Pick"]
        closed = [i for i, r in enumerate(pr) if r["gripper_closed"]]
        if not closed:
            continue
        for i, r in enumerate(pr[: closed[0]]):
            if not (r["seen"].get("head", 0) or r["seen"].get("wrist", 0)):
                unseen_before_close[closed[0] - i] = unseen_before_close.get(closed[0] - i, 0) + 1
    pick_untuck = pick_rows_in("untuck")
    spread = {k: (float(np.max(np.ptp(np.array(v), axis=0))) if len(v) > 1 else None) for k, v in marks.items()}
    outcomes: dict[str, list[int]] = {}
    for e in episodes:
        for skill, ok, _ in e["outcomes"]:
            s = outcomes.setdefault(skill, [0, 0])
            s[0] += int(ok)
            s[1] += 1
    return {
        "episodes": len(episodes),
        "successes": outcomes,
        "failures": [(e["index"], e["failure"]) for e in episodes if e["failure"]],
        "pick_rows_per_segment": {k: float(np.mean([c[k] for c in phase_counts])) for k in ("rows", "base", "untuck", "object")} if phase_counts else {},
        "pick_object_share": float(np.mean([c["object"] / c["rows"] for c in phase_counts])) if phase_counts else None,
        "visible_pick": visible(pick_rows),
        "visible_pick_untuck": visible(pick_untuck),
        "visible_pick_object_phase": visible(pick_obj),
        "visible_pick_object_phase_open": visible([r for r in pick_obj if not r["gripper_closed"]]),
        "visible_pick_object_phase_closed": visible([r for r in pick_obj if r["gripper_closed"]]),
        "visible_place": visible(place_rows),
        "head_covered_by_robot": {
            "pick_untuck": float(np.mean([r["head_robot"] for r in pick_untuck])) if pick_untuck else None,
            "pick_object_phase": float(np.mean([r["head_robot"] for r in pick_obj])) if pick_obj else None,
        },
        "joint_spread_rad": spread,
        "unseen_rows_before_close": dict(sorted(unseen_before_close.items())),
        "seconds": round(seconds, 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe")
    ap.add_argument("-n", type=int, default=5)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    out = measure(args.recipe, args.n)
    text = json.dumps(out, indent=1)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")


if __name__ == "__main__":
    main()
