"""`echo-data train`: behaviour cloning per skill and the audio planner (needs the torch extra)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

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
    """Before any training: the run folder can be written and the dataset's files are whole."""
    from echo_data.dataset.validate import check_whole
    from echo_data.targets import check_folder

    check_folder(folder, "--out")
    if (dataset / "manifest.json").is_file():  # no dataset at all: training's own message says so
        check_whole(dataset)


def _need_torch() -> None:
    try:
        import torch  # noqa: F401
    except ImportError:
        raise _fail("training needs PyTorch: pip install 'echo-data[torch]'") from None


@train_app.command("bc")
def bc_cmd(
    ctx: typer.Context,
    dataset: _Dataset,
    skill: Annotated[str, typer.Option("--skill", help="Skill whose step rows are cloned (Navigate, Pick, Place, OpenDoor, CloseSink).")],
    inputs: Annotated[str, typer.Option("--inputs", help="Comma list of audio, depth (head), wrist_depth, rgb (head), state (velocities left out), state_raw (all 25), target (the goal position: the paper's * rows), kind (the chain's target kind, one-hot).")] = "audio,depth,state",
    epochs: _Epochs = None,
    seed: _Seed = 0,
    out: Annotated[Path | None, typer.Option("--out", help="Run folder (default runs/bc-<skill>-<inputs>).")] = None,
    chunk: Annotated[int, typer.Option("--chunk", min=1, help="Actions predicted per step (action chunking).")] = 1,
    execute: Annotated[int, typer.Option("--execute", min=1, help="Predicted actions executed before predicting again.")] = 1,
    audio_form: Annotated[str, typer.Option("--audio-form", help="How audio is fed: level_ild (each ear in dB plus their difference) or stored (the dataset's spectrogram, normalised).")] = "level_ild",
    batch_size: Annotated[int, typer.Option("--batch-size", min=1)] = 64,
    lr: Annotated[float, typer.Option("--lr", min=0.0)] = 1e-3,
    max_steps: _MaxSteps = None,
    threads: _Threads = 1,
    gru: Annotated[bool, typer.Option("--gru/--no-gru", help="A GRU over the steps of a skill (BC-RNN), trained on whole segments; its state resets at each skill's start.")] = False,
    seq_batch: Annotated[int, typer.Option("--seq-batch", min=1, help="With --gru: segments per optimiser step.")] = 4,
    shift: Annotated[int, typer.Option("--shift", min=0, help="Random-shift augmentation of training images: up to N pixels (0 = off).")] = 0,
    action_form: Annotated[str, typer.Option("--action-form", help="What the network predicts: absolute (the dataset's joint targets) or delta (torso and arm targets as the change from the measured joints; needs state).")] = "absolute",
    resume: _Resume = False,
    overwrite: _Overwrite = False,
    progress: _Progress = True,
    dagger: Annotated[int, typer.Option("--dagger", min=0, help="DAgger rounds after BC (Navigate only): roll the learner on train episodes, label with the expert, retrain. With --resume: start from the BC run in --out.")] = 0,
    dagger_episodes: Annotated[int, typer.Option("--dagger-episodes", min=1, help="Train episodes rolled per DAgger round.")] = 8,
    dagger_steps: Annotated[int | None, typer.Option("--dagger-steps", min=1, help="Learner steps per rollout (default: the Navigate budget).")] = None,
) -> None:
    """Behaviour-clone one skill from the dataset's step rows; the run folder loads as a policy."""
    _need_torch()
    from echo_data.learn import runs
    from echo_data.learn.bc import BCConfig, train_bc
    from echo_data.learn.features import BC_INPUTS, parse_inputs

    try:
        names = parse_inputs(inputs, BC_INPUTS)
        _not_applying(ctx, {"audio_form": ("audio" in names, "without audio in --inputs"),
                            "dagger_episodes": (dagger > 0, "without --dagger"), "dagger_steps": (dagger > 0, "without --dagger")})
        folder = out or Path("runs") / f"bc-{skill}-{'-'.join(names)}"
        cfg = BCConfig(str(dataset), skill, names, seed=seed, chunk=chunk, execute=execute, batch_size=batch_size, lr=lr, max_steps=max_steps, threads=threads,
                       audio_form=audio_form, recurrent=gru, seq_batch=seq_batch, shift=shift, action_form=action_form)
        if epochs is not None:
            cfg.epochs = epochs
        _check(dataset, folder)
        if dagger:
            from echo_data.learn.dagger import run_dagger

            runs.check_out(folder, resume, overwrite)
            summary = run_dagger(cfg, folder, dagger, dagger_episodes, dagger_steps, progress, resume=resume)
        else:
            summary = train_bc(cfg, folder, resume=resume, overwrite=overwrite, progress=progress)
    except _errors() as e:
        raise _fail(str(e)) from None
    except OSError as e:
        raise _fail(write_failed("--out", folder, e)) from None
    typer.echo(json.dumps(summary, indent=1))


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
    epochs: _Epochs = None,
    seed: _Seed = 0,
    out: Annotated[Path | None, typer.Option("--out", help="Run folder (default runs/planner-<inputs>).")] = None,
    max_steps: _MaxSteps = None,
    threads: _Threads = 1,
    resume: _Resume = False,
    overwrite: _Overwrite = False,
    progress: _Progress = True,
) -> None:
    """Train the planner on the train split, score it on the test split (unheard sounds); prints and saves eval.json."""
    _need_torch()
    from echo_data.learn.features import PLANNER_INPUTS, parse_inputs
    from echo_data.learn.planner import PlannerConfig, train_planner

    try:
        names = parse_inputs(inputs, PLANNER_INPUTS)
        _not_applying(ctx, {"audio": ("audio" in names, "without audio in --inputs"), "augment": ("audio" in names, "without audio in --inputs")})
        folder = out or Path("runs") / f"planner-{'-'.join(names)}"
        cfg = PlannerConfig(str(dataset), names, seed=seed, audio=audio, max_steps=max_steps, threads=threads, train_frames=train_frames, train_episodes=train_episodes,
                            val_by=val_by, select=select, augment=augment)
        if epochs is not None:
            cfg.epochs = epochs
        _check(dataset, folder)
        report = train_planner(cfg, folder, resume=resume, overwrite=overwrite, progress=progress)
    except _errors() as e:
        raise _fail(str(e)) from None
    except OSError as e:
        raise _fail(write_failed("--out", folder, e)) from None
    typer.echo(json.dumps(report, indent=1))
