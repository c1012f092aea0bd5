"""What recording a step's extra columns costs: the privileged probe and the `to_ee` twin of a
joint-born action, against one environment step with the recipe's cameras, in the same process.

    python benchmarks/bench_recorder.py [recipe]

CPU time (process), so a busy machine does not inflate it; prints each part and its ratio to the step.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def cpu_ms(f: Callable[[], object], n: int) -> float:
    t = time.process_time()
    for _ in range(n):
        f()
    return (time.process_time() - t) / n * 1e3


def main() -> None:
    from echo_data.envs import EchoDataEnv
    from echo_data.envs.privileged import PrivilegedProbe
    from echo_data.recipe import load_recipe

    recipe = load_recipe(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "recipes" / "quickstart.yaml")
    env = EchoDataEnv(recipe, split="test", images=True, audio=False)
    env.reset(options={"split": "test", "index": 0})
    probe, robot = PrivilegedProbe(), env.world.robot
    hold = robot.applied_action()
    moved = hold.copy()
    moved[4:11] += 0.01
    step = cpu_ms(lambda: env.step(hold), 20)
    print(f"env step with cameras: {step:.2f} ms CPU (baseline)")
    for call in env.episode.chain:
        t = cpu_ms(lambda: probe(env.world, env.episode, call), 100)  # noqa: B023
        print(f"privileged probe, {call.skill} {call.target}: {t:.3f} ms ({t / step:.1%} of a step)")
    t = cpu_ms(lambda: robot.ee.to_ee(moved), 200)
    print(f"to_ee twin of a joint action: {t:.3f} ms ({t / step:.1%} of a step)")
    env.close()


if __name__ == "__main__":
    main()
