"""From valid image-source paths to what a listener gets: `PathSet` gathers the paths of many
receivers as arrays and turns them into `Arrival`s at once; `omni_rir` renders a response for an
omnidirectional receiver. Split from `acoustics.room` (which finds the paths) by job.
"""

from __future__ import annotations

import math

import numpy as np

from echo_data.acoustics.ism import ImagePaths
from echo_data.acoustics.tail import band_masks
from echo_data.acoustics.types import SPEED_OF_SOUND, AcousticResponse, Arrival


class PathSet:
    """Valid paths of many receivers, gathered as arrays and turned into `Arrival`s at once."""

    def __init__(self) -> None:
        self.parts: list[tuple[np.ndarray, ...]] = []

    def add(self, rows: np.ndarray, ip: ImagePaths, log0: np.ndarray, len0: float | np.ndarray, len_prefix: np.ndarray, skip_direct: np.ndarray | None) -> None:
        """Add the valid paths of `ip` (receivers `rows`), with per-(receiver, cell) log gain
        and length prefixes (diffraction, route to a doorway); `skip_direct` drops cell 0
        for receivers that already have the geometric direct path."""
        ok = ip.valid.copy()
        if skip_direct is not None:
            ok[:, 0] &= ~skip_direct
        r, i = np.nonzero(ok)
        length = ip.length[r, i] + len_prefix[r, i] + len0
        door = ip.door_db[r, i]
        order = ip.order[i].astype(np.int64)
        order = np.where((door > 0.0) & (order == 0), -1, order)
        self.parts.append((rows[r], length, ip.direction[r, i], ip.log_gain[r, i] + log0[r, i], door, order))

    def arrivals(self, n: int, air: np.ndarray, max_len: float) -> list[list[Arrival]]:
        out: list[list[Arrival]] = [[] for _ in range(n)]
        if not self.parts:
            return out
        row, L, d, lg, door, order = (np.concatenate(x) for x in zip(*self.parts))
        keep = max_len > L
        row, L, d, lg, door, order = row[keep], L[keep], d[keep], lg[keep], door[keep], order[keep]
        L = np.maximum(L, 1e-3)
        band = np.exp(lg - 0.5 * air[None] * L[:, None])
        gain = 10.0 ** (-door / 20.0) / L
        srt = np.lexsort((order, L, row))
        objs = list(
            map(
                Arrival,
                (L / SPEED_OF_SOUND)[srt].tolist(),
                map(tuple, d[srt].tolist()),
                gain[srt].tolist(),
                map(tuple, band[srt].tolist()),
                order[srt].tolist(),
            )
        )
        bounds = np.searchsorted(row[srt], np.arange(n + 1)).tolist()
        return [objs[bounds[i] : bounds[i + 1]] for i in range(n)]


def omni_rir(response: AcousticResponse) -> np.ndarray:
    """The response rendered for an omnidirectional receiver: float32 (length,).

    Each arrival is a fractional-delay impulse shaped by its band gains through
    amplitude-complementary octave masks (unit band gains give an exact band-limited
    impulse), rendered in the frequency domain; the tails (own room, openings) are added as is.
    """
    L = response.length
    fs = response.fs
    n_fft = 1 << int(math.ceil(math.log2(2 * L + 64)))
    f = np.fft.rfftfreq(n_fft, 1.0 / fs)
    masks = band_masks(n_fft, fs, power=False)
    spec = np.zeros(len(f), dtype=np.complex128)
    arr = [a for a in response.arrivals if a.delay_s * fs < L]
    for s in range(0, len(arr), 64):
        chunk = arr[s : s + 64]
        tau = np.asarray([a.delay_s for a in chunk])
        g = np.asarray([a.gain for a in chunk])[:, None] * np.asarray([a.band_gains for a in chunk])  # (A, bands)
        ph = np.exp(-2j * np.pi * f[None, :] * tau[:, None])  # (A, F)
        spec += np.einsum("ab,bf,af->f", g, masks, ph)
    h = np.fft.irfft(spec, n=n_fft)[:L]
    tail = np.asarray(response.tail, dtype=np.float64)[:L]
    h[: len(tail)] += tail
    for ap in response.apertures:  # an omni receiver sums the opening's late energy too
        late = np.asarray(ap.signals, dtype=np.float64).sum(axis=0)[:L]
        h[: len(late)] += late
    return h.astype(np.float32)
