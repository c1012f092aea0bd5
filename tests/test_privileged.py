"""Privileged observations (`observation.privileged.*`, echo_data/envs/privileged.py) against geometry.

The base-frame target pose is the world pose seen from the base (a rigid transform written out
here by hand: rotate by -yaw about z after subtracting the base position); the TCP-to-target
vector is the difference of the two world points in the base's axes; the joint angle is the
articulation's own joint position; the columns are flagged privileged in the schema (field
metadata, schema metadata) and never among a loader's default inputs.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from support.optional import needs_torch

from echo_data.envs import EchoDataEnv
from echo_data.envs.privileged import JOINT_ANGLE, PLACE_SPOT, TARGET_POSE, TCP_TO_TARGET, PrivilegedProbe
from echo_data.recipe import load_recipe
from echo_data.records import PRIVILEGED_COLUMNS, PRIVILEGED_NOTES, PRIVILEGED_PREFIX
from echo_data.target import Target

ROOT = Path(__file__).resolve().parents[1]


def _in_base(p: np.ndarray, base: tuple[float, float, float]) -> np.ndarray:
    x, y, yaw = base
    dx, dy = float(p[0]) - x, float(p[1]) - y
    return np.array([math.cos(yaw) * dx + math.sin(yaw) * dy, -math.sin(yaw) * dx + math.cos(yaw) * dy, float(p[2])])


@pytest.fixture(scope="module")
def multi_event_env() -> EchoDataEnv:
    recipe = load_recipe(ROOT / "recipes" / "quickstart.yaml")
    env = EchoDataEnv(recipe, split="test", images=False, audio=False)
    for index in range(recipe.splits["test"]):
        env.reset(options={"split": "test", "index": index})
        if env.episode.setting == "multi_event":  # an object, a receptacle and a door or faucet
            break
    yield env
    env.close()


def test_target_pose_is_the_world_pose_seen_from_the_base(multi_event_env: EchoDataEnv) -> None:
    env = multi_event_env
    world, spec = env.world, env.episode
    probe = PrivilegedProbe()
    base = world.robot.base_pose()
    tcp = np.asarray(world.robot.ee_pose().p, dtype=np.float64)
    kinds = set()
    for call in spec.chain:
        got = probe(world, spec, call)
        assert set(got) == set(PRIVILEGED_COLUMNS) and all(v.dtype == np.float32 and v.shape == (PRIVILEGED_COLUMNS[k],) for k, v in got.items())
        t = Target.parse(call.target)
        kinds.add(t.kind)
        pose = got[TARGET_POSE].astype(np.float64)
        assert pose[3] >= 0 and math.isclose(float(np.linalg.norm(pose[3:])), 1.0, abs_tol=1e-5)
        # the TCP-to-target vector is the two world points' difference in the base's axes
        assert np.allclose(got[TCP_TO_TARGET], pose[:3] - _in_base(tcp, base), atol=1e-5)
        if t.kind == "object":
            p = world.object_pose(t.name)
            assert np.allclose(pose[:3], _in_base(p.p, base), atol=1e-5)
            w, x, y, z = (float(v) for v in p.q)
            want = Rotation.from_euler("z", -base[2]) * Rotation.from_quat([x, y, z, w])
            assert (Rotation.from_quat([*pose[4:], pose[3]]) * want.inv()).magnitude() < 1e-4
            assert got[JOINT_ANGLE][0] == 0.0
        elif t.kind == "door":
            door = world.plan.doors[t.index]
            assert got[JOINT_ANGLE][0] == np.float32(world.handles.doors[t.index].get_qpos()[0])
            assert math.isclose(pose[2], door.handle_height, abs_tol=1e-5)
            # the handle sits on the leaf: width - offset from the hinge, within the leaf's half thickness + standoff
            hinge = _in_base(np.array([*door.hinge, pose[2]]), base)
            assert 0.5 * door.width < float(np.linalg.norm(pose[:2] - hinge[:2])) < door.width
        elif t.kind == "faucet":
            faucet = world.plan.faucets[t.index]
            angle = float(world.handles.faucets[t.index].get_qpos()[0])
            assert got[JOINT_ANGLE][0] == np.float32(angle)
            pivot = _in_base(np.asarray(faucet.pivot), base)
            assert math.isclose(float(np.linalg.norm(pose[:3] - pivot)), faucet.lever_length, abs_tol=1e-5)
        else:  # furniture: a point of its top (a Place's place spot)
            f = world.plan.furniture[t.index]
            assert math.isclose(pose[2], f.top_z, abs_tol=1e-5)
            c, s = math.cos(base[2]), math.sin(base[2])
            wx, wy = base[0] + c * pose[0] - s * pose[1], base[1] + s * pose[0] + c * pose[1]  # back in the world
            assert f.footprint.contains(float(wx), float(wy))
        if call.skill == "Place":
            assert np.allclose(pose[:3], got[PLACE_SPOT], atol=1e-6)
        else:
            assert not got[PLACE_SPOT].any()
    assert {"object", "furniture"} <= kinds and kinds & {"door", "faucet"}


def test_privileged_columns_are_flagged_and_documented() -> None:
    from echo_data.dataset.lerobot import lerobot_features
    from echo_data.dataset.schema import StepLayout, is_privileged

    layout = StepLayout.from_recipe(load_recipe(ROOT / "recipes" / "quickstart.yaml"))
    schema = layout.schema()
    for col in PRIVILEGED_COLUMNS:
        assert col.startswith(PRIVILEGED_PREFIX) and is_privileged(col) and PRIVILEGED_NOTES[col]
        assert schema.field(col).metadata == {b"privileged": b"true"}
        assert lerobot_features(layout)["extra." + col]["info"] == {"privileged": True}  # the export's name for it
    flagged = [f.name for f in schema if (f.metadata or {}).get(b"privileged")]
    assert flagged == list(PRIVILEGED_COLUMNS)


@needs_torch
def test_no_loader_reads_privileged_columns_by_default(synth_dataset: Callable[[dict[str, int]], Path]) -> None:
    from echo_data.dataset.torch import SequenceDataset, StepDataset

    out = synth_dataset({"train": 4, "test": 1})
    seq = SequenceDataset(out, "train")
    assert not [c for c in seq.observations if c.startswith(PRIVILEGED_PREFIX)]
    named = SequenceDataset(out, "train", observations=["observation.state", TARGET_POSE])  # read by name
    assert tuple(named[0][TARGET_POSE].shape)[-1] == 7
    assert tuple(StepDataset(out, "train", columns=[PLACE_SPOT])[0][PLACE_SPOT].shape) == (3,)
    ee = SequenceDataset(out, "train", action_chunk=4, action="action.ee")  # chunks of the end-effector form
    assert tuple(ee[0]["action.ee"].shape) == (4, 11) and "action" not in ee[0]
