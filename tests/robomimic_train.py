"""robomimic's own BC training entry point (`robomimic.scripts.train.train`) on an
`echo-data export --format robomimic` file, for a few steps on CPU (tests/test_export_arrays.py).

    python robomimic_train.py DATASET.hdf5 OUTPUT_DIR STEPS

Low-dimensional observations only (the state and the audio spectrogram), the train mask, no
rollouts (there is no robomimic environment of echo-data), no next_obs (BC does not use them).
Prints one JSON line: the steps taken and the last epoch's losses as robomimic logs them.
"""

from __future__ import annotations

import json
import sys

import robomimic.utils.torch_utils as torch_utils
from robomimic.config import config_factory
from robomimic.scripts import train as rm_train


def main(data: str, out: str, steps: int) -> None:
    config = config_factory("bc")
    with config.values_unlocked():
        config.train.data = data
        config.train.output_dir = out
        config.train.hdf5_filter_key = "train"
        config.train.hdf5_load_next_obs = False
        config.train.hdf5_cache_mode = "low_dim"
        config.train.batch_size = 4
        config.train.num_data_workers = 0
        config.train.num_epochs = 1
        config.experiment.name = "echo_data_bc"
        config.experiment.epoch_every_n_steps = steps
        config.experiment.validate = False
        config.experiment.rollout.enabled = False
        config.experiment.save.enabled = False
        config.experiment.logging.log_tb = False
        config.experiment.logging.terminal_output_to_txt = False
        config.observation.modalities.obs.low_dim = ["state", "spectrogram"]
        config.observation.modalities.obs.rgb = []
        config.algo.actor_layer_dims = (64, 64)
    logged: dict[str, float] = {}
    run_epoch = rm_train.TrainUtils.run_epoch

    def recording_run_epoch(*args, **kwargs):  # keeps what robomimic logs for the epoch
        stats = run_epoch(*args, **kwargs)
        logged.update({k: float(v) for k, v in stats.items() if "Loss" in k})
        logged["steps"] = float(kwargs.get("num_steps", args[4] if len(args) > 4 else -1))
        return stats

    rm_train.TrainUtils.run_epoch = recording_run_epoch
    rm_train.train(config, device=torch_utils.get_torch_device(try_to_use_cuda=False))
    print(json.dumps(logged))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]))
