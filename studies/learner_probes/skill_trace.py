"""Where a learned manipulation skill goes wrong, closed loop: a per-step trace of one skill.

Runs episodes of a recipe's *train* or *val* split (never the test split: this is a development
tool) with the oracle planner, the scripted experts for every other skill and the learned run for
`--skill`, and prints for each step of that skill what its success test depends on: the hand's
distance to the target object (3-D and horizontal), the gripper opening, whether the object is
held, its height above its receptacle and the hand's distance to the carry pose; for a target
that is furniture (Place), a door or a sink, the base's distance to the expert's interaction pose.
To look at the same episode, `echo-data evaluate RECIPE --split val -n K --policy=SKILL=RUN
--policy oracle --planner oracle --video DIR` writes its MP4; a camera-free recipe (the sanity
learners') shows only the plan there, so extend it with `robot.head_camera.rgb: true` (and the
wrist camera's) for the pictures: the learner reads no image, so its actions are the same.

  python studies/learner_probes/skill_trace.py studies/paper_table/recipes/cameras_test_object_relocation.yaml --run runs/Pick \
      --skill Pick --split train --index 0 1 2 [--every 10]
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("LP_NUM_THREADS", "1")


def trace_row(env: Any, call: Any) -> dict[str, float]:
    """What the active manipulation skill's success test reads, now."""
    from echo_data.envs.privileged import target_world
    from echo_data.records import STATE_NAMES
    from echo_data.skills.success import CARRY_TCP, object_bottom, receptacle_of, tcp_in_base
    from echo_data.target import Target

    world = env.world
    robot = world.robot
    row: dict[str, float] = {"step": env.steps, "gripper": float(robot.state()[STATE_NAMES.index("gripper")])}
    tcp = np.asarray(robot.ee_pose().p, dtype=float)
    name = call.target
    if name in world.handles.objects:
        p = np.asarray(world.handles.objects[name].pose.p, dtype=float)
        row["tcp_obj_m"] = float(np.linalg.norm(tcp - p))
        row["tcp_obj_xy_m"] = float(np.linalg.norm(tcp[:2] - p[:2]))
        row["tcp_above_obj_m"] = float(tcp[2] - p[2])
        top = world.plan.furniture[receptacle_of(world, name)].top_z
        row["obj_lift_m"] = float(object_bottom(world, name) - top)
    else:  # a receptacle, door or sink: how far the base stands from where the expert would stand
        from echo_data.skills.navigate import goal_pose

        px, py, _ = goal_pose(world, name)
        bx, by, _ = robot.base_pose()
        row["base_to_goal_m"] = float(np.hypot(px - bx, py - by))
        if Target.parse(name).kind in ("door", "faucet"):  # the handle bar / lever tip and its joint
            target, angle = target_world(world, env.episode, call)
            row["tcp_target_m"] = float(np.linalg.norm(tcp - target[:3, 3]))
            row["joint_angle_rad"] = angle
    held = robot.holding
    row["held"] = float(held == name) if name in world.handles.objects else float(held is not None)
    row["carry_dist_m"] = float(np.linalg.norm(tcp_in_base(world) - np.asarray(CARRY_TCP)))
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe")
    ap.add_argument("--run", required=True, help="the learned run folder for --skill")
    ap.add_argument("--skill", default="Pick")
    ap.add_argument("--split", default="train", choices=("train", "val"))
    ap.add_argument("--index", type=int, nargs="+", default=[0])
    ap.add_argument("--every", type=int, default=10, help="print every Nth step of the skill")
    ap.add_argument("--json", type=Path, default=None, help="write the full traces here")
    args = ap.parse_args()

    from echo_data.agents.loading import load_planner, load_policy
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv

    policy = load_policy([f"{args.skill}={args.run}", "oracle"])
    planner = load_planner("oracle")
    env = EchoDataEnv(args.recipe, split=args.split)
    out: list[dict[str, Any]] = []
    for index in args.index:
        obs, info = env.reset(options={"split": args.split, "index": index})
        rows: list[dict[str, float]] = []

        def hook(env: Any, obs: Any, action: Any, k: int, call: Any, flags: Any, rows: list = rows) -> None:
            if call.skill == args.skill:
                rows.append({**trace_row(env, call), "action_gripper": float(action[-1])})

        run = run_episode(env, obs, info, planner, policy, on_step=hook)
        print(f"== {args.split}[{index}] {env.episode.setting}: {run.failure or 'success'} ({run.steps} steps)")
        for r in rows[:: args.every] + rows[-1:]:
            print("  " + "  ".join(f"{k}={v:.3f}" if isinstance(v, float) else f"{k}={v}" for k, v in r.items()))
        out.append({"index": index, "failure": run.failure, "trace": rows})
    env.close()
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
