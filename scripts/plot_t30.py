"""Plot the reverberation of generated homes against measured furnished homes -> docs/t30_generated_homes.png.

For every room of the plans of `--seeds` seeds of a recipe: an omnidirectional RIR (source
and receiver 2/5 and 3/5 across the room, 1 s long) rendered by the acoustic model, and its
octave-band T30 (Schroeder backward integral, -5 to -35 dB). Left: per-band medians and
10th-90th percentiles for furnished rooms and for kitchens/bathrooms/corridors, with Jackson &
Leventhall's 50 British living rooms (0.69 s at 125 Hz falling to 0.40 s at 8 kHz, ends
joined linearly in log-frequency as an indication) and the BBC band of better-furnished
rooms (0.35-0.45 s). Right: histogram of the 500 Hz-1 kHz mean.

Usage:  python scripts/plot_t30.py [--recipe recipes/object_relocation.yaml] [--seeds 50]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402

from echo_data.acoustics.survey import room_t30s  # noqa: E402
from echo_data.recipe import AcousticsConfig, load_recipe  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BANDS = (125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0)
FURNISHED = ("living", "bedroom", "study", "hall")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--recipe", default=str(ROOT / "recipes" / "object_relocation.yaml"))
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--out", default=str(ROOT / "docs" / "t30_generated_homes.png"))
    args = ap.parse_args()
    recipe = load_recipe(args.recipe)
    cfg = AcousticsConfig(**{**recipe.acoustics.model_dump(), "rir_seconds": 1.0})
    kinds, t30 = room_t30s(recipe, range(args.seeds), cfg, BANDS)
    soft = np.isin(kinds, FURNISHED)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(12, 4.5))
    for mask, label, colour in ((soft, "generated: living rooms, bedrooms, studies, halls", "tab:blue"), (~soft, "generated: kitchens, bathrooms, corridors", "tab:orange")):
        if not mask.any():
            continue
        med = np.median(t30[mask], axis=0)
        ax.plot(BANDS, med, "o-", color=colour, label=f"{label} (median, n={mask.sum()})")
        ax.fill_between(BANDS, np.percentile(t30[mask], 10, axis=0), np.percentile(t30[mask], 90, axis=0), color=colour, alpha=0.15)
    jl = np.interp(np.log2(BANDS), np.log2([125.0, 8000.0]), [0.69, 0.40])
    ax.plot(BANDS, jl, "k--", label="Jackson & Leventhall: 50 living rooms (mean, end points)")
    ax.axhspan(0.35, 0.45, color="grey", alpha=0.2, label="BBC: better-furnished living rooms")
    ax.set_xscale("log")
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_xticks(BANDS, [f"{int(b)}" if b < 1000 else f"{int(b / 1000)}k" for b in BANDS])
    ax.set_xlabel("octave band (Hz)")
    ax.set_ylabel("T30 (s)")
    ax.set_title(f"T30 of rendered RIRs, {args.seeds} generated apartments\n(median, 10th-90th percentile shaded)")
    ax.legend(fontsize=7)
    mid = t30[:, 2:4].mean(axis=1)
    bins = np.linspace(0.1, 1.5, 29)
    bx.hist([mid[soft], mid[~soft]], bins=bins, stacked=True, color=["tab:blue", "tab:orange"], label=["furnished rooms", "kitchens, bathrooms, corridors"])
    bx.axvspan(0.35, 0.6, color="green", alpha=0.1, label="target median 0.35-0.6 s")
    bx.axvline(0.9, color="red", ls=":", label="target 90th percentile <= 0.9 s")
    bx.set_xlabel("T30, mean of 500 Hz and 1 kHz (s)")
    bx.set_ylabel("rooms")
    bx.set_title(
        f"furnished rooms: median {np.median(mid[soft]):.2f} s, p90 {np.percentile(mid[soft], 90):.2f} s\n"
        f"kitchens, bathrooms, corridors: median {np.median(mid[~soft]):.2f} s"
    )
    bx.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}: furnished median {np.median(mid[soft]):.2f} s, p90 {np.percentile(mid[soft], 90):.2f} s; "
          f"per-band medians {np.round(np.median(t30[soft], axis=0), 2).tolist()}; hard rooms median {np.median(mid[~soft]):.2f} s, "
          f"p10-p90 {np.percentile(mid[~soft], 10):.2f}-{np.percentile(mid[~soft], 90):.2f} s")


if __name__ == "__main__":
    main()
