"""`echo-data info`: what a dataset holds, from its manifest and meta/episodes.parquet."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from echo_data.dataset.reader import episode_records, has_episode_records, read_manifest


def info(out: Path) -> dict[str, Any]:
    """Summary of the dataset at `out`: episodes (split -> count), steps, skills, bytes, and more.

    Raises `ManifestError` when `out` is not a dataset.
    """
    out = Path(out)
    m = read_manifest(out)
    counts = m["counts"]
    sounds: dict[str, list[str]] = {}
    events: dict[str, dict[str, int]] = {}
    if has_episode_records(out):
        for row in episode_records(out, ["split", "events"]):
            for e in row["events"]:
                sounds.setdefault(row["split"], [])
                if e["sound_id"] not in sounds[row["split"]]:
                    sounds[row["split"]].append(e["sound_id"])
                cats = events.setdefault(row["split"], {})
                cats[e["category"]] = cats.get(e["category"], 0) + 1
    size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    return {
        "name": m["name"],
        "path": str(out),
        "complete": m["complete"],
        "recipe_hash": m["recipe_hash"],
        "limit": m["limit"],
        "episodes": {s: counts["episodes"].get(s, 0) for s in m["splits"]},
        "episodes_planned": {s: v["episodes"] for s, v in m["splits"].items()},
        "steps": sum(counts["steps"].values()),
        "steps_per_split": {s: counts["steps"].get(s, 0) for s in m["splits"]},
        "settings": counts["settings"],
        "skills": m["skills"],
        "episode_success_rate": counts["episode_success_rate"],
        "failed_attempts": len(m["failed_episodes"]),
        "rejections": m["rejected"],
        "sound_instances": {s: len(v) for s, v in sorted(sounds.items())},
        "events": events,
        "shards": len(m["shards"]),
        "bytes": size,
        "versions": m["versions"],
    }


def format_info(d: dict[str, Any]) -> str:
    """Human-readable lines for the CLI."""
    lines = [
        f"{d['name']} at {d['path']} ({'complete' if d['complete'] else 'INCOMPLETE'}, recipe {d['recipe_hash'][:12]}"
        + (f", --limit {d['limit']}" if d["limit"] is not None else "")
        + ")",
        "episodes: " + ", ".join(f"{s} {n}/{d['episodes_planned'][s]}" for s, n in d["episodes"].items()),
        f"steps: {d['steps']} ({', '.join(f'{s} {n}' for s, n in d['steps_per_split'].items())}) in {d['shards']} shards, "
        f"{d['bytes'] / 1e6:.1f} MB",
        "settings: " + "; ".join(f"{s}: " + ", ".join(f"{k} {v}" for k, v in c.items()) for s, c in d["settings"].items()),
        "skills: " + ", ".join(f"{k} {v['successes']}/{v['attempts']}" for k, v in d["skills"].items()),
        f"failed attempts: {d['failed_attempts']}; rejections: "
        + (", ".join(f"{k} {v}" for k, v in d["rejections"].items()) or "none"),
        "sound instances: " + ", ".join(f"{s} {n}" for s, n in d["sound_instances"].items()),
    ]
    return "\n".join(lines)
