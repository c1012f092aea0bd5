"""Shipped recipes made small for tests: tiny cameras, one test episode per setting."""

from __future__ import annotations

from pathlib import Path

from echo_data.recipe import CameraConfig, Recipe, load_recipe

ROOT = Path(__file__).resolve().parents[2]


def tiny_recipe(setting: str = "quickstart") -> Recipe:
    r = load_recipe(ROOT / "recipes" / f"{setting}.yaml")
    cam = CameraConfig(width=32, height=32)
    robot = r.robot.model_copy(update={"head_camera": cam, "wrist_camera": cam.model_copy(update={"rgb": False})})
    comp = {"object_relocation": {"test": 1}, "state_transition": {"test": 1}, "multi_event": {"test": 1}}
    return r.model_copy(update={"robot": robot, "composition": comp, "splits": {"test": 3}})
