"""`torchvision.transforms.ToTensor` as torchvision defines it: PIL image -> (C, H, W) tensor; 8-bit images become
float32 in [0, 1], 16-bit ("I;16") images stay integers (int16), as torchvision returns them."""

from __future__ import annotations

import numpy as np
import torch


class ToTensor:
    def __call__(self, pic):  # type: ignore[no-untyped-def]
        dtype = {"I": np.int32, "I;16": np.int16, "F": np.float32}.get(pic.mode, np.uint8)
        arr = np.array(pic, dtype=dtype, copy=True)
        if arr.ndim == 2:
            arr = arr[:, :, None]
        t = torch.from_numpy(arr).permute(2, 0, 1).contiguous()
        return t.float().div(255) if t.dtype == torch.uint8 else t
