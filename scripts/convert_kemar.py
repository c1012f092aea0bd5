"""Convert the MIT KEMAR HRIRs shipped with `slab` into assets/hrtf/mit_kemar.npz (run once).

Why a converted copy: the product must not need `slab` (or PortAudio) at run time, and
resampling 710 x 512-tap 44.1 kHz responses on every load would waste time. The npz keeps
the measured directions in slab's convention (azimuth counter-clockwise from the nose,
90 deg = left; elevation up; channel 0 = left ear), resampled to 16 kHz, with the leading
silence common to all directions removed (so every interaural delay is kept).

Usage:  python scripts/convert_kemar.py [--out assets/hrtf/mit_kemar.npz]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.signal import resample_poly

FS_OUT = 16000
TAPS_OUT = 96  # 6 ms at 16 kHz: keeps >= 96.8 % of the energy of every response (>= 99 % ipsilateral)
LEAD_KEEP = 4  # samples (16 kHz) kept before the earliest onset over all directions


def _load_slab_kemar() -> tuple[np.ndarray, np.ndarray, float]:
    """(irs (n, taps, 2), az_el_deg (n, 2), fs) straight from slab's bundled data."""
    sys.modules.setdefault("sounddevice", None)  # slab imports sounddevice (PortAudio) eagerly
    import slab  # noqa: PLC0415

    h = slab.HRTF.kemar()
    irs = np.stack([np.asarray(f.data, dtype=np.float64) for f in h.data])
    polar = np.asarray(h.sources.vertical_polar, dtype=np.float64)
    return irs, polar[:, :2], float(h.samplerate)


def _check_conventions(irs: np.ndarray, az_el: np.ndarray) -> None:
    """Fail loudly if slab's conventions are not what the product assumes."""
    def nearest(az: float) -> int:
        daz = np.abs((az_el[:, 0] - az + 180.0) % 360.0 - 180.0)
        return int(np.argmin(daz + np.abs(az_el[:, 1])))

    for az, lead in ((90.0, 0), (270.0, 1)):
        ir = irs[nearest(az)]
        onset = [int(np.argmax(np.abs(ir[:, c]) > 0.1 * np.abs(ir[:, c]).max())) for c in (0, 1)]
        energy = (ir**2).sum(axis=0)
        if not (onset[lead] < onset[1 - lead] and energy[lead] > energy[1 - lead]):
            raise SystemExit(f"unexpected slab convention at azimuth {az}: onsets {onset}, energies {energy}")


def convert(out: Path) -> None:
    irs, az_el, fs_in = _load_slab_kemar()
    if irs.shape != (710, 512, 2) or fs_in != 44100.0:
        raise SystemExit(f"unexpected KEMAR data: {irs.shape} at {fs_in} Hz")
    _check_conventions(irs, az_el)
    res = resample_poly(irs, FS_OUT, int(fs_in), axis=1)  # 160/441 polyphase, anti-aliased
    peak = np.abs(res).max(axis=1, keepdims=True)
    onsets = np.argmax(np.abs(res) > 0.1 * peak, axis=1)
    start = max(int(onsets.min()) - LEAD_KEEP, 0)
    cut = res[:, start : start + TAPS_OUT, :]
    kept = (cut**2).sum(axis=1) / (res**2).sum(axis=1)
    print(f"start {start}, taps {TAPS_OUT}, min energy kept {kept.min():.4f}")
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        out,
        hrir=cut.astype(np.float32),
        azimuth_deg=np.round(az_el[:, 0], 2).astype(np.float32),
        elevation_deg=np.round(az_el[:, 1], 2).astype(np.float32),
        fs=np.int32(FS_OUT),
        source=np.array("MIT Media Lab KEMAR, normal pinna (Gardner & Martin 1994), via slab 1.8.2"),
    )
    print(f"wrote {out} ({out.stat().st_size // 1024} KiB)")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "assets/hrtf/mit_kemar.npz")
    convert(p.parse_args().out)


if __name__ == "__main__":
    main()
