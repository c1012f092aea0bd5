"""Run inside the LeRobot environment (see tests/test_export_lerobot.py): load an export with
`ledataset`'s LeRobotDataset from a local root, iterate a DataLoader over it, and save every
frame's tensors to an .npz for the echo-data side to compare with its own rows.

usage: python lerobot_load.py ROOT OUT.npz
"""

import json
import sys

import numpy as np
import torch
from ledataset.datasets.lerobot_dataset import LeRobotDataset, LeRobotDatasetMetadata

root, out = sys.argv[1], sys.argv[2]
meta = LeRobotDatasetMetadata("echo-data/export", root=root)
ds = LeRobotDataset("echo-data/export", root=root)
loader = torch.utils.data.DataLoader(ds, batch_size=4, shuffle=False, num_workers=2)
columns: dict[str, list] = {}
strings: dict[str, list] = {}
for batch in loader:
    for k, v in batch.items():
        if isinstance(v, torch.Tensor):
            columns.setdefault(k, []).append(v.numpy())
        else:
            strings.setdefault(k, []).extend(v)
arrays = {k: np.concatenate(v) for k, v in columns.items()}
# behaviour-cloning windows as LeRobot policies ask for them: frame 1 of episode 0 with the
# previous frame's image and an action chunk of 3 (frame 0 has no predecessor: padded)
windows = LeRobotDataset("echo-data/export", root=root, delta_timestamps={"observation.state": [-0.1, 0.0], "action": [0.0, 0.1, 0.2]})
w = windows[1]
arrays["window.observation.state"] = w["observation.state"].numpy()[None]
arrays["window.action"] = w["action"].numpy()[None]
arrays["window.pad"] = np.concatenate([w["observation.state_is_pad"].numpy(), w["action_is_pad"].numpy()])[None]
np.savez(out, **arrays)
# the train split as `splits` names it (LeRobot casts the rows to the schema of info.json's feature order)
lo, hi = map(int, meta.info["splits"]["train"].split(":"))
train = LeRobotDataset("echo-data/export", root=root, episodes=list(range(lo, hi)))
train_episodes = sorted({int(x) for x in train.hf_dataset["episode_index"]})
episodes = meta.episodes.to_list()
print(
    json.dumps(
        {
            "len": len(ds),
            "num_episodes": ds.num_episodes,
            "fps": ds.fps,
            "camera_keys": meta.camera_keys,
            "video_keys": meta.video_keys,
            "splits": meta.info["splits"],
            "tasks": list(meta.tasks.index),
            "stats_keys": sorted(meta.stats),
            "train_episodes": train_episodes,
            "train_len": len(train),
            "strings": strings,
            "episodes": [{k: e[k] for k in ("episode_index", "split", "episode_id", "audio_path", "dataset_from_index", "dataset_to_index", "tasks")} for e in episodes],
            "dtypes": {k: str(v.dtype) for k, v in arrays.items()},
        }
    )
)
