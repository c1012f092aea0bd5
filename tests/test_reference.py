"""Reference learners (echo_data.learn.reference): made from a run folder, loaded by
`--policy reference`, rendered for whatever the recipe stores, named by their weights' SHA-256 in
the results, judged current or stale against the shipped set, reproduced exactly on a second run.

The learner is a tiny one trained here (two optimiser steps on the shared synthetic dataset,
reading the wrist depth camera); the reference set is a temporary folder (`$ECHO_DATA_REFERENCE`).
"""

from __future__ import annotations

import fnmatch
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import tomllib
import yaml
from support.recipes import tiny_recipe
from support.torch_module import torch  # skips the module where the test extra leaves torch out (3.12); fails on 3.11
from typer.testing import CliRunner

from echo_data.cli import app
from echo_data.dataset.schema import IMAGE_COLUMNS
from echo_data.evaluation import provenance, table
from echo_data.learn import reference, runs
from echo_data.learn.reference import ReferenceSet

ROOT = Path(__file__).resolve().parent.parent
runner = CliRunner()


@pytest.fixture(scope="module")
def trained(synth_dataset: Callable[[dict[str, int]], Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A Navigate learner reading the wrist depth camera and the state, two optimiser steps."""
    run = tmp_path_factory.mktemp("ref") / "run"
    args = ["train", "bc", str(synth_dataset({"train": 3, "test": 1})), "--skill", "Navigate", "--inputs", "wrist_depth,state",
            "--image-size", "32", "--max-steps", "2", "--out", str(run), "--no-progress", "--threads", "1"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    return run


@pytest.fixture(scope="module")
def shipped(trained: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A reference set holding that learner, made by the CLI."""
    root = tmp_path_factory.mktemp("refset") / "set"
    res = runner.invoke(app, ["reference", "add", str(trained), "--name", "nav", "--to", str(root)])
    assert res.exit_code == 0, res.output
    return root


@pytest.fixture
def use(shipped: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv(reference.ENV, str(shipped))
    return shipped


def _no_wrist_recipe(folder: Path) -> Path:
    """The tests' tiny quickstart with outputs that do not store the wrist camera, Navigate cut short."""
    r = tiny_recipe()
    r = r.model_copy(update={"outputs": r.outputs.model_copy(update={"observations": ("head_rgb", "head_depth", "spectrogram")}),
                             "robot": r.robot.model_copy(update={"max_steps": {**r.robot.max_steps, "Navigate": 6}})})
    path = folder / "no_wrist.yaml"
    path.write_text(yaml.safe_dump(r.model_dump(mode="json"), sort_keys=False))
    return path


def test_a_reference_learner_holds_its_weights_config_recipe_and_sums(trained: Path, shipped: Path) -> None:
    folder = shipped / "nav"
    assert sorted(p.name for p in folder.iterdir()) == sorted([runs.WEIGHTS, runs.CONFIG, runs.POLICY, runs.AGENT, reference.RECIPE, reference.SUMS])
    refs = ReferenceSet.load(shipped)
    entry = refs.learners["nav"]
    assert refs.skills == {"Navigate": ["nav"]} and refs.planner is None
    assert entry["weights_sha256"] == runs.file_sha256(folder / runs.WEIGHTS)
    config = json.loads((folder / runs.CONFIG).read_text())
    assert config["dataset"] == "synth" and config["inputs"] == ["wrist_depth", "state"]  # no path of this machine
    assert yaml.safe_load((folder / reference.RECIPE).read_text())["name"] == "synth"
    # fp16 where the actions stay within the tolerance, measured on the dataset's steps
    check = entry["fp16_check"]
    assert "dataset steps" in check["on"] and 0 < check["max_relative_difference"] <= reference.FP16_TOLERANCE
    from safetensors.torch import load_file

    stored = load_file(str(folder / runs.WEIGHTS))
    assert {k for k, v in stored.items() if v.dtype == torch.float16} and not set(check["fp32_tensors"]) & {k for k, v in stored.items() if v.dtype == torch.float16}
    # acting from the shipped folder: the run's actions to within the recorded difference
    from echo_data.learn.policy import SkillPolicy

    steps = reference._skill_steps(Path(json.loads((trained / runs.CONFIG).read_text())["dataset"]), "Navigate")
    a, b = SkillPolicy.from_run(trained), SkillPolicy.from_run(folder)
    got = np.abs(np.stack([a.act(o) for _, o in steps]) - np.stack([b.act(o) for _, o in steps])).max()
    assert got == pytest.approx(check["max_action_difference"], abs=1e-7)
    # a changed file is refused by name
    (folder / reference.RECIPE).write_text((folder / reference.RECIPE).read_text() + "# edited\n")
    try:
        with pytest.raises(reference.ReferenceError, match="recipe.yaml: SHA-256"):
            refs.learner("Navigate")
    finally:
        (folder / reference.RECIPE).write_text((folder / reference.RECIPE).read_text().removesuffix("# edited\n"))


def test_fp32_is_kept_where_the_fp16_round_trip_changes_the_actions(trained: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(reference, "FP16_TOLERANCE", 0.0)  # any change of an action is too much
    entry = reference.add(trained, "exact", tmp_path)
    check = entry["fp16_check"]
    assert check["max_action_difference"] == check["max_relative_difference"] == 0.0 and check["fp32_tensors"]
    from safetensors.torch import load_file

    stored = load_file(str(tmp_path / "exact" / runs.WEIGHTS))
    assert all(stored[k].dtype == torch.float32 for k in check["fp32_tensors"])


def test_reference_with_no_shipped_learner_is_one_line_naming_the_skill(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(reference.ENV, str(tmp_path / "empty"))
    for args, what in ((["--policy", "reference"], "no learner for skill Navigate"), (["--planner", "reference"], "no planner")):
        res = runner.invoke(app, ["evaluate", str(ROOT / "recipes" / "quickstart.yaml"), "-n", "1", *args])
        assert res.exit_code == 2 and what in res.output and len(res.output.strip().splitlines()) == 1, res.output


def test_the_package_ships_its_reference_set_within_budget() -> None:
    refs = ReferenceSet.load(reference.PACKAGE_DIR)
    assert reference.shipped_bytes(reference.PACKAGE_DIR) <= reference.BUDGET_BYTES
    assert {p.name for p in reference.PACKAGE_DIR.iterdir() if p.is_dir()} == set(refs.learners)  # nothing shipped unlisted (and unsized)
    for skill in refs.skills:
        assert runs.file_sha256(refs.learner(skill) / runs.WEIGHTS) == refs.weights_sha256(skill)
    if refs.planner:
        assert runs.file_sha256(refs.learner(None) / runs.WEIGHTS) == refs.weights_sha256(None)
    # every file of the set is package data (pyproject's patterns), so an installed package has it
    patterns = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["echo_data"]
    for p in reference.PACKAGE_DIR.rglob("*"):
        if p.is_file():
            rel = p.relative_to(reference.PACKAGE_DIR.parent).as_posix()
            assert any(fnmatch.fnmatch(rel, pat) for pat in patterns), rel


def test_rows_are_current_only_with_the_shipped_weights(shipped: Path) -> None:
    refs = ReferenceSet.load(shipped)
    sha = refs.weights_sha256("Navigate")
    assert sha is not None
    experts = {"skills": dict.fromkeys(refs.skills | {"Pick": None}), "planner": None}
    learned = {"skills": {"Navigate": sha, "Pick": None}, "planner": None}
    other = {"skills": {"Navigate": "0" * 64, "Pick": None}, "planner": None}
    assert provenance.verdict(experts, refs).state == "current"
    assert provenance.verdict(learned, refs).state == "current"
    stale = provenance.verdict(other, refs)
    assert stale.state == "stale" and "Navigate" in stale.why
    assert provenance.verdict({"skills": {}, "planner": "1" * 64}, refs).state == "stale"  # no planner shipped
    assert provenance.verdict(None, refs).state == "unrecorded"
    assert provenance.row_state({"a": {"weights": learned}, "b": {"weights": other}}, refs).state == "stale"
    assert provenance.stale_rows({"new": {"a": {"weights": learned}}, "old": {"a": {"weights": other}}, "before": {"a": {}}}, refs) == {"old"}
    # a learned-planner row composed from two evaluations: the skills of one, the planner of the other
    plans = {"weights": {"skills": dict.fromkeys(learned["skills"]), "planner": "2" * 64}}
    assert provenance.composed_weights(plans, {"weights": learned}) == {"skills": learned["skills"], "planner": "2" * 64}
    assert provenance.composed_weights(plans, {}) is None


def test_the_table_marks_a_row_measured_with_other_weights_stale(shipped: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(reference.ENV, str(shipped))
    sha = ReferenceSet.load(shipped).weights_sha256("Navigate")
    m = {"episodes": 1, "task_planning": {"k": 1, "n": 1, "value": 1.0, "ci95": [0.2, 1.0]},
         "skill_completion": {"k": 0, "n": 1, "value": 0.0, "ci95": [0.0, 0.8]}, "progressive": []}
    row = "oracle planner + learned skills"
    settings = ("object_relocation", "state_transition")
    rows: dict[str, table.Row] = {row: table.EvaluatedRow(name=row, planner="oracle", policy={"Navigate": "nav"}, settings=settings)}

    def md(nav: str) -> str:
        doc = {"rows": {row: {s: {"metrics": m, "weights": {"skills": {"Navigate": nav}, "planner": None}} for s in settings}}}
        return table.markdown(doc, rows, settings)

    assert f"| {row} §" in md("0" * 64) and "§ stale" in md("0" * 64)
    assert f"| {row} §" not in md(str(sha)) and "§ stale" not in md(str(sha))


def test_evaluate_reference_renders_the_wrist_camera_the_recipe_does_not_store_and_names_the_weights(use: Path, tmp_path: Path) -> None:
    recipe = _no_wrist_recipe(tmp_path)
    out = tmp_path / "e.json"
    res = runner.invoke(app, ["evaluate", str(recipe), "-n", "1", "--policy", "Navigate=reference", "--policy", "oracle", "--json", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    sha = ReferenceSet.load(use).weights_sha256("Navigate")
    assert doc["weights"]["skills"]["Navigate"] == sha and doc["weights"]["skills"]["Pick"] is None and doc["weights"]["planner"] is None
    assert doc["policy"]["skills"]["Navigate"]["reference"] == "nav" and "checkpoint" not in doc["policy"]["skills"]["Navigate"]
    ep = doc["episodes"][0]
    assert not ep["failure"].startswith("agent error") and ep["skills"][0]["skill"] == "Navigate" and ep["skills"][0]["steps"] > 1, ep
    assert provenance.verdict(doc["weights"], ReferenceSet.load(use)).state == "current"


def test_a_reference_learners_first_episode_reproduces_exactly(use: Path, tmp_path: Path) -> None:
    from echo_data.agents.builtin import OraclePlanner
    from echo_data.agents.loading import load_policy
    from echo_data.agents.runtime import run_episode
    from echo_data.envs.env import EchoDataEnv
    from echo_data.evaluation.rendered import rendering
    from echo_data.evaluation.run import episode_record
    from echo_data.recipe import Recipe

    recipe = yaml.safe_load(_no_wrist_recipe(tmp_path).read_text())

    def once() -> tuple[dict, list[np.ndarray]]:
        policy = load_policy(("Navigate=reference", "oracle"))  # loaded afresh, as a second evaluation would
        env = EchoDataEnv(rendering(Recipe(**recipe), policy), split="test", audio=False)
        try:
            assert IMAGE_COLUMNS["wrist_depth"] in env.observation_space.spaces
            actions: list[np.ndarray] = []
            obs, info = env.reset(options={"spec": env.sample_spec("test", 0)})
            run = run_episode(env, obs, info, OraclePlanner(), policy, skills=1,
                              on_step=lambda e, o, a, *_: actions.append(np.array(a, dtype=np.float32)))
            return episode_record(run, 0), actions
        finally:
            env.close()

    first, second = once(), once()
    assert first[0] == second[0] and first[0]["skills"][0]["steps"] > 1
    assert len(first[1]) == len(second[1]) and all(np.array_equal(a, b) for a, b in zip(first[1], second[1]))


def test_a_planner_ships_and_plans_as_its_run(synth_dataset: Callable[[dict[str, int]], Path], tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    from echo_data.agents.loading import identity, load_planner
    from echo_data.dataset.torch import StepDataset
    from echo_data.learn.policy import PlannerModel

    ds = synth_dataset({"train": 3, "test": 1})
    run = tmp_path / "planner"
    res = runner.invoke(app, ["train", "planner", str(ds), "--inputs", "audio", "--epochs", "1", "--out", str(run), "--threads", "1", "--no-progress"])
    assert res.exit_code == 0, res.output
    root = tmp_path / "set"
    res = runner.invoke(app, ["reference", "add", str(run), "--name", "planner", "--to", str(root)])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["fp16_check"]["max_relative_difference"] <= reference.FP16_TOLERANCE
    res = runner.invoke(app, ["reference", "add", str(run), "--name", "planner", "--to", str(root)])
    assert res.exit_code == 2 and "--overwrite" in res.output  # a learner is replaced only when asked
    monkeypatch.setenv(reference.ENV, str(root))
    planner = load_planner("reference")
    assert isinstance(planner, PlannerModel) and planner.weights_sha256 == ReferenceSet.load(root).weights_sha256(None)
    assert identity(planner, "reference")["reference"] == "planner"
    first = {k: v for k, v in StepDataset(ds, "test")[0].items() if k.startswith("observation.")}
    assert planner.plan(first) == PlannerModel.from_run(run).plan(first)


def test_a_variant_ships_beside_the_serving_learner_and_is_asked_for_by_name(trained: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from echo_data.agents.loading import AgentLoadError, folder_sha256, identity, load_policy

    root = tmp_path / "set"
    reference.add(trained, "nav", root)
    monkeypatch.setattr(reference, "FP16_TOLERANCE", 0.0)  # other weights than the serving learner's
    variant = reference.add(trained, "nav-exact", root, serve=False)
    refs = ReferenceSet.load(root)
    assert refs.skills == {"Navigate": ["nav"]} and refs.of("Navigate") == ["nav", "nav-exact"]
    assert refs.shipped("Navigate") == {refs.weights_sha256("Navigate"), variant["weights_sha256"]} and len(refs.shipped("Navigate")) == 2
    monkeypatch.setenv(reference.ENV, str(root))
    policy = load_policy(("Navigate=reference:nav-exact", "oracle"))
    who = identity(policy, ("Navigate=reference:nav-exact", "oracle"))["skills"]["Navigate"]
    assert who["reference"] == "nav-exact" and who["weights_sha256"] == variant["weights_sha256"]
    # the shipped folder by content, as a run folder's (what --adopt compares), and no path of this machine
    assert who["checkpoint_sha256"] == folder_sha256(root / "nav-exact") and str(tmp_path) not in str(who)
    assert provenance.verdict({"skills": {"Navigate": variant["weights_sha256"]}, "planner": None}, refs).state == "current"
    # an evaluation over two training seeds (evaluation.seeds): the members' hashes, member by member
    served = identity(load_policy(("Navigate=reference", "oracle")), ("Navigate=reference", "oracle"))
    both = provenance.weights({"name": "two seeds", "members": [served, {"skills": {"Navigate": who, "*": {"name": "oracle"}}}]}, {"name": "oracle"})
    assert both["skills"]["Navigate"] == [refs.weights_sha256("Navigate"), variant["weights_sha256"]] and both["skills"]["Pick"] is None
    assert provenance.verdict(both, refs).state == "current"
    both["skills"]["Navigate"][1] = "3" * 64
    assert provenance.verdict(both, refs).state == "stale"
    with pytest.raises(reference.ReferenceError, match="a plain folder name"):
        reference.add(trained, "nav:b", root)
    for spec, says in (("Pick=reference:nav-exact", "not a learner for skill Pick"), ("Navigate=reference:nope", "no learner 'nope'"),
                       ("reference:nav-exact", "give SKILL=reference:nav-exact")):
        with pytest.raises(AgentLoadError, match=says):
            load_policy((spec, "oracle") if "=" in spec else spec)


def test_a_skill_served_by_several_seeds_is_evaluated_over_them(trained: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`reference add --join`: another training seed serves the skill beside the first, and
    `--policy reference` shares the episodes out over the seeds the set ships (evaluation.seeds)."""
    from echo_data.evaluation.seeds import SeedSpecError, shipped_seeds, split_members

    root = tmp_path / "set"
    reference.add(trained, "nav-s0", root)
    monkeypatch.setattr(reference, "FP16_TOLERANCE", 0.0)  # other weights: the second seed's stand-in is the fp32 copy
    res = runner.invoke(app, ["reference", "add", str(trained), "--name", "nav-s1", "--to", str(root), "--join"])
    assert res.exit_code == 0, res.output
    refs = ReferenceSet.load(root)
    assert refs.skills == {"Navigate": ["nav-s0", "nav-s1"]} and refs.weights_sha256("Navigate") == refs.learners["nav-s0"]["weights_sha256"]
    res = runner.invoke(app, ["reference", "list", "--to", str(root)])
    assert res.exit_code == 0 and "nav-s0+nav-s1" in res.output, res.output
    monkeypatch.setenv(reference.ENV, str(root))
    assert shipped_seeds(("Navigate=reference", "oracle")) == ["oracle", "Navigate=reference:nav-s0+reference:nav-s1"]
    assert shipped_seeds("oracle") == "oracle" and shipped_seeds(("Navigate=runs/a", "oracle")) == ("Navigate=runs/a", "oracle")
    fallback = split_members("reference")
    assert len(fallback) == 2 and all("reference" in m for m in fallback)
    assert [m for m in fallback[1] if m.startswith("Navigate=")] == ["Navigate=reference:nav-s1"]
    with pytest.raises(SeedSpecError, match="lists 3 runs"):  # the shipped seeds line up with a user's list or say why not
        split_members(("Navigate=reference", "Pick=a+b+c"))
    res = runner.invoke(app, ["reference", "add", str(trained), "--name", "nav-v", "--to", str(root), "--variant", "--join"])
    assert res.exit_code == 2 and "--join" in res.output and not (root / "nav-v").exists()
    before = (root / reference.MANIFEST).read_bytes()
    doc = json.loads(before)
    doc["learners"]["nav-s1"]["algo"] = "act"
    (root / reference.MANIFEST).write_text(json.dumps(doc))
    with pytest.raises(reference.ReferenceError, match="one command"):  # a seed of another command does not join
        reference.add(trained, "nav-s2", root, join=True)
    assert not (root / "nav-s2").exists()
