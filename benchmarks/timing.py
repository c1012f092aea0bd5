"""What the benchmarks share: the floor they measure against and one way to print a figure.

The floor: per control step, the physics sub-steps of one control period, `update_render`, and
`take_picture` + `get_picture` of every robot camera (no conversion) on the same world — what no
pipeline on SAPIEN can go under. Every figure is printed as wall-clock and process-CPU time (all
threads of the process), each with its ratio to the floor measured in the same run: on a machine
shared with other jobs the wall clock moves with the load, the CPU ratio says what a step costs.
"""

from __future__ import annotations

import time

import numpy as np

from echo_data.robot.robot import COLOR_PICTURE, POSITION_PICTURE


class Clock:
    """Wall-clock and process-CPU seconds since it was made."""

    def __init__(self) -> None:
        self.wall, self.cpu = time.perf_counter(), time.process_time()

    def lap(self) -> tuple[float, float]:
        return time.perf_counter() - self.wall, time.process_time() - self.cpu


def _cameras(world: object) -> list[tuple[object, object]]:
    return list(world.robot.cameras.values())  # type: ignore[attr-defined]


def _read_pictures(world: object, cams: list[tuple[object, object]]) -> None:
    """`update_render`, then `take_picture` + `get_picture` of every robot camera (no conversion)."""
    world.scene.update_render()  # type: ignore[attr-defined]
    for comp, cfg in cams:
        comp.take_picture()  # type: ignore[attr-defined]
        if cfg.rgb:  # type: ignore[attr-defined]
            comp.get_picture(COLOR_PICTURE)  # type: ignore[attr-defined]
        if cfg.depth:  # type: ignore[attr-defined]
            comp.get_picture(POSITION_PICTURE)  # type: ignore[attr-defined]


def bare_step_render(world: object, steps: int, cpu: bool = False) -> float:
    """Seconds per control step of physics + render + picture readback only (process CPU
    seconds with `cpu`, else wall-clock)."""
    return floor_times(world, steps)[1 if cpu else 0]


def floor_times(world: object, steps: int) -> tuple[float, float]:
    """(wall-clock, process-CPU) seconds per control step of physics + render + readback, one run."""
    scene = world.scene  # type: ignore[attr-defined]
    cams = _cameras(world)
    clock = Clock()
    for _ in range(steps):
        for _ in range(world.substeps):  # type: ignore[attr-defined]
            scene.step()
        _read_pictures(world, cams)
    wall, proc = clock.lap()
    return wall / steps, proc / steps


def replay_times(world: object, actions: list[np.ndarray]) -> tuple[float, float]:
    """(wall-clock, process-CPU) seconds per control step of `World.step(action)` for the recorded
    actions + render + readback, one run (the floor along a recorded path)."""
    cams = _cameras(world)
    clock = Clock()
    for a in actions:
        world.step(a)  # type: ignore[attr-defined]
        _read_pictures(world, cams)
    wall, proc = clock.lap()
    return wall / max(len(actions), 1), proc / max(len(actions), 1)


def ratio_row(label: str, what: str, wall: float, cpu: float, floor: tuple[float, float], tail: str = "") -> str:
    """One figure as every benchmark prints it: wall and process-CPU seconds per step, each with its ratio to the floor measured in the same run."""
    return f"{label:9s} {what:36s} {wall * 1e3:7.2f} ms/step  ratio {wall / floor[0]:5.2f}x | CPU {cpu * 1e3:7.2f} ms/step  ratio {cpu / floor[1]:5.2f}x{tail}"


def floor_row(wall: float, cpu: float, what: str = "bare SAPIEN step+render:") -> str:
    """The floor's own line, in the layout of `ratio_row`."""
    return f"{'floor':9s} {what:36s} {wall * 1e3:7.2f} ms/step = {1 / wall:6.1f} steps/s | CPU {cpu * 1e3:7.2f} ms/step"
