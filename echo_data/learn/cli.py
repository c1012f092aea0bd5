"""`echo-data train`: one command per skill-learning algorithm (its options generated from the
algorithm's config) and the audio planner (needs the torch extra)."""

from __future__ import annotations

import dataclasses
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


def _fail(message: str) -> typer.Exit:
    typer.echo(f"error: {message}", err=True)
    return typer.Exit(2)


def _as_command(command: Any, params: list[inspect.Parameter], name: str, doc: str) -> Any:
    """`command` as typer reads a command: the generated options as its signature, its name and help."""
    command.__signature__ = inspect.Signature(params)
    command.__annotations__ = {p.name: p.annotation for p in params}
    command.__doc__ = doc
    command.__name__ = name
    return command


def _errors() -> tuple[type[Exception], ...]:
    from echo_data.dataset.manifest import ManifestError
    from echo_data.dataset.validate import DamagedDataset
    from echo_data.learn.features import FeatureError
    from echo_data.learn.runs import RunError
    from echo_data.targets import TargetError

    return (FeatureError, RunError, TargetError, ManifestError, DamagedDataset)


def _check(dataset: Path, folder: Path) -> None:
    """Before any training: the run folder can be written, lies apart from the dataset, and the
    dataset's files are whole."""
    from echo_data.dataset.reader import is_dataset
    from echo_data.dataset.validate import check_whole
    from echo_data.dataset.written import apart_problem
    from echo_data.learn.runs import RunError
    from echo_data.targets import check_folder

    check_folder(folder, "--out")
    if is_dataset(dataset):  # no dataset at all: training's own message says so
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


def _flag(name: str, hint: Any) -> str:
    """A field's option name: "--train-frames"; a switch both ways: "--augment/--no-augment"."""
    flag = name.replace("_", "-")
    return f"--{flag}/--no-{flag}" if _option_type(hint) is bool else f"--{flag}"


def _dataset_argument() -> inspect.Parameter:
    return inspect.Parameter("dataset", inspect.Parameter.POSITIONAL_OR_KEYWORD, annotation=Path,
                             default=typer.Argument(..., metavar="DATASET", help="Dataset folder (out/<name>)."))


def _run_folder_options(default_out: str) -> list[inspect.Parameter]:
    """--out, --resume, --overwrite, --progress: every learner's run-folder options."""
    kw = inspect.Parameter.KEYWORD_ONLY
    return [
        inspect.Parameter("out", kw, annotation=Path | None, default=typer.Option(None, "--out", help=f"Run folder (default {default_out}).")),
        inspect.Parameter("resume", kw, annotation=bool, default=typer.Option(False, "--resume", help="Continue the run in --out from its last checkpoint.")),
        inspect.Parameter("overwrite", kw, annotation=bool, default=typer.Option(False, "--overwrite", help="Replace the run in --out.")),
        inspect.Parameter("progress", kw, annotation=bool, default=typer.Option(True, "--progress/--no-progress", help="Show progress bars.")),
    ]


def _field_default(f: Any) -> Any:
    return f.default_factory() if f.default is dataclasses.MISSING else f.default


def _field_options(cls: type, fields: list[Any], per_skill: tuple[str, ...] = ()) -> list[inspect.Parameter]:
    """One keyword option per config field (its `opt` help, bounds and default; `per_skill`: the
    fields whose default is the skill's, `learn/defaults.py`): the options of every `echo-data
    train` learner are generated here from its config class. Each defaults to None on the command
    line, so a value the user gave is told apart from the config's default."""
    hints = typing.get_type_hints(cls)
    params = []
    for f in fields:
        default = _field_default(f)
        shown = "per skill, above" if f.name in per_skill else ",".join(default) if isinstance(default, tuple) else default
        help_text = f.metadata["help"] + (" (required)" if f.metadata.get("required") else f" (default {shown})")
        bounds = {k: f.metadata[k] for k in ("min", "max") if k in f.metadata}
        params.append(inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, annotation=_option_type(hints[f.name]) | None,
                                        default=typer.Option(None, _flag(f.name, hints[f.name]), help=help_text, show_default=False, **bounds)))
    return params


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
    from echo_data.learn.defaults import RESOLVED, help_line

    algo = algorithm(name)
    cls = algo.config
    fields = cls.options()
    params = [_dataset_argument()]
    params += _field_options(cls, fields, RESOLVED)
    params += [
        inspect.Parameter("config", inspect.Parameter.KEYWORD_ONLY, annotation=Path | None,
                          default=typer.Option(None, "--config", help="JSON or YAML file of option values (the command line wins).")),
        *_run_folder_options(f"runs/{name}-<skill>-<inputs>"),
    ]
    params += [
        inspect.Parameter("dagger", inspect.Parameter.KEYWORD_ONLY, annotation=int, default=typer.Option(
            0, "--dagger", min=0, help="DAgger rounds after training: roll the learner on train episodes (from where the experts hand its skill over), label every state with the expert, retrain with each rollout as a segment. With --resume: start from the run in --out.")),
        inspect.Parameter("dagger_episodes", inspect.Parameter.KEYWORD_ONLY, annotation=int | None, default=typer.Option(
            None, "--dagger-episodes", min=1, help="Train episodes rolled per DAgger round (default 8).")),
        inspect.Parameter("dagger_steps", inspect.Parameter.KEYWORD_ONLY, annotation=int | None, default=typer.Option(
            None, "--dagger-steps", min=1, help="Learner steps per rollout (default: the skill's budget).")),
        inspect.Parameter("dagger_chunk", inspect.Parameter.KEYWORD_ONLY, annotation=str | None, default=typer.Option(
            None, "--dagger-chunk", help="How DAgger rows teach a chunking learner: path (each row's chunk: the labels of the states the learner went on to visit; default), first (the row's own label alone) or takeover (the expert takes over each rollout at a random step; only its own rows from there on).")),
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
            values = {**_skill_defaults(values, dataset, kw["out"] if kw["resume"] else None), **values}
            inputs = values.get("inputs", cls.default_of(next(f for f in fields if f.name == "inputs")))
            names = parse_inputs(inputs if isinstance(inputs, str) else ",".join(inputs), BC_INPUTS)
            if "audio_form" in values and "audio" not in names:
                raise ConfigError("--audio-form: does not apply without audio in --inputs")
            if not kw.get("dagger") and any(kw.get(k) is not None for k in ("dagger_episodes", "dagger_steps", "dagger_chunk")):
                raise ConfigError("--dagger-episodes / --dagger-steps / --dagger-chunk: do not apply without --dagger")
            cfg = cls(**{**values, "dataset": str(dataset), "inputs": names})
            folder = kw["out"] or Path("runs") / f"{name}-{cfg.skill}-{'-'.join(n.rsplit('.', 1)[-1] for n in names)}"
            cfg.check()
            _check(dataset, folder)
            if kw.get("dagger"):
                from echo_data.learn.dagger import run_dagger

                runs.check_out(folder, kw["resume"], kw["overwrite"])
                summary = run_dagger(cfg, folder, kw["dagger"], kw.get("dagger_episodes") or 8, kw.get("dagger_steps"), kw["progress"], resume=kw["resume"],
                                     chunk=kw.get("dagger_chunk") or "path")
            else:
                from echo_data.learn.fit import train_skill

                summary = train_skill(cfg, folder, resume=kw["resume"], overwrite=kw["overwrite"], progress=kw["progress"])
        except _errors() + (ConfigError,) as e:
            raise _fail(str(e)) from None
        except OSError as e:
            raise _fail(write_failed("--out", folder, e)) from None
        typer.echo(json.dumps(summary, indent=1))

    return _as_command(command, params, f"train_{name}", f"{algo.summary} Clones one skill from the dataset's step rows; the run folder loads as a policy.\n\n{help_line()}")


def _skill_defaults(given: dict[str, Any], dataset: Path, resumed: Path | None) -> dict[str, Any]:
    """The per-skill defaults of the options `given` lacks (`learn.defaults.resolve`; its notes on
    stderr); resuming the run in `resumed`, that run's own values instead (a run trained before the
    per-skill defaults continues as it started)."""
    from echo_data.learn import runs
    from echo_data.learn.defaults import RESOLVED, resolve

    if resumed is not None and (resumed / runs.CONFIG).is_file():
        saved = runs.read_json(resumed / runs.CONFIG)
        return {k: saved[k] for k in RESOLVED if k not in given and k in saved}
    fill, notes = resolve(str(given["skill"]), given, dataset)
    for note in notes:
        typer.echo(f"note: {note}", err=True)
    return fill


def register_algorithms() -> None:
    """One `echo-data train <algo>` per registered algorithm."""
    from echo_data.learn.algos import ALGORITHMS

    for name in ALGORITHMS:
        train_app.command(name.replace("_", "-"))(_make_train_command(name))


register_algorithms()


def _make_planner_command() -> Callable[..., None]:
    """`echo-data train planner`: one option per `opt` field of `PlannerConfig` (like the skill
    learners'), plus the run-folder options."""
    from echo_data.learn.planner_config import PlannerConfig

    fields = PlannerConfig.options()
    params = [_dataset_argument()]
    params += _field_options(PlannerConfig, fields)
    params += _run_folder_options("runs/planner-<inputs>")

    def command(**kw: Any) -> None:
        _need_torch()
        from echo_data.learn.algos.base import SEED_LIMIT
        from echo_data.learn.features import PLANNER_INPUTS, parse_inputs
        from echo_data.learn.planner import train_planner

        values = {f.name: kw[f.name] for f in fields if kw[f.name] is not None}
        dataset = kw["dataset"]
        folder = kw["out"] or Path("runs")
        try:
            inputs = values.pop("inputs", ",".join(_field_default(next(f for f in fields if f.name == "inputs"))))
            names = parse_inputs(inputs, PLANNER_INPUTS)
            seed = values.get("seed", 0)
            if not 0 <= seed < SEED_LIMIT:
                raise _fail(f"--seed {seed}: must be within [0, 2**64)")
            for f in fields:  # an audio option given without audio would be stored as if it had mattered
                if f.metadata.get("needs_audio") and f.name in values and "audio" not in names:
                    raise _fail(f"--{f.name.replace('_', '-')}: does not apply without audio in --inputs")
            folder = kw["out"] or Path("runs") / f"planner-{'-'.join(names)}"
            cfg = PlannerConfig(str(dataset), names, **values)
            _check(dataset, folder)
            report = train_planner(cfg, folder, resume=kw["resume"], overwrite=kw["overwrite"], progress=kw["progress"])
        except _errors() as e:
            raise _fail(str(e)) from None
        except OSError as e:
            raise _fail(write_failed("--out", folder, e)) from None
        typer.echo(json.dumps(report, indent=1))

    return _as_command(command, params, "train_planner", ("Train the planner on the train split, choosing on validation; prints and saves eval.json. "
                       "The test split is not read: `echo-data evaluate-planner RUN` scores it."))


train_app.command("planner")(_make_planner_command())


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
