"""Runs inside the LeRobot environment (scripts/setup_lerobot.sh): a stock LeRobot policy on an
`echo-data export --format lerobot` folder, the way `lerobot-train` builds it.

    python lerobot_policy.py EXPORT_ROOT {act,diffusion} STEPS
    python lerobot_policy.py EXPORT_ROOT diffusion params

LeRobot's own dataset metadata types the features (`make_policy` -> `dataset_to_policy_features`,
then the config's `validate_features`), LeRobot's processors normalise with the export's
meta/stats.json, LeRobot's dataset serves the train split's frames with the policy's
`delta_timestamps`, and the policy takes STEPS Adam steps on CPU. Prints one JSON line: the
policy's input and output features (key -> type), the losses, the episodes it read and the mean
absolute gradient that reached the audio input (`observation.environment_state`) at each step.
Small model sizes keep the steps to seconds; nothing is downloaded (no pretrained backbone).
`params` builds the stock (full-size) config with and without the audio input and prints both
parameter counts.
"""

from __future__ import annotations

import json
import sys

import torch
from lerobot.configs.types import FeatureType
from lerobot.datasets.factory import resolve_delta_timestamps
from lerobot.datasets.lerobot_dataset import LeRobotDataset, LeRobotDatasetMetadata
from lerobot.datasets.utils import dataset_to_policy_features
from lerobot.policies.factory import make_policy, make_policy_config, make_pre_post_processors

SMALL = {
    "act": {"dim_model": 64, "n_heads": 2, "dim_feedforward": 128, "n_encoder_layers": 1, "n_decoder_layers": 1,
            "chunk_size": 4, "n_action_steps": 4, "pretrained_backbone_weights": None, "use_vae": True, "latent_dim": 8},
    "diffusion": {"n_obs_steps": 2, "horizon": 8, "n_action_steps": 4, "drop_n_last_frames": 3, "down_dims": (32, 64),
                  "diffusion_step_embed_dim": 32, "spatial_softmax_num_keypoints": 8, "n_groups": 4, "num_train_timesteps": 10},
}


ENV = "observation.environment_state"


def params(root: str, kind: str) -> None:
    """Parameter counts of the stock `kind` policy with and without the audio input."""
    meta = LeRobotDatasetMetadata("echo-data/export", root=root)
    counts = {}
    for name, drop in (("with_audio", ()), ("without_audio", (ENV,))):
        cfg = make_policy_config(kind, device="cpu")
        cfg.input_features = {k: f for k, f in dataset_to_policy_features(meta.features).items() if f.type is not FeatureType.ACTION and k not in drop}
        cfg.output_features = {k: f for k, f in dataset_to_policy_features(meta.features).items() if f.type is FeatureType.ACTION}
        policy = make_policy(cfg, ds_meta=meta)
        counts[name] = sum(p.numel() for p in policy.parameters())
        del policy
    print(json.dumps(counts))


def main(root: str, kind: str, steps: int) -> None:
    torch.manual_seed(0)
    meta = LeRobotDatasetMetadata("echo-data/export", root=root)
    cfg = make_policy_config(kind, device="cpu", **SMALL[kind])
    policy = make_policy(cfg, ds_meta=meta)  # types the features, calls cfg.validate_features()
    pre, _post = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    lo, hi = (int(x) for x in meta.info["splits"]["train"].split(":"))
    ds = LeRobotDataset("echo-data/export", root=root, episodes=list(range(lo, hi)), delta_timestamps=resolve_delta_timestamps(cfg, meta), video_backend="pyav")
    loader = torch.utils.data.DataLoader(ds, batch_size=4, shuffle=True, num_workers=0, drop_last=True)
    opt = torch.optim.Adam(policy.parameters(), lr=1e-4)
    policy.train()
    losses: list[float] = []
    audio_grad: list[float] = []
    seen: set[int] = set()
    while len(losses) < steps:
        for batch in loader:
            seen.update(int(e) for e in batch["episode_index"].flatten())
            inputs = pre(batch)
            inputs[ENV].requires_grad_(True)  # after normalisation: what the policy itself is given
            loss, _ = policy.forward(inputs)
            opt.zero_grad()
            loss.backward()
            audio_grad.append(float(inputs[ENV].grad.abs().mean()))
            opt.step()
            losses.append(float(loss.detach()))
            if len(losses) == steps:
                break
    out = {
        "inputs": {k: str(f.type.name) for k, f in cfg.input_features.items()},
        "outputs": {k: str(f.type.name) for k, f in cfg.output_features.items()},
        "losses": losses,
        "audio_grad": audio_grad,
        "episodes_seen": sorted(seen),
        "train_episodes": [lo, hi],
    }
    print(json.dumps(out))


if __name__ == "__main__":
    if sys.argv[3] == "params":
        params(sys.argv[1], sys.argv[2])
    else:
        main(sys.argv[1], sys.argv[2], int(sys.argv[3]))
