"""Cost of one environment step with online binaural audio vs one build step, measured in the same run.

For the same sampled episodes:
  build    the build as it ran before the environment existed: the experts' rollout with camera
           observations, then the whole episode track rendered offline along the recorded path
           (`render_track`, one pass per door state, crossfaded) and the per-step features
           (`step_features`); no dataset encoding. This is the baseline.
  env      `EchoDataEnv.reset` to the episode and `step` of its recorded actions: physics,
           cameras, the control period heard online (`OnlineTrack`) and its features, every step.
  oracle   the build as it runs now: the experts acting in the environment (`pipeline.simulate`).
Prints ms/step of each and the ratio env / build (the acceptance bound is 1.2).

  python benchmarks/bench_env.py [RECIPE] [-n EPISODES]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def offline_track(spec, ro, recipe, library) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """The episode track rendered after the fact along the recorded path (the pre-environment build)."""
    from echo_data.acoustics.hrtf import Hrtf
    from echo_data.acoustics.room import AcousticScene
    from echo_data.acoustics.stream import SourceTrack, render_track
    from echo_data.envs.audio import epoch_window, pre_roll_steps, step_samples

    cfg = recipe.acoustics
    fs, hop, pre = cfg.sample_rate, step_samples(recipe), pre_roll_steps(recipe)
    poses = np.array([[*s.ear_position, s.ear_yaw] for s in ro.steps])
    poses = np.concatenate([np.repeat(poses[:1], pre, axis=0), poses])
    seconds = len(poses) * hop / fs + cfg.rir_seconds
    sources = [
        SourceTrack(ev.source, library.waveform(ev.sound_id, fs, seconds), None if ro.resolved_frame[e] is None else (ro.resolved_frame[e] + pre) * hop)
        for e, ev in enumerate(spec.events)
    ]
    hrtf = Hrtf.load(cfg.hrtf, fs)
    epochs = [(0, None)] + [((f + pre) * hop, a) for f, a in ro.door_changes]
    track = None
    for e, (start, angles) in enumerate(epochs):
        part = render_track(AcousticScene(spec.plan, cfg, door_angles=angles), sources, poses, hop, cfg, hrtf=hrtf)
        track = np.zeros_like(part) if track is None else track
        end = epochs[e + 1][0] if e + 1 < len(epochs) else None
        track += part * epoch_window(np.arange(len(part)), start if e else None, end, hop)[:, None]
    return track, (pre + np.arange(len(ro.steps))) * hop


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recipe", nargs="?", default=str(ROOT / "recipes" / "quickstart.yaml"))
    ap.add_argument("-n", type=int, default=3, help="episodes")
    args = ap.parse_args()

    from echo_data.acoustics.features import step_features
    from echo_data.envs import EchoDataEnv
    from echo_data.app.pipeline import simulate
    from echo_data.recipe import load_recipe
    from echo_data.scene.sampling import sample_episode
    from echo_data.sounds import SoundLibrary
    from echo_data.world import World

    recipe = load_recipe(args.recipe)
    library = SoundLibrary.from_recipe(recipe, Path(args.recipe).resolve().parent)
    env = EchoDataEnv(recipe, split="train", library=library)
    t_build = t_env = t_oracle = 0.0
    steps = oracle_steps = 0
    for i in range(args.n):
        spec, _ = sample_episode(recipe, "train", i, library)
        w = World(spec, recipe, render=True)
        w.observe()  # the process's first-render cost is part of neither measurement
        w.close()
        t0 = time.perf_counter()
        ro = simulate(spec, recipe, observe=True)
        track, offsets = offline_track(spec, ro, recipe, library)
        step_features(track, offsets, recipe.acoustics.sample_rate, recipe.acoustics.mel_bands)
        t_build += time.perf_counter() - t0
        t0 = time.perf_counter()
        env.reset(options={"spec": spec})
        for s in ro.steps:
            env.step(s.action)
        env.episode_audio()
        t_env += time.perf_counter() - t0
        steps += len(ro.steps)
        t0 = time.perf_counter()
        now = simulate(spec, recipe, observe=True, library=library)
        t_oracle += time.perf_counter() - t0
        oracle_steps += len(now.steps)
        print(f"episode {i}: {spec.setting:18s} steps {len(ro.steps):4d} success {ro.success}")
    env.close()
    b, e, o = t_build / steps, t_env / steps, t_oracle / max(oracle_steps, 1)
    print(f"build   experts + cameras, offline audio + features: {b * 1e3:7.2f} ms/step (baseline)")
    print(f"env     replayed actions, cameras, online audio:     {e * 1e3:7.2f} ms/step  ratio {e / b:5.2f}x")
    print(f"oracle  experts acting in the env (today's build):   {o * 1e3:7.2f} ms/step  ratio {o / b:5.2f}x")


if __name__ == "__main__":
    main()
