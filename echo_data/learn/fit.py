"""Training one skill with any registered algorithm: data, split, normalisation, device, the
shared epoch loop (`loop.fit`), validation and the closed-loop checkpoint choice.

Targets are the cloned action column's next `window` actions within the segment (padding past
its end masked), continuous entries normalised with the dataset's statistics (the skill's own
training rows for the delta form and for columns the statistics lack), binary entries kept 0/1.
Validation: whole episodes of the train split held out (`split_episodes`); the test split is
never read here. Sequence algorithms (BC-RNN) train on whole segments, `batch_size` per step,
padded to the longest and masked. Deterministic for a seed: fixed thread count, deterministic
kernels, weights initialised from the seed, the batch order of epoch e drawn from (seed, e), and
each batch's augmentation and diffusion noise drawn from the batch itself, so a resumed run
draws the same batches as an uninterrupted one.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.reader import dataset_manifest
from echo_data.learn import runs
from echo_data.learn.algos import build_model, config_from_run
from echo_data.learn.algos.base import SkillConfig, held_entries
from echo_data.learn.carry import carried_skills
from echo_data.learn.data import SkillRows, append_rows, count_rows, load_skill_rows, skill_kinds, skills_in, split_episodes
from echo_data.learn.features import ACTION_FORMS, FeatureSpec, feature_spec, to_action_form
from echo_data.learn.loop import LoopConfig, fit, setup_torch

POLICY_CLASS = runs.POLICY_CLASS
IMAGE_INPUTS = ("depth", "wrist_depth", "rgb", "image")
# What a resumed run must share with the run it continues.
SAME_RUN = ("dataset", "skill", "inputs", "seed", "audio_form", "action_form", "action_column", "algo", "stop", "from_stance", "with_carries", "select_recipe")


def resolve_device(name: str) -> str:
    """cpu | cuda | auto -> the torch device to train on (RunError when cuda is asked and absent)."""
    import torch

    if name == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if name == "cuda" and not torch.cuda.is_available():
        raise runs.RunError("--device cuda: this machine has no CUDA device torch can use (try --device auto)")
    return name


def resolve(cfg: SkillConfig) -> SkillConfig:
    """Check the request against the dataset and freeze the constants (raises ConfigError /
    FeatureError / RunError with a one-line message)."""
    from echo_data.learn.models import audio_shape

    cfg.check()
    root = Path(cfg.dataset)
    manifest = dataset_manifest(root, "train", "to learn from")
    if cfg.action_form not in ACTION_FORMS:
        raise runs.RunError(f"--action-form: unknown form {cfg.action_form!r}; choose from {', '.join(ACTION_FORMS)}")
    if cfg.action_form == "delta" and not {"state", "state_raw"} & set(cfg.inputs):
        raise runs.RunError("--action-form delta adds the predicted change to the measured joints: --inputs needs state")
    skills = skills_in(root, "train")
    if cfg.skill not in skills:
        raise runs.RunError(f"--skill {cfg.skill!r}: no such rows in {root} (train split has {', '.join(skills)})")
    spec = feature_spec(root, cfg.inputs, audio=cfg.audio, image_size=cfg.image_size, audio_form=cfg.audio_form,
                        kinds=tuple(sorted({k for s in (cfg.skill, *carried_skills(cfg.with_carries)) for k in skill_kinds(root, "train", s)})))
    smallest = min((min(s) if isinstance(s, tuple) else s for s in (spec.side(n) for n in IMAGE_INPUTS if n in cfg.inputs)), default=None)
    if cfg.shift and smallest is not None and cfg.shift >= smallest:
        raise runs.RunError(f"--shift {cfg.shift}: must be below the image side ({smallest} px)")
    stats = runs.read_json(root / "meta" / "stats.json").get(cfg.action_column)
    shape = audio_shape(spec, manifest["layout"])
    out = type(cfg).from_dict({**asdict(cfg), "dataset": str(root.resolve()), "features": spec.to_dict(), "audio_shape": list(shape) if shape else None})
    if stats is not None and cfg.action_form == "absolute":
        out.action_mean = list(stats["mean"])
        out.action_std = [s if s > 1e-3 else 1.0 for s in stats["std"]]
    out.algo = cfg.ALGO
    return out


class Units:
    """What one optimiser step draws: rows, or whole segments for a sequence algorithm, and how a
    draw becomes (model inputs, row index (N,), real (N,) bool; padding rows of a short segment
    are not real)."""

    def __init__(self, rows: SkillRows, sequence: bool, device: str, history: int = 1) -> None:
        self.rows, self.sequence, self.device = rows, sequence, device
        self.history = None
        if history > 1:  # rows t-history+1 .. t of each row, clamped to its segment's first row (as acting pads)
            _, first, inverse = np.unique(rows.segments, return_index=True, return_inverse=True)
            start = first[inverse]
            start[rows.segments < 0] = np.flatnonzero(rows.segments < 0)  # appended rows: no history
            self.history = np.maximum(np.arange(len(rows))[:, None] + np.arange(1 - history, 1)[None, :], start[:, None])
        if sequence:
            if (rows.segments < 0).any():
                raise runs.RunError("a recurrent model trains on whole segments: appended rows without one cannot train it")
            ids, first, count = np.unique(rows.segments, return_index=True, return_counts=True)
            self.spans = {int(i): (int(f), int(c)) for i, f, c in zip(ids, first, count, strict=True)}

    def split(self, is_val: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Train and validation units (row indices or segment ids) from the per-row mask."""
        if not self.sequence:
            return np.flatnonzero(~is_val), np.flatnonzero(is_val)
        seg = np.array(sorted(self.spans))
        val = np.array([is_val[self.spans[s][0]] for s in seg], dtype=bool)
        return seg[~val], seg[val]

    def inputs(self, units: np.ndarray, shift: int = 0, seed: int = 0) -> tuple[dict[str, Any], np.ndarray, np.ndarray, Any]:
        """(inputs on the device, row index, real mask, a torch generator drawn from the batch)."""
        import torch

        rng = np.random.default_rng([seed, len(units), *units.tolist()])  # from the batch itself: a resumed run draws alike
        gen = torch.Generator().manual_seed(int(rng.integers(2**63)))
        src = self.rows.inputs
        if not self.sequence:
            t = torch.from_numpy(units if self.history is None else self.history[units])
            x = {k: shifted(v[t], shift, rng) if k in IMAGE_INPUTS else v[t] for k, v in src.items()}
            return {k: v.to(self.device) for k, v in x.items()}, units, np.ones(len(units), dtype=bool), gen
        spans = [self.spans[int(s)] for s in units]
        length = max(c for _, c in spans)
        steps = np.arange(length)
        real = steps[None, :] < np.array([c for _, c in spans])[:, None]
        ix = np.array([f + np.minimum(steps, c - 1) for f, c in spans])  # padded with each segment's last row
        t = torch.from_numpy(ix.reshape(-1))
        x = {k: v[t].view(len(spans), length, *v.shape[1:]) for k, v in src.items()}
        x = {k: (shifted(v, shift, rng) if k in IMAGE_INPUTS else v).to(self.device) for k, v in x.items()}
        return x, ix.reshape(-1), real.reshape(-1), gen


def shifted(x: Any, shift: int, rng: np.random.Generator) -> Any:
    """Random-shift augmentation (DrQ, Kostrikov et al. 2020; RAD, Laskin et al. 2020): pad each
    image by `shift` pixels (edge values repeated) and crop back at a random offset, one offset
    per sample (per segment for sequences: the camera is off by a constant). Why: with tens of
    demonstrations a CNN otherwise keys on exact pixel positions of one room."""
    if shift <= 0:
        return x
    import torch
    import torch.nn.functional as F

    c, h, w = x.shape[-3:]
    parts = []
    for sample in x:  # (C, H, W), or (T, C, H, W) for a segment
        dy, dx = (int(v) for v in rng.integers(0, 2 * shift + 1, size=2))
        padded = F.pad(sample.reshape(-1, c, h, w), (shift, shift, shift, shift), mode="replicate")
        parts.append(padded[..., dy : dy + h, dx : dx + w].reshape(sample.shape))
    return torch.stack(parts)


def train_skill(cfg: SkillConfig, out: Path, resume: bool = False, overwrite: bool = False, progress: bool = True, extra: Any = None) -> dict[str, Any]:
    """Train (or continue) a skill run in `out`; returns the summary also printed by the CLI.
    Long because setup, resume, the epoch loop and the closing summary share one run's state.

    `extra` (DAgger's labelled rollouts, `learn.dagger.Rollouts`: `inputs` and `windows(chunk, stop)`,
    one segment per rollout) is appended to the training rows as segments, never to validation."""
    from tqdm import tqdm

    if resume:
        runs.check_out(out, resume, overwrite)
        saved = config_from_run(runs.read_json(out / runs.CONFIG))
        runs.check_same_run(out, {**asdict(cfg), "algo": cfg.ALGO}, {**asdict(saved), "algo": saved.ALGO}, SAME_RUN)
        cfg = type(saved).from_dict({**asdict(saved), "epochs": cfg.epochs, "max_steps": cfg.max_steps, "device": cfg.device,
                                     "select_every": cfg.select_every, "select_episodes": cfg.select_episodes})
        cfg.check()
    else:
        cfg = resolve(cfg)
    if cfg.select_every:  # before --overwrite removes anything: a choice that cannot run is refused with nothing changed
        from echo_data.learn.select import check_selection

        check_selection(cfg)
    if not resume:
        runs.check_out(out, resume, overwrite)
    device = resolve_device(cfg.device)
    if device == "cuda":  # cuBLAS is deterministic only with a fixed workspace (torch's reproducibility notes)
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
    torch = setup_torch(cfg.seed, cfg.threads)
    spec = FeatureSpec.from_dict(cfg.features)
    root = Path(cfg.dataset)
    total_rows = count_rows(root, "train", cfg.skill)
    with tqdm(total=total_rows, desc=f"decode {cfg.skill}", unit="row", disable=not progress, leave=False) as bar:
        rows = load_skill_rows(root, "train", cfg.skill, spec, chunk=cfg.window(), tick=bar.update, action_column=cfg.action_column, stop=cfg.stop,
                               from_stance=cfg.from_stance, with_carries=cfg.with_carries)
    val_eps = split_episodes(rows.episodes, cfg.val_fraction, cfg.seed)
    cfg.val_episodes = [int(e) for e in val_eps]
    binary = list(cfg.binary)
    if cfg.action_form != "absolute":
        if extra is not None and len(extra):
            raise runs.RunError(f"--action-form {cfg.action_form} does not take DAgger rows (their states are not kept)")
        assert rows.states is not None
        rows.actions = to_action_form(rows.actions, rows.states, cfg.action_form)
    kept = ~np.isin(rows.episodes, val_eps)  # the training rows (validation episodes left out)
    if not resume:  # entries the demonstrations never vary are acted exactly (`held_entries`)
        cfg.held_entries = held_entries(rows.actions[kept, 0, : len(cfg.action_names)])  # each row's own action (position 0: never padded)
    if not cfg.action_mean:  # the skill's own training rows set the scale
        fit_rows = rows.actions[kept][~rows.action_pad[kept]]
        cfg.action_mean = [float(v) for v in fit_rows.mean(axis=0)]
        cfg.action_std = [float(v) if v > 1e-3 else 1.0 for v in fit_rows.std(axis=0)]
    if len(cfg.action_mean) < len(cfg.target_names):  # the dataset's statistics cover the action, not the STOP
        cfg.action_mean = [*cfg.action_mean, 0.0]
        cfg.action_std = [*cfg.action_std, 1.0]
    if binary:  # binary entries are classified, not regressed: kept as 0/1
        cfg.action_mean = [0.0 if i in binary else v for i, v in enumerate(cfg.action_mean)]
        cfg.action_std = [1.0 if i in binary else v for i, v in enumerate(cfg.action_std)]
        rows.actions[..., binary] = (rows.actions[..., binary] > 0.5).astype(np.float32)
    if extra is not None and len(extra):
        acts, pad = extra.windows(cfg.window(), cfg.stop)
        rows = append_rows(rows, extra.inputs, acts, pad, extra.segments)
    is_val = np.isin(rows.episodes, val_eps)
    if cfg.stop and not resume:  # the STOP's class balance over the training rows, DAgger's too (`SkillConfig.binary_weights`)
        last = float(rows.actions[~is_val, 0, -1].sum())  # position 0 of a window is never padded
        cfg.stop_weight = float(((~is_val).sum() - last) / last) if last else 1.0
    mean, std = np.asarray(cfg.action_mean, np.float32), np.asarray(cfg.action_std, np.float32)
    target = torch.from_numpy((rows.actions - mean) / std)
    valid = torch.from_numpy(~rows.action_pad).float()

    torch.manual_seed(cfg.seed % 2**63)
    model = build_model(cfg).to(device)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    runs.write_run_files(out, "policy", POLICY_CLASS, cfg.to_dict(), {"algo": cfg.ALGO, "skill": cfg.skill, "inputs": list(cfg.inputs)})
    units = Units(rows, cfg.SEQUENCE, device, cfg.history())
    tr_units, va_units = units.split(is_val)
    tr, va = np.flatnonzero(~is_val), np.flatnonzero(is_val)
    scale = torch.from_numpy(std)
    cont = [i for i in range(len(mean)) if i not in binary]

    def loss_fn(ix: np.ndarray) -> Any:
        x, at, real, gen = units.inputs(ix, cfg.shift, cfg.seed)
        t = torch.from_numpy(at)
        return model.loss(x, target[t].to(device), (valid[t] * torch.from_numpy(real)[:, None]).to(device), gen)

    def validate() -> dict[str, float]:
        """The loss, and the mean absolute error of the next action in physical units over the
        continuous entries and over the base velocities alone (every validation row once)."""
        if len(va_units) == 0:
            return {"val_loss": math.nan, "val_action_mae": math.nan, "val_base_mae": math.nan}
        step = 8 if cfg.SEQUENCE else 256
        lo_sum, ae, base, n = 0.0, 0.0, 0.0, 0
        with torch.no_grad():
            for lo in range(0, len(va_units), step):
                part = va_units[lo : lo + step]
                x, at, real, _ = units.inputs(part)
                gen = torch.Generator().manual_seed(cfg.seed % 2**63)  # the same noise every epoch: losses compare
                keep = torch.from_numpy(real)
                t = torch.from_numpy(at)
                lo_sum += float(model.loss(x, target[t].to(device), (valid[t] * keep[:, None]).to(device), gen)) * int(keep.sum())
                pred = predict_rows(model, x, cfg.SEQUENCE, gen)[keep].cpu()
                err = (pred[:, 0] - target[t][keep][:, 0]).abs() * scale
                ae += float(err[:, cont].mean()) * int(keep.sum())
                base += float(err[:, :3].mean()) * int(keep.sum())
                n += int(keep.sum())
        return {"val_loss": lo_sum / n, "val_action_mae": ae / n, "val_base_mae": base / n}

    counter = {"epoch": runs.load_torch(out / runs.CHECKPOINT)["state"]["epoch"] if resume else 0}

    def validate_epoch() -> dict[str, float]:
        """The validation above, plus every `select_every` epochs (and after the last) the
        closed-loop success on validation-split episodes, which then chooses best.pt."""
        counter["epoch"] += 1
        val = validate()
        if cfg.select_every:
            from echo_data.learn.select import closed_loop_scores

            e = counter["epoch"]
            val.update(closed_loop_scores(cfg, model, out) if e % cfg.select_every == 0 or e == cfg.epochs else {"val_success": math.nan})
        return val

    loop = LoopConfig(cfg.epochs, cfg.batch_size, cfg.seed % 2**63, cfg.max_steps, select="val_success" if cfg.select_every else "val_loss")
    state = fit(model, opt, tr_units, loss_fn, validate_epoch, loop, out, resume, progress, desc=f"train {cfg.ALGO} {cfg.skill}")
    if cfg.stop:  # the STOP threshold chosen with best.pt's weights on validation (select.closed_loop_scores) acts with them
        chosen = runs.load_torch(out / runs.BEST).get("stop_threshold")
        cfg.stop_threshold = float(chosen) if chosen is not None and math.isfinite(chosen) else 0.5
        runs.write_run_files(out, "policy", POLICY_CLASS, cfg.to_dict(), {"algo": cfg.ALGO, "skill": cfg.skill, "inputs": list(cfg.inputs)})
    return {
        "run": str(out),
        "algo": cfg.ALGO,
        "skill": cfg.skill,
        "inputs": list(cfg.inputs),
        "action_column": cfg.action_column,
        **({"stop_threshold": cfg.stop_threshold} if cfg.stop else {}),
        **({"select_recipe": {"path": cfg.select_recipe, "sha256": cfg.select_recipe_sha256}} if cfg.select_recipe else {}),
        "state_fed": list(spec.state_names),
        "device": device,
        "rows": {"train": int(len(tr)), "val": int(len(va)), "dagger": int(len(extra)) if extra is not None else 0},
        "episodes": {"train": int(len(np.unique(rows.episodes[tr]))), "val": int(len(val_eps))},
        "step": state["step"],
        "epoch": state["epoch"],
        "seconds": round(state["seconds"], 1),
        "best_val_loss": state["best_val"] if state["best_val"] != math.inf and not cfg.select_every else None,
        "val_loss_of_mean_train_action": mean_action_loss(target, valid, tr, va),
        "last": state["history"][-1] if state["history"] else None,
    }


def mean_action_loss(target: Any, valid: Any, tr: np.ndarray, va: np.ndarray) -> float:
    """A reference: the mean squared error (normalised units) on validation rows of always
    answering the mean training action of this skill."""
    if not len(va):
        return math.nan
    mean = target[tr].mean(dim=0, keepdim=True)
    err = ((mean - target[va]) ** 2).mean(dim=2)
    return float((err * valid[va]).sum() / valid[va].sum().clamp(min=1))


def predict_rows(model: Any, x: dict[str, Any], sequence: bool, gen: Any = None) -> Any:
    """Predictions (N, W, A) for training-form inputs (rows, or (B, T) segments flattened)."""
    if not sequence:
        return model.predict(x, None, gen)[0]
    y, _ = model(x)
    from echo_data.learn.algos.base import to_probabilities

    return to_probabilities(y.reshape(-1, *y.shape[2:]), model.binary)
