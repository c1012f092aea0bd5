"""`echo-data train`: one command per skill-learning algorithm (its options generated from the
algorithm's config) and the audio planner (needs the torch extra)."""

from __future__ import annotations

import inspect
import json
import types
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer

from echo_data.targets import write_failed

train_app = typer.Typer(add_completion=False, no_args_is_help=True, help="Train reference policies on a dataset (needs the torch extra).")

_Dataset = Annotated[Path, typer.Argument(metavar="DATASET", help="Dataset folder (out/<name>).")]
_Epochs = Annotated[int | None, typer.Option("--epochs", min=1, help="Passes over the training rows.")]
_Seed = Annotated[int, typer.Option("--seed", help="Seed of initialisation, split and batch order.")]
_Resume = Annotated[bool, typer.Option("--resume", help="Continue the run in --out from its last checkpoint.")]
_Overwrite = Annotated[bool, typer.Option("--overwrite", help="Replace the run in --out.")]
_MaxSteps = Annotated[int | None, typer.Option("--max-steps", min=1, help="Stop after this many optimiser steps (checkpointed).")]
_Threads = Annotated[int, typer.Option("--threads", min=1, help="torch CPU threads (results are reproducible for a fixed count; 1 is fastest on a busy machine).")]
_Progress = Annotated[bool, typer.Option("--progress/--no-progress", help="Show progress bars.")]


def _fail(message: str) -> typer.Exit:
    typer.echo(f"error: {message}", err=True)
    return typer.Exit(2)


def _errors() -> tuple[type[Exception], ...]:
    from echo_data.dataset.manifest import ManifestError
    from echo_data.dataset.validate import DamagedDataset
    from echo_data.learn.features import FeatureError
    from echo_data.learn.runs import RunError
    from echo_data.targets import TargetError

    return (FeatureError, RunError, TargetError, ManifestError, DamagedDataset)


def _not_applying(ctx: typer.Context, needs: dict[str, tuple[bool, str]]) -> None:
    """Refuse an option given on the command line where it has no effect (it would be stored in
    the run's config as if it had mattered): `needs` maps a parameter to (applies, why not)."""
    for name, (applies, why) in needs.items():
        source = ctx.get_parameter_source(name)  # typer vendors its own click: match the enum by name
        if not applies and source is not None and source.name == "COMMANDLINE":
            raise _fail(f"--{name.replace('_', '-')}: does not apply {why}")


def _check(dataset: Path, folder: Path) -> None:
    """Before any training: the run folder can be written, lies apart from the dataset, and the
    dataset's files are whole."""
    from echo_data.dataset.validate import check_whole
    from echo_data.dataset.written import apart_problem
    from echo_data.learn.runs import RunError
    from echo_data.targets import check_folder

    check_folder(folder, "--out")
    if (dataset / "manifest.json").is_file():  # no dataset at all: training's own message says so
        why = apart_problem(dataset, folder, "training dataset")
        if why:
            raise RunError(why)
        check_whole(dataset)


def _need_torch() -> None:
    try:
        import torch  # noqa: F401
    except ImportError:
        raise _fail("training needs PyTorch: pip install 'echo-data[torch]'") from None


def _option_type(hint: Any) -> Any:
    """A config field's type as the command line takes it (tuples as comma lists)."""
    if hint == tuple[str, ...]:
        return str
    args = [a for a in typing.get_args(hint) if a is not type(None)]
    return args[0] if args and typing.get_origin(hint) in (typing.Union, types.UnionType) else hint


def _read_config_file(path: Path) -> dict[str, Any]:
    """--config FILE: a JSON or YAML mapping of option names (underscores or dashes) to values."""
    import yaml

    try:
        doc = yaml.safe_load(path.read_text())  # JSON is YAML
    except (OSError, yaml.YAMLError) as e:
        raise _fail(f"--config {path}: cannot read ({' '.join(str(e).split())})"[:300]) from None
    if not isinstance(doc, dict):
        raise _fail(f"--config {path}: expected a mapping of option names to values")
    return {str(k).replace("-", "_"): v for k, v in doc.items()}


def _make_train_command(name: str) -> Callable[..., None]:
    """`echo-data train <algo>`: one option per field of the algorithm's config (defaults from the
    config class, then `--config FILE`, then the command line), plus the run-folder options."""
    from echo_data.learn.algos import algorithm

    algo = algorithm(name)
    cls = algo.config
    hints = typing.get_type_hints(cls)
    fields = cls.options()
    params = [inspect.Parameter("dataset", inspect.Parameter.POSITIONAL_OR_KEYWORD, annotation=Path,
                                default=typer.Argument(..., metavar="DATASET", help="Dataset folder (out/<name>)."))]
    for f in fields:
        default = cls.default_of(f)
        shown = ",".join(default) if isinstance(default, tuple) else default
        help_text = f.metadata["help"] + (" (required)" if f.metadata.get("required") else f" (default {shown})")
        params.append(inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, annotation=_option_type(hints[f.name]) | None,
                                        default=typer.Option(None, f"--{f.name.replace('_', '-')}", help=help_text, show_default=False)))
    params += [
        inspect.Parameter("config", inspect.Parameter.KEYWORD_ONLY, annotation=Path | None,
                          default=typer.Option(None, "--config", help="JSON or YAML file of option values (the command line wins).")),
        inspect.Parameter("out", inspect.Parameter.KEYWORD_ONLY, annotation=Path | None,
                          default=typer.Option(None, "--out", help=f"Run folder (default runs/{name}-<skill>-<inputs>).")),
        inspect.Parameter("resume", inspect.Parameter.KEYWORD_ONLY, annotation=bool, default=typer.Option(False, "--resume", help="Continue the run in --out from its last checkpoint.")),
        inspect.Parameter("overwrite", inspect.Parameter.KEYWORD_ONLY, annotation=bool, default=typer.Option(False, "--overwrite", help="Replace the run in --out.")),
        inspect.Parameter("progress", inspect.Parameter.KEYWORD_ONLY, annotation=bool, default=typer.Option(True, "--progress/--no-progress", help="Show progress bars.")),
    ]
    if name == "bc":
        params += [
            inspect.Parameter("dagger", inspect.Parameter.KEYWORD_ONLY, annotation=int, default=typer.Option(
                0, "--dagger", min=0, help="DAgger rounds after BC (Navigate only): roll the learner on train episodes, label with the expert, retrain. With --resume: start from the BC run in --out.")),
            inspect.Parameter("dagger_episodes", inspect.Parameter.KEYWORD_ONLY, annotation=int | None, default=typer.Option(
                None, "--dagger-episodes", min=1, help="Train episodes rolled per DAgger round (default 8).")),
            inspect.Parameter("dagger_steps", inspect.Parameter.KEYWORD_ONLY, annotation=int | None, default=typer.Option(
                None, "--dagger-steps", min=1, help="Learner steps per rollout (default: the Navigate budget).")),
        ]

    def command(**kw: Any) -> None:
        _need_torch()
        from echo_data.learn import runs
        from echo_data.learn.algos.base import ConfigError
        from echo_data.learn.features import BC_INPUTS, parse_inputs

        values: dict[str, Any] = {}
        if kw["config"] is not None:
            values.update(_read_config_file(kw["config"]))
            unknown = sorted(set(values) - {f.name for f in fields})
            if unknown:
                raise _fail(f"--config {kw['config']}: unknown option {unknown[0]!r} for train {name.replace('_', '-')}")
        values.update({f.name: kw[f.name] for f in fields if kw[f.name] is not None})
        dataset = kw["dataset"]
        folder = kw["out"] or Path("runs")
        try:
            if not values.get("skill"):
                raise ConfigError("--skill: required (on the command line or in --config)")
            inputs = values.get("inputs", cls.default_of(next(f for f in fields if f.name == "inputs")))
            names = parse_inputs(inputs if isinstance(inputs, str) else ",".join(inputs), BC_INPUTS)
            if "audio_form" in values and "audio" not in names:
                raise ConfigError("--audio-form: does not apply without audio in --inputs")
            if not kw.get("dagger") and (kw.get("dagger_episodes") is not None or kw.get("dagger_steps") is not None):
                raise ConfigError("--dagger-episodes / --dagger-steps: do not apply without --dagger")
            cfg = cls(**{**values, "dataset": str(dataset), "inputs": names})
            folder = kw["out"] or Path("runs") / f"{name}-{cfg.skill}-{'-'.join(n.rsplit('.', 1)[-1] for n in names)}"
            cfg.check()
            _check(dataset, folder)
            if kw.get("dagger"):
                from echo_data.learn.dagger import run_dagger

                runs.check_out(folder, kw["resume"], kw["overwrite"])
                summary = run_dagger(cfg, folder, kw["dagger"], kw.get("dagger_episodes") or 8, kw.get("dagger_steps"), kw["progress"], resume=kw["resume"])
            else:
                from echo_data.learn.fit import train_skill

                summary = train_skill(cfg, folder, resume=kw["resume"], overwrite=kw["overwrite"], progress=kw["progress"])
        except _errors() + (ConfigError,) as e:
            raise _fail(str(e)) from None
        except OSError as e:
            raise _fail(write_failed("--out", folder, e)) from None
        typer.echo(json.dumps(summary, indent=1))

    command.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
    command.__annotations__ = {p.name: p.annotation for p in params}
    command.__doc__ = f"{algo.summary} Clones one skill from the dataset's step rows; the run folder loads as a policy."
    command.__name__ = f"train_{name}"
    return command


def register_algorithms() -> None:
    """One `echo-data train <algo>` per registered algorithm."""
    from echo_data.learn.algos import ALGORITHMS

    for name in ALGORITHMS:
        train_app.command(name.replace("_", "-"))(_make_train_command(name))


register_algorithms()


@train_app.command("planner")
def planner_cmd(
    ctx: typer.Context,
    dataset: _Dataset,
    inputs: Annotated[str, typer.Option("--inputs", help="Comma list of audio, image (first head RGB frame).")] = "audio",
    audio: Annotated[str, typer.Option("--audio", help="Audio feature: mel (64 bands x 101 frames) or spectrogram (SoundSpaces 65 x 26).")] = "mel",
    train_frames: Annotated[int, typer.Option("--train-frames", min=1, help="Frames 0..N-1 of each training episode are training examples (test: frame 0).")] = 10,
    train_episodes: Annotated[int | None, typer.Option("--train-episodes", min=1, help="Train on a seeded subset of N train episodes (learning curves).")] = None,
    val_by: Annotated[str, typer.Option("--val-by", help="Validation: episodes (held-out train episodes) or sounds (episodes of held-out train sound instances, unheard like the test's).")] = "episodes",
    select: Annotated[str, typer.Option("--select", help="Checkpoint kept: lowest validation loss (loss) or highest validation accuracy of the events in order, single- and multi-event episodes weighing half each (accuracy).")] = "loss",
    augment: Annotated[bool, typer.Option("--augment/--no-augment", help="Augment training audio: pitch shift, gain, SpecAugment masks.")] = False,
    encoder: Annotated[str, typer.Option("--encoder", help="Audio encoder: flat (SoundSpaces' CNN, flattened) or pooled (batch-normed CNN pooled over time).")] = "flat",
    order: Annotated[str, typer.Option("--order", help="Order of the sounding events: learned (priority scores) or priority (the recipe's priority rule from the manifest).")] = "learned",
    mix: Annotated[float, typer.Option("--mix", min=0.0, max=0.99, help="Share of single-event training rows mixed with a single event of the other kind (state + relocation) into a multi-event example; 0 = off.")] = 0.0,
    epochs: _Epochs = None,
    seed: _Seed = 0,
    out: Annotated[Path | None, typer.Option("--out", help="Run folder (default runs/planner-<inputs>).")] = None,
    max_steps: _MaxSteps = None,
    threads: _Threads = 1,
    resume: _Resume = False,
    overwrite: _Overwrite = False,
    progress: _Progress = True,
) -> None:
    """Train the planner on the train split, choosing on validation; prints and saves eval.json. The test split is not read: `echo-data evaluate-planner RUN` scores it."""
    _need_torch()
    from echo_data.learn.algos.base import SEED_LIMIT
    from echo_data.learn.features import PLANNER_INPUTS, parse_inputs
    from echo_data.learn.planner import PlannerConfig, train_planner

    try:
        names = parse_inputs(inputs, PLANNER_INPUTS)
        if not 0 <= seed < SEED_LIMIT:
            raise _fail(f"--seed {seed}: must be within [0, 2**64)")
        _not_applying(ctx, {name: ("audio" in names, "without audio in --inputs") for name in ("audio", "augment", "encoder", "mix")})
        folder = out or Path("runs") / f"planner-{'-'.join(names)}"
        cfg = PlannerConfig(str(dataset), names, seed=seed, audio=audio, max_steps=max_steps, threads=threads, train_frames=train_frames, train_episodes=train_episodes,
                            val_by=val_by, select=select, augment=augment, encoder=encoder, order=order, mix=mix)
        if epochs is not None:
            cfg.epochs = epochs
        _check(dataset, folder)
        report = train_planner(cfg, folder, resume=resume, overwrite=overwrite, progress=progress)
    except _errors() as e:
        raise _fail(str(e)) from None
    except OSError as e:
        raise _fail(write_failed("--out", folder, e)) from None
    typer.echo(json.dumps(report, indent=1))


def evaluate_planner_cmd(
    run: Annotated[Path, typer.Argument(metavar="RUN", help="A finished `echo-data train planner` run folder.")],
    dataset: Annotated[Path | None, typer.Argument(metavar="DATASET", help="The dataset it was trained on (default: the folder its config.json names).")] = None,
) -> None:
    """Score a trained planner on its dataset's test split (unheard sounds), once its options are chosen on validation; prints and saves RUN/test.json."""
    _need_torch()
    from echo_data.learn.planner_score import score_test

    try:
        report = score_test(run, dataset)
    except _errors() as e:
        raise _fail(str(e)) from None
    except OSError as e:
        raise _fail(write_failed("RUN", run, e)) from None
    typer.echo(json.dumps(report, indent=1))
