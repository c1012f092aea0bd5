"""The dataset's own PNG writer: Pillow and Hugging Face `datasets` decode it to the same pixels
(RGB 8-bit and 16-bit depth), and it is a PNG by the format's rules (signature, chunk CRCs)."""

from __future__ import annotations

import io
import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from echo_data.dataset.encode import encode_png


def _images() -> list[np.ndarray]:
    rng = np.random.default_rng(0)
    yy, xx = np.mgrid[0:37, 0:53]
    return [
        rng.integers(0, 256, (37, 53, 3), dtype=np.uint8),
        np.stack([xx * 4 % 256, yy * 6 % 256, (xx + yy) % 256], -1).astype(np.uint8),
        rng.integers(0, 65536, (37, 53), dtype=np.uint16),
        (1500 + 7 * xx + 3 * yy).astype(np.uint16),
        np.full((1, 1), 65535, dtype=np.uint16),
    ]


@pytest.mark.parametrize("k", range(5))
def test_pillow_and_datasets_decode_the_same_pixels(k: int) -> None:
    import datasets

    img = _images()[k]
    data = encode_png(img)
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(data))), img)
    decoded = datasets.Image().decode_example({"bytes": data, "path": None})
    assert np.array_equal(np.asarray(decoded), img)


def test_chunks_are_well_formed() -> None:
    data = encode_png(_images()[0])
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, tags = 8, []
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos : pos + 4])
        tag, payload = data[pos + 4 : pos + 8], data[pos + 8 : pos + 8 + n]
        assert struct.unpack(">I", data[pos + 8 + n : pos + 12 + n])[0] == zlib.crc32(tag + payload)
        tags.append(tag)
        pos += 12 + n
    assert tags == [b"IHDR", b"IDAT", b"IEND"]


def test_refuses_other_images() -> None:
    with pytest.raises(ValueError, match="unsupported image"):
        encode_png(np.zeros((4, 4), dtype=np.float32))
