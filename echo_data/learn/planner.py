"""The planner baseline: first second of binaural audio (+ first head image) -> skill chain.

The model answers two questions about the first observation of an episode (frame 0, whose
audio features cover the first second the robot heard): which event categories sound (one
logit each) and, when several do, which to resolve first (one priority score each, trained with
a pairwise logistic loss on multi-event episodes). The chain is then the sounding categories
sorted by score, each expanded into its skill template learned from the training chains (e.g.
doorbell -> Navigate door, OpenDoor door). The Place target of an object (the nearest free
receptacle) cannot be heard; the template uses its most frequent kind in training, and the
evaluation reports chain accuracy with and without that target.

Training chooses (checkpoint, decoder) on validation only and never reads the test split;
`score_test` scores a finished run on the test split, whose sound instances are never heard in
training, as a separate act (`echo-data evaluate-planner RUN`), so that the options are not
tuned by looking at test figures.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from echo_data.dataset.reader import dataset_manifest
from echo_data.evaluation.metrics import plan_right_without_receptacle
from echo_data.learn import runs
from echo_data.learn.data import split_episodes
from echo_data.learn.features import FeatureSpec, feature_spec
from echo_data.learn.loop import LoopConfig, fit, setup_torch
from echo_data.learn.metrics import rate
from echo_data.learn.planner_config import PlannerConfig
from echo_data.learn.planner_data import Episodes, chain_of, chosen_episodes, episode_rows, learn_templates, load_episodes
from echo_data.skill_table import role_of

PLANNER_CLASS = "echo_data.learn.policy:PlannerModel"


VAL_BY = ("episodes", "sounds")
ENCODERS = ("flat", "pooled")
ORDERS = ("learned", "priority")
# "accuracy": the mean of the single-event and the multi-event validation accuracy (each group
# weighs half, as the goals are stated per group): validation by sounds holds few multi-event
# episodes (both sounds must be held out), and the plain accuracy let single events choose alone.
SELECT = {"loss": "val_loss", "accuracy": "val_balanced_accuracy"}
# Augmentation ranges (training rows only). Pitch: a shift of up to 2 mel bands moves a tone by
# about 3-8 % in frequency above 1 kHz (mel bands are near-logarithmic there), the spread between
# instances of a ringtone or a beeper; gain: +-6 dB, the level change of a source moved
# by a factor of two in distance (inverse-square law); masks as SpecAugment (Park et al. 2019,
# "SpecAugment: A Simple Data Augmentation Method for ASR"): one band of up to 8 mel bands and one
# stretch of up to 20 frames (0.2 s) set to the mean. Pitch-shift augmentation for environmental
# sound classification: Salamon & Bello 2017 (IEEE SPL 24(3)).
AUG_SHIFT_BANDS, AUG_GAIN_DB, AUG_FREQ_MASK, AUG_TIME_MASK = 2, 6.0, 8, 20


def augment_audio(x: Any, std_db: Any, rng: np.random.Generator) -> Any:
    """(B, 2, F, T) normalised log-mel (dB / per-ear std `std_db`, (1, 2, 1, 1)) -> an augmented copy: the same pitch
    shift, gain and masks on both ears of an example (interaural cues stay as heard)."""
    out = x.clone()
    b, _, f, t = x.shape
    for n in range(b):
        k = int(rng.integers(-AUG_SHIFT_BANDS, AUG_SHIFT_BANDS + 1))
        if k > 0:
            out[n, :, k:] = x[n, :, :-k]
            out[n, :, :k] = x[n, :, :1]
        elif k < 0:
            out[n, :, :k] = x[n, :, -k:]
            out[n, :, k:] = x[n, :, -1:]
        out[n] += float(rng.uniform(-AUG_GAIN_DB, AUG_GAIN_DB)) / std_db[0]
        w, lo = int(rng.integers(0, AUG_FREQ_MASK + 1)), int(rng.integers(0, f))
        out[n, :, lo : lo + w] = 0.0
        w, lo = int(rng.integers(0, AUG_TIME_MASK + 1)), int(rng.integers(0, t))
        out[n, :, :, lo : lo + w] = 0.0
    return out


def resolve(cfg: PlannerConfig) -> PlannerConfig:
    from echo_data.learn.models import audio_shape

    root = Path(cfg.dataset)
    manifest = dataset_manifest(root, "train", "(the planner trains on train)")
    rows = episode_rows(root, "train")
    spec = feature_spec(root, cfg.inputs, audio=cfg.audio, image_size=cfg.image_size)
    shape = audio_shape(spec, manifest["layout"])
    # Every category the recipe can sound, so a test-only category is at least representable.
    recipe_cats = manifest.get("recipe", {}).get("events", {}).get("categories", {})
    cats = sorted(set(recipe_cats) | {e["category"] for r in rows for e in r["events"]})
    priority = list(manifest.get("recipe", {}).get("events", {}).get("priority", []))
    if cfg.order == "priority" and not set(cats) <= set(priority):
        raise runs.RunError(f"{root / 'manifest.json'}: recipe.events.priority does not rank every category (--order priority needs it)")
    return PlannerConfig(
        **{**asdict(cfg), "dataset": str(root.resolve()), "features": spec.to_dict(), "audio_shape": list(shape) if shape else None,
           "categories": cats, "templates": learn_templates(rows), "event_sets": event_sets(rows), "priority": priority}
    )


def build_model(cfg: PlannerConfig) -> Any:
    from echo_data.learn.models import PlannerNet, stored_audio_shape

    return PlannerNet(FeatureSpec.from_dict(cfg.features), stored_audio_shape(cfg.audio_shape), len(cfg.categories), audio_encoder=cfg.encoder)


DECODERS = ("threshold", "sets")


def decode(logits: np.ndarray, scores: np.ndarray, categories: list[str], sets: list[list[str]] | None = None,
           priority: list[str] | None = None) -> list[str]:
    """Sounding categories, most urgent first. Without `sets` ("threshold"): every category whose
    logit is > 0, at least the most likely one. With `sets` ("sets": the event sets of the training
    episodes, e.g. one relocation and one state event at most): the most probable of those sets
    under independent per-category probabilities sigmoid(logit) -- the answer cannot be a set the
    recipe never makes, such as two state events. Ordered by `priority` (the recipe's rule) when
    given, else by the learned scores."""
    if sets:
        index = {c: i for i, c in enumerate(categories)}
        gain = -np.logaddexp(0.0, -logits) + np.logaddexp(0.0, logits)  # log p(on) - log p(off)
        best = max(sets, key=lambda s: float(sum(gain[index[c]] for c in s)))
        on = [index[c] for c in best]
    else:
        on = [i for i in range(len(categories)) if logits[i] > 0] or [int(np.argmax(logits))]
    if priority:
        return sorted((categories[i] for i in on), key=priority.index)
    return [categories[i] for i in sorted(on, key=lambda i: -scores[i])]


def event_sets(rows: list[dict[str, Any]]) -> list[list[str]]:
    """The distinct event sets (sorted categories) of episode rows, sorted."""
    return [list(t) for t in sorted({tuple(sorted(e["category"] for e in r["events"])) for r in rows})]


def _targets(ep: Episodes, categories: list[str]) -> tuple[Any, Any]:
    """Multi-hot labels (n, C) and, per episode, the (first, second) category indices of its
    first two events (-1 when it has one)."""
    import torch

    y = torch.zeros(len(ep.events), len(categories))
    pairs = torch.full((len(ep.events), 2), -1, dtype=torch.long)
    for n, evs in enumerate(ep.events):
        idx = [categories.index(c) for c in evs if c in categories]
        y[n, idx] = 1.0
        if len(idx) >= 2 and idx[0] != idx[1]:
            pairs[n] = torch.tensor(idx[:2])
    return y, pairs


def planner_loss(logits: Any, scores: Any, y: Any, pairs: Any) -> Any:
    import torch.nn.functional as F

    loss = F.binary_cross_entropy_with_logits(logits, y)
    multi = pairs[:, 0] >= 0
    if bool(multi.any()):
        s = scores[multi]
        p = pairs[multi]
        margin = s.gather(1, p[:, :1]) - s.gather(1, p[:, 1:])
        loss = loss + F.softplus(-margin).mean()
    return loss


def score(predicted: list[list[str]], ep: Episodes, templates: dict[str, list[list[str]]]) -> dict[str, Any]:
    """Accuracies with Wilson 95 % intervals, overall and for single- and multi-event episodes."""
    out: dict[str, Any] = {}
    for name, sel in (("all", lambda e: True), ("single_event", lambda e: len(e) == 1), ("multi_event", lambda e: len(e) >= 2)):
        ix = [n for n, e in enumerate(ep.events) if sel(e)]
        events = sum(predicted[n] == ep.events[n] for n in ix)
        chain = sum(chain_of(predicted[n], templates) == ep.chains[n] for n in ix)
        chain_np = sum(plan_right_without_receptacle(chain_of(predicted[n], templates), ep.chains[n]) for n in ix)
        out[name] = {
            "events_in_order": rate(events, len(ix)),
            "chain_without_place_target": rate(chain_np, len(ix)),
            "chain_exact": rate(chain, len(ix)),
        }
        if name == "multi_event":
            out[name]["event_set"] = rate(sum(sorted(predicted[n]) == sorted(ep.events[n]) for n in ix), len(ix))
    return out


def predict(model: Any, ep: Episodes, categories: list[str], sets: list[list[str]] | None = None, priority: list[str] | None = None) -> list[list[str]]:
    import torch

    with torch.no_grad():
        logits, scores = model(ep.inputs)
    return [decode(logits[n].numpy(), scores[n].numpy(), categories, sets, priority) for n in range(len(ep.events))]


def errors(predicted: list[list[str]], events: list[list[str]]) -> dict[str, Any]:
    """What went wrong, by kind: per true event list, the wrong answers counted ("true -> said"),
    and how many wrong answers had the right set in the wrong order, a missing or an extra event,
    or a wrong category in its place."""
    wrong = [(e, p) for p, e in zip(predicted, events) if p != e]
    kinds: Counter[str] = Counter()
    for e, p in wrong:
        se, sp = set(e), set(p)
        kinds["order" if se == sp else "missed" if sp < se else "extra" if se < sp else "swapped"] += 1
    pairs = Counter(f"{'+'.join(e)} -> {'+'.join(p)}" for e, p in wrong)
    return {"wrong": len(wrong), "of": len(events), "kinds": dict(sorted(kinds.items())), "pairs": dict(pairs.most_common())}


def mix_examples(a: Any, b: Any, ya: Any, yb: Any, std: Any, mean: Any, rank: dict[int, int]) -> tuple[Any, Any, Any]:
    """Row n of single-event batches `a` and `b` (normalised log-mel (B, 2, F, T), multi-hot labels
    (B, C)) -> the mix heard at once: the powers summed (normalised dB -> power -> sum -> dB), the
    labels united and the (first, second) category pair ordered by `rank` (category index ->
    position in the priority rule). Why power: two sources heard together add their intensities
    (an incoherent sum), not their levels in dB."""
    import torch

    da, db = a * std + mean, b * std + mean
    mixed = (10.0 * torch.log10(torch.pow(10.0, da / 10.0) + torch.pow(10.0, db / 10.0)) - mean) / std
    first, second = ya.argmax(dim=1).tolist(), yb.argmax(dim=1).tolist()
    pairs = torch.tensor([sorted((i, j), key=lambda c: rank[c]) for i, j in zip(first, second)], dtype=torch.long).view(-1, 2)
    return mixed, torch.clamp(ya + yb, max=1.0), pairs


def train_planner(cfg: PlannerConfig, out: Path, resume: bool = False, overwrite: bool = False, progress: bool = True) -> dict[str, Any]:
    """Train on the train split and choose the checkpoint and decoder on validation (held-out
    train episodes); writes eval.json (validation figures only: the test split is not read, see
    `planner_score.score_test`) in the run folder and returns it. Long because setup, resume, the
    epoch loop and the choice of checkpoint and decoder share one run's state."""
    runs.check_out(out, resume, overwrite)
    if resume:
        saved = PlannerConfig.from_dict(runs.read_json(out / runs.CONFIG))
        runs.check_same_run(out, asdict(cfg), asdict(saved), ("dataset", "inputs", "seed", "audio", "image_size", "train_episodes", "val_by", "select", "augment",
                                                                "encoder", "order", "mix"))
        cfg = PlannerConfig.from_dict({**asdict(saved), "epochs": cfg.epochs, "max_steps": cfg.max_steps})
    else:
        if cfg.val_by not in VAL_BY:
            raise runs.RunError(f"--val-by: unknown {cfg.val_by!r}; choose from {', '.join(VAL_BY)}")
        if cfg.select not in SELECT:
            raise runs.RunError(f"--select: unknown {cfg.select!r}; choose from {', '.join(SELECT)}")
        if cfg.encoder not in ENCODERS:
            raise runs.RunError(f"--encoder: unknown {cfg.encoder!r}; choose from {', '.join(ENCODERS)}")
        if cfg.order not in ORDERS:
            raise runs.RunError(f"--order: unknown {cfg.order!r}; choose from {', '.join(ORDERS)}")
        if not 0.0 <= cfg.mix < 1.0:
            raise runs.RunError(f"--mix {cfg.mix}: must be within [0, 1)")
        if cfg.mix > 0 and cfg.audio != "mel":  # mix_examples sums powers from dB; the spectrogram is log1p of magnitudes
            raise runs.RunError(f"--mix {cfg.mix} needs --audio mel (the log-mel in dB; mixing sums powers)")
        cfg = resolve(cfg)
    torch = setup_torch(cfg.seed, cfg.threads)
    spec = FeatureSpec.from_dict(cfg.features)
    root = Path(cfg.dataset)
    meta = episode_rows(root, "train")
    if cfg.train_episodes is not None and cfg.train_episodes > len(meta):
        raise runs.RunError(f"--train-episodes {cfg.train_episodes}: the train split of {root} has {len(meta)} episodes")
    chosen, val_set, held = chosen_episodes(cfg, meta)
    train = load_episodes(root, "train", spec, frames=cfg.train_frames, episodes=chosen)
    val_eps = split_episodes(train.index, cfg.val_fraction, cfg.seed) if val_set is None else np.asarray(sorted(val_set), dtype=np.int64)
    cfg.val_episodes = [int(e) for e in val_eps]
    is_val = np.isin(train.index, val_eps)
    tr, va = np.flatnonzero(~is_val), np.flatnonzero(is_val & (train.frame == 0))
    y, pairs = _targets(train, cfg.categories)
    audio_std = torch.tensor(spec.audio_std, dtype=torch.float32).view(1, -1, 1, 1)
    audio_mean = torch.tensor(spec.audio_mean, dtype=torch.float32).view(1, -1, 1, 1)
    priority = cfg.priority if cfg.order == "priority" else None
    # Mixing partners: training rows of single-event episodes, by kind of event (state, relocation).
    state_cats = {c for c, tpl in cfg.templates.items() if not any(role_of(skill) == "deliver" for skill, _ in tpl)}
    singles = {kind: np.asarray([n for n in tr if len(train.events[n]) == 1 and (train.events[n][0] in state_cats) == kind], dtype=np.int64)
               for kind in (True, False)}
    rank = {cfg.categories.index(c): k for k, c in enumerate(cfg.priority) if c in cfg.categories}

    torch.manual_seed(cfg.seed)
    model = build_model(cfg)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    runs.write_run_files(out, "planner", PLANNER_CLASS, asdict(cfg), {"inputs": list(cfg.inputs)})

    def part(ix: np.ndarray) -> dict[str, Any]:
        t = torch.from_numpy(ix)
        return {k: v[t] for k, v in train.inputs.items()}

    def loss_fn(ix: np.ndarray) -> Any:
        x = part(ix)
        yb, pb = y[ix], pairs[ix]
        rng = np.random.default_rng([cfg.seed, *ix[:8].tolist()])  # seeded by the batch itself, so a resumed run draws the same
        if cfg.mix > 0 and "audio" in x and all(len(v) for v in singles.values()):
            partner = torch.full((len(ix),), -1, dtype=torch.long)
            for n, i in enumerate(ix):
                if len(train.events[i]) == 1 and rng.random() < cfg.mix:
                    other = singles[train.events[i][0] not in state_cats]
                    partner[n] = int(other[rng.integers(len(other))])
            rows = torch.nonzero(partner >= 0).flatten()
            if len(rows):
                mixed, ym, pm = mix_examples(x["audio"][rows], train.inputs["audio"][partner[rows]], yb[rows], y[partner[rows]], audio_std, audio_mean, rank)
                x["audio"], yb, pb = x["audio"].clone(), yb.clone(), pb.clone()
                x["audio"][rows], yb[rows], pb[rows] = mixed, ym, pm
        if cfg.augment and "audio" in x:
            x["audio"] = augment_audio(x["audio"], audio_std, rng)
        logits, scores = model(x)
        return planner_loss(logits, scores, yb, pb)

    def val_accuracy(logits: Any, scores: Any, sets: list[list[str]] | None) -> tuple[float, float]:
        """(plain, balanced) validation accuracy of the events in order: balanced is the mean of the
        single- and the multi-event episodes' accuracies."""
        pred = [decode(logits[n].numpy(), scores[n].numpy(), cfg.categories, sets, priority) for n in range(len(va))]
        right = np.asarray([p == train.events[i] for p, i in zip(pred, va)], dtype=float)
        multi = np.asarray([len(train.events[i]) >= 2 for i in va])
        return float(right.mean()), float(np.mean([right[g].mean() for g in (~multi, multi) if g.any()]))

    def validate() -> dict[str, float]:
        if len(va) == 0:
            return {"val_loss": math.nan, "val_events_accuracy": math.nan, "val_balanced_accuracy": math.nan}
        with torch.no_grad():
            logits, scores = model(part(va))
            loss = float(planner_loss(logits, scores, y[va], pairs[va]))
        plain, balanced = val_accuracy(logits, scores, None)
        return {"val_loss": loss, "val_events_accuracy": plain, "val_balanced_accuracy": balanced}

    loop = LoopConfig(cfg.epochs, cfg.batch_size, cfg.seed, cfg.max_steps, select=SELECT[cfg.select])
    state = fit(model, opt, tr, loss_fn, validate, loop, out, resume, progress, desc="train planner")
    best = runs.load_torch(out / runs.BEST)
    model.load_state_dict(best["model"])
    model.eval()
    # The decoder of the kept weights, chosen on validation (balanced accuracy; a tie keeps "threshold").
    decoders = {"threshold": None, "sets": cfg.event_sets}
    val_by_decoder: dict[str, float] = {}
    if len(va):
        with torch.no_grad():
            logits, scores = model(part(va))
        val_by_decoder = {name: val_accuracy(logits, scores, sets)[1] for name, sets in decoders.items()}
        cfg.decode = max(DECODERS, key=lambda d: (val_by_decoder[d], d == "threshold"))
        val_said = [decode(logits[n].numpy(), scores[n].numpy(), cfg.categories, decoders[cfg.decode], priority) for n in range(len(va))]
        runs.write_run_files(out, "planner", PLANNER_CLASS, asdict(cfg), {"inputs": list(cfg.inputs)})
    fitted = {s for n in tr for s in train.sounds[n]}
    report = {
        "run": str(out),
        "inputs": list(cfg.inputs),
        "audio": cfg.audio,
        "episodes": {"train": int(len(np.unique(train.index[tr]))), "val": int(len(va))},
        "train_rows": int(len(tr)),
        "step": state["step"],
        "seconds": round(state["seconds"], 1),
        "val_by": cfg.val_by,
        "val_sounds_held_out": held,
        # validation episodes playing an instance the fitted rows play: 0 means the validation hears
        # only unheard voices (by construction with --val-by sounds, or with fresh training instances)
        "val_episodes_hearing_fitted_sounds": int(sum(any(s in fitted for s in train.sounds[n]) for n in va)),
        "select": cfg.select,
        "augment": cfg.augment,
        "best": {k: best.get(k) for k in ("epoch", "val_loss", "val_events_accuracy", "val_balanced_accuracy")},
        "best_val_loss": best.get("val_loss"),
        "templates": cfg.templates,
        "decode": cfg.decode,
        "val_balanced_accuracy_by_decoder": val_by_decoder,
        "encoder": cfg.encoder,
        "order": cfg.order,
        "mix": cfg.mix,
        # what the kept checkpoint gets wrong on validation (the diagnosis that chooses)
        "val_errors": errors(val_said, [train.events[i] for i in va]) if len(va) else {},
    }
    runs.write_json(out, runs.EVAL, report)
    return report


