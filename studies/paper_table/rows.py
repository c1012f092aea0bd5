"""The paper's main table (its Fig. 4a) on echo-data: which rows exist, the learners and training
data each needs, where each row is scored, and the README's copy of the rendering. The
machinery (row kinds, reading entries, composing, summarising, rendering) is the package's
`echo_data.evaluation.table`; this catalogue is the study's, beside its driver (paper_table.py).

Rows:
- oracle planner + scripted experts (the upper bound the data allows);
- oracle planner + learned skills, the drives without the target position (the paper's
  "Oracle") and with it ("*", the paper's "Oracle*"): the paper gives it to Navigate; here Place
  gets it too, because our Place drives the held object to its receptacle (named only by its
  kind otherwise), which is a navigation of its own;
- learned planner + scripted experts, measured; + learned skills, composed from that row and the
  oracle-planner row (`table.composed` says why that is the closed-loop result);
- each skill alone: its learner drives that skill, the scripted experts the others;
- the paper-comparable rows: the same with Habitat's grasp (`robot.grasp: magic`, which the
  paper's skills use) instead of our physical one; starred, the target position given.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from echo_data.evaluation import table
from echo_data.evaluation.table import ComposedRow, DatasetSpec, DerivedRow, EvaluatedRow, Grasp, LearnerSpec, PlannerSpec
from echo_data.learn import defaults

SKILLS = table.SKILLS  # the skill table's, in its order
SETTINGS = ("object_relocation", "state_transition", "multi_event")
PAPER_ORDER = ("state_transition", "object_relocation", "multi_event")  # the paper's column order
PAPER_COMPARABLE = " (paper-comparable)"
STOP_CHAIN = "oracle planner + learned skills, Navigate says STOP"
STOP_NEAR_CHAIN = STOP_CHAIN + ", OpenDoor from near starts"
CENTRE_CHAIN = f"oracle planner + learned skills*{PAPER_COMPARABLE}, 3 seeds, drive to the stance's centre"
# The rendered copies in documents, each between two markers: the whole table in this study's
# README, the headline (the paper's layout and the skills alone) in the repository's README.
TABLE_BEGIN = "<!-- paper table: rendered from studies/paper_table/results/paper_table.json by studies/paper_table/rows.py"
TABLE_END = "<!-- end of the paper table -->"
HEADLINE_BEGIN = "<!-- headline results: rendered from studies/paper_table/results/paper_table.json by studies/paper_table/rows.py"
HEADLINE_END = "<!-- end of the headline results -->"


def recipe(row: EvaluatedRow, setting: str) -> str:
    """The evaluation recipe of `row` on `setting` (a file in this study's recipes/): every test
    episode in one setting (or one event, or after a hand-over), so `-n N` scores N episodes of
    it; `_magic` the same with `robot.grasp: magic`."""
    return f"cameras_test_{setting}{'_magic' if row.grasp == 'magic' else ''}.yaml"


# Training data: dataset (its folder under --data-root) -> recipe (a path from the repository
# root). The learners clone the closed-loop experts' end-effector actions (`action.ee`) from
# demonstrations under the shipped perturbation whose manipulation starts anywhere in Navigate's
# success region (studies/paper_table/recipes/sanity.yaml says what they share): Pick and Place from
# studies/paper_table/recipes/cameras_pick_place.yaml (150 object-relocation episodes), OpenDoor and CloseSink from
# studies/paper_table/recipes/cameras_door_sink.yaml (300 state-transition episodes), both with head and wrist depth;
# Navigate from studies/paper_table/recipes/nav_audio.yaml (600 episodes, no camera: it hears its way).
# The planner learns from studies/planner/recipes/planner_fresh.yaml (episodes cut after 10 frames, a fresh
# synthesised voice per training event; built whole: once trained (choosing on validation), the
# planner is scored on that build's own test split by `echo-data evaluate-planner RUN`). The
# magic-grasp build (studies/paper_table/recipes/cameras_pick_place_magic.yaml: the same 150 episodes with
# `robot.grasp: magic`) is the paper-comparable rows' Pick and Place data, and
# studies/paper_table/recipes/cameras_door_sink_magic.yaml (the door-and-sink episodes with it) their OpenDoor's.
DATASETS: dict[str, DatasetSpec] = {
    "cameras_pick_place": DatasetSpec("studies/paper_table/recipes/cameras_pick_place.yaml"),
    "cameras_door_sink": DatasetSpec("studies/paper_table/recipes/cameras_door_sink.yaml"),
    "nav_audio": DatasetSpec("studies/paper_table/recipes/nav_audio.yaml"),
    "planner_fresh": DatasetSpec("studies/planner/recipes/planner_fresh.yaml", None),
    "cameras_pick_place_magic": DatasetSpec("studies/paper_table/recipes/cameras_pick_place_magic.yaml"),
    "nav_audio_stop": DatasetSpec("studies/paper_table/recipes/nav_audio_stop.yaml"),
    "cameras_door_near": DatasetSpec("studies/paper_table/recipes/cameras_door_near.yaml"),
    "cameras_door_sink_magic": DatasetSpec("studies/paper_table/recipes/cameras_door_sink_magic.yaml"),
}
# The planner run: audio only, the checkpoint of the best balanced validation accuracy of 20
# epochs (chosen on validation among the planner_fresh runs: studies/planner/results/planner_fresh.json).
PLANNER = PlannerSpec("planner_fresh", ("--inputs", "audio", "--select", "accuracy", "--epochs", "20"))
# Skill learners, each chosen on validation by its study. Manipulation: ACT (chunk 20, temporal
# ensembling) over head and wrist depth, proprioception and the target kind, random shift 4, the
# checkpoint of the best closed-loop validation success at epochs 10 and 20
# (studies/learners/camera_learners.py; its ablations: studies/learners/results/camera_ablations.json).
# Navigate: a GRU over the skill's steps reading the binaural level and ILD (no camera), chosen
# every 5 epochs on validation (studies/learners/navigate_from_sound.py); the chain hands over at the
# first step Navigate's success test holds. Every learner gets the target
# kind its chain entry names; the starred ones also the target position (the paper's Oracle*).
STUDY = "studies/paper_table"  # this study's folder, from the repository root (where the driver runs `echo-data`)
# The values are the per-skill defaults of `echo-data train` (their owner, echo_data/learn/defaults.py),
# passed explicitly in the order the committed runs were trained with (tests/test_train_defaults.py
# checks every committed training command of studies/paper_table/results/paper_table.json against these).
_M, _N = defaults.MANIPULATION, defaults.NAVIGATE
MANIPULATION = ("--action-column", defaults.STUDY_ACTION_COLUMN, "--device", "auto", "--epochs", str(_M.epochs), "--select-every", str(_M.select_every),
                "--shift", str(_M.shift), "--select-episodes", str(_M.select_episodes), "--seed", "0")
MANIPULATION_INPUTS = ",".join(_M.inputs)
NAVIGATE = ("--audio-form", "level_ild", "--action-column", defaults.STUDY_ACTION_COLUMN, "--epochs", str(_N.epochs), "--select-every", str(_N.select_every),
            "--select-episodes", str(_N.select_episodes), "--device", "auto", "--seed", "0")
NAVIGATE_INPUTS = ",".join(_N.inputs)
LEARNERS: dict[str, LearnerSpec] = {
    "Navigate": LearnerSpec("nav_audio", "Navigate", NAVIGATE_INPUTS, "bc-rnn", NAVIGATE),
    "Navigate-target": LearnerSpec("nav_audio", "Navigate", NAVIGATE_INPUTS + ",target", "bc-rnn", NAVIGATE),
    **{s: LearnerSpec("cameras_pick_place", s, MANIPULATION_INPUTS, "act", MANIPULATION) for s in ("Pick", "Place")},
    "Place-target": LearnerSpec("cameras_pick_place", "Place", MANIPULATION_INPUTS + ",target", "act", MANIPULATION),
    **{s: LearnerSpec("cameras_door_sink", s, MANIPULATION_INPUTS, "act", MANIPULATION) for s in ("OpenDoor", "CloseSink")},
    # Paper-comparable: Pick and Place cloned from demonstrations with the magic grasp (the grasp
    # changes what Pick and Place do; the drives and the door and sink skills are the same).
    "Pick-magic": LearnerSpec("cameras_pick_place_magic", "Pick", MANIPULATION_INPUTS, "act", MANIPULATION),
    "Place-magic": LearnerSpec("cameras_pick_place_magic", "Place", MANIPULATION_INPUTS, "act", MANIPULATION),
    "Place-target-magic": LearnerSpec("cameras_pick_place_magic", "Place", MANIPULATION_INPUTS + ",target", "act", MANIPULATION),
    # ... and OpenDoor with the magic grasp on the door's handle bar (echo_data/world.py), from the
    # door episodes of cameras_door_sink.yaml built with it (the paper's OpenDoor grasps that way);
    # its checkpoint chosen on the val split of the condition its row scores (alone, the exact pose).
    "OpenDoor-magic": LearnerSpec("cameras_door_sink_magic", "OpenDoor", MANIPULATION_INPUTS, "act",
                                  (*MANIPULATION, "--select-recipe", f"{STUDY}/recipes/cameras_test_door_magic.yaml")),
    # The hand-over study: Navigate's options plus a STOP output (`--stop`), cloned from the same
    # episodes with the expert's Navigate ending at the interaction pose (nav_audio_stop.yaml), so
    # the learner ends its own skill there instead of being cut at the rim of its success region.
    "Navigate-stop": LearnerSpec("nav_audio_stop", "Navigate", NAVIGATE_INPUTS, "bc-rnn", (*NAVIGATE, "--stop")),
    # The stance study (docs/learners.md, "OpenDoor stands where it is"): cloned from door
    # episodes whose expert grasps from where Navigate stopped when it can, hand-overs within 0.3
    # of the success region (cameras_door_near.yaml); the table's OpenDoor options with a
    # spatial-softmax encoder (keypoints: where the bar is), chosen on 20 validation episodes over
    # the strided CNN at 64 px (5/20) and at 128 px (8/20, tied: the smaller input kept).
    "OpenDoor-near": LearnerSpec("cameras_door_near", "OpenDoor", MANIPULATION_INPUTS, "act", (*MANIPULATION, "--encoder", "spatial_softmax")),
    # CloseSink over three training seeds (issue 45: one training is not a figure), its checkpoint
    # chosen on the val split of the recipe its row scores on (alone); runs CloseSink-3seeds,
    # CloseSink-3seeds-s1, CloseSink-3seeds-s2 (`table.run_name`).
    "CloseSink-3seeds": LearnerSpec("cameras_door_sink", "CloseSink", MANIPULATION_INPUTS, "act",
                                    (*MANIPULATION, "--select-recipe", f"{STUDY}/recipes/cameras_test_sink.yaml"), seeds=(0, 1, 2)),
    # ... and the Oracle* row's other learners over three seeds: Navigate* and OpenDoor-magic, the
    # options of their one-seed runs (runs <name>, <name>-s1, <name>-s2).
    "Navigate-target-3seeds": LearnerSpec("nav_audio", "Navigate", NAVIGATE_INPUTS + ",target", "bc-rnn", NAVIGATE, seeds=(0, 1, 2)),
    "OpenDoor-magic-3seeds": LearnerSpec("cameras_door_sink_magic", "OpenDoor", MANIPULATION_INPUTS, "act",
                                         (*MANIPULATION, "--select-recipe", f"{STUDY}/recipes/cameras_test_door_magic.yaml"), seeds=(0, 1, 2)),
}
# Each learner chooses its checkpoint on the val split of its own training recipe (the manipulation
# ones: experts.handover_noise 1.0, cameras_door_near 0.3), not of the condition its row measures
# (alone: 0; after a hand-over: 1.0). One chosen on its row's condition adds
# `--select-recipe studies/paper_table/recipes/cameras_test_<setting>[_handover].yaml` to its options
# (that file's val split, never its test split; docs/learners.md), as a LearnerSpec of its own so
# the table's committed learners and results stay as they were trained.
# Where each manipulation skill is scored alone: recipes/cameras_test_<setting>.yaml, 50 test
# episodes of its own event, the skills before it done by the experts with Navigate stopping at
# the exact interaction pose; "after a hand-over", the same episodes with the oracle Navigate
# stopping anywhere in its success region (`experts.handover_noise` 1.0), as a learned Navigate
# hands over. Navigate alone is read from the chain rows (`_rows`).
ALONE_SETTINGS = {"Navigate": ("object_relocation", "state_transition"), "Pick": ("pick_place",), "Place": ("pick_place",),
                  "OpenDoor": ("door",), "CloseSink": ("sink",)}


def _rows() -> dict[str, table.Row]:
    """The catalogue in the paper's order: oracle-planner rows, then learned-planner rows, each
    ours (physical grasp) before the paper-comparable ones; then the skills alone."""
    learned = {s: s for s in SKILLS}
    starred = {**learned, "Navigate": "Navigate-target", "Place": "Place-target"}  # the drives are given their target
    magic = {**learned, "Pick": "Pick-magic", "Place": "Place-magic", "OpenDoor": "OpenDoor-magic"}
    # The paper's Oracle* row: CloseSink by its three training seeds (the single-seed run of the rows
    # above is the committed one they were measured with).
    magic_starred = {**starred, "Pick": "Pick-magic", "Place": "Place-target-magic", "OpenDoor": "OpenDoor-magic", "CloseSink": "CloseSink-3seeds"}
    experts = "oracle planner + scripted experts"
    chain: list[table.Row] = [EvaluatedRow(name=experts, planner="oracle", settings=SETTINGS)]
    pc = PAPER_COMPARABLE
    grasps: tuple[Grasp, Grasp] = ("physical", "magic")
    variants: list[tuple[dict[str, str], str, Grasp]] = [(learned, "", "physical"), (starred, "*", "physical"), (magic, "", "magic"), (magic_starred, "*", "magic")]
    for policy, star, grasp in variants:
        suffix = star + (pc if grasp == "magic" else "")
        chain.append(EvaluatedRow(name=f"oracle planner + learned skills{suffix}", planner="oracle", policy=policy, settings=SETTINGS, grasp=grasp))
    for grasp in grasps:
        tail = pc if grasp == "magic" else ""
        chain.append(EvaluatedRow(name=f"learned planner + scripted experts{tail}", planner="learned", settings=SETTINGS, grasp=grasp))
        for star in ("", "*"):
            chain.append(ComposedRow(name=f"learned planner + learned skills{star}{tail}", plans=f"learned planner + scripted experts{tail}",
                                     outcomes=f"oracle planner + learned skills{star}{tail}", settings=SETTINGS, grasp=grasp))
    alone: list[table.Row] = []
    for s in SKILLS:
        alone.append(EvaluatedRow(name=f"{s} alone", planner="oracle", policy={s: s}, settings=ALONE_SETTINGS[s], skill=s))
    for s in ("Pick", "Place", "OpenDoor", "CloseSink"):  # where the chain hands them over
        alone.append(EvaluatedRow(name=f"{s} after a hand-over", planner="oracle", policy={s: s}, settings=tuple(f"{x}_handover" for x in ALONE_SETTINGS[s]),
                                  skill=s))
    # CloseSink alone over three training seeds, the 50 test episodes dealt out over them (`evaluation.seeds`).
    alone.append(EvaluatedRow(name="CloseSink alone (3 seeds)", planner="oracle", policy={"CloseSink": "CloseSink-3seeds"},
                              settings=ALONE_SETTINGS["CloseSink"], skill="CloseSink"))
    alone.append(EvaluatedRow(name="CloseSink after a hand-over (3 seeds)", planner="oracle", policy={"CloseSink": "CloseSink-3seeds"},
                              settings=tuple(f"{x}_handover" for x in ALONE_SETTINGS["CloseSink"]), skill="CloseSink"))
    alone.append(EvaluatedRow(name="Place* alone", planner="oracle", policy={"Place": "Place-target"}, settings=ALONE_SETTINGS["Place"], skill="Place"))
    for s, learner in (("Pick", "Pick-magic"), ("Place", "Place-magic"), ("OpenDoor", "OpenDoor-magic")):
        alone.append(EvaluatedRow(name=f"{s} alone{pc}", planner="oracle", policy={s: learner}, settings=ALONE_SETTINGS[s], skill=s, grasp="magic"))
    alone.append(EvaluatedRow(name=f"Place* alone{pc}", planner="oracle", policy={"Place": "Place-target-magic"}, settings=ALONE_SETTINGS["Place"],
                              skill="Place", grasp="magic"))
    # The hand-over study (docs/learners.md, "A Navigate that says STOP"): Navigate-stop alone (the
    # experts after it), and the state-transition chain after it; object relocation and multi-event
    # would add Pick and Place to the row's policy.
    stop = {"Navigate": "Navigate-stop"}
    chain.append(EvaluatedRow(name=STOP_CHAIN, planner="oracle", policy={**stop, "OpenDoor": "OpenDoor", "CloseSink": "CloseSink"},
                              settings=("state_transition",)))
    # ... and with the OpenDoor cloned from near hand-overs (the stance study): a STOP that hands
    # over near the interaction pose is what that learner was trained for.
    chain.append(EvaluatedRow(name=STOP_NEAR_CHAIN, planner="oracle", policy={**stop, "OpenDoor": "OpenDoor-near", "CloseSink": "CloseSink"},
                              settings=("state_transition",)))
    # The Oracle* row with every learner over three seeds and the drive ended in the stance's centre
    # (`evaluate --drive-end centre`): ended the first step inside the stance, Navigate* hands over
    # on its rim (the hand-over study, handover_spread.json).
    chain.append(EvaluatedRow(name=CENTRE_CHAIN, planner="oracle", settings=("state_transition",), grasp="magic", drive_end="centre",
                              policy={**magic_starred, "Navigate": "Navigate-target-3seeds", "OpenDoor": "OpenDoor-magic-3seeds"}))
    alone.append(EvaluatedRow(name="Navigate (STOP) alone", planner="oracle", policy=stop, settings=ALONE_SETTINGS["Navigate"], skill="Navigate"))
    for name, settings in (("OpenDoor (near starts) alone", ALONE_SETTINGS["OpenDoor"]), ("OpenDoor (near starts) after a hand-over", ("door_handover",))):
        alone.append(EvaluatedRow(name=name, planner="oracle", policy={"OpenDoor": "OpenDoor-near"}, settings=settings, skill="OpenDoor"))
    out = {r.name: r for r in [*chain, *alone]}
    # Navigate is the first skill of every single-event chain, so its outcome alone (experts after
    # it) is its outcome in the oracle-planner chain row, step for step (an episode is a pure
    # function of recipe, split, index and policies; `derived`'s docstring).
    for star in ("", "*"):
        name = f"Navigate{star} alone"
        out[name] = DerivedRow(name=name, source=f"oracle planner + learned skills{star}", skill="Navigate", settings=ALONE_SETTINGS["Navigate"])
    return out


ROWS: dict[str, table.Row] = _rows()


def needs_learned_planner(row: table.Row) -> bool:
    """Whether `row` (or a row it is computed from) runs the learned planner."""
    return table.needs_learned_planner(row, ROWS)


def summary(doc: dict[str, Any]) -> dict[str, Any]:
    """The results document's `summary` block over this catalogue (`table.summary`)."""
    return table.summary(doc, ROWS)


def markdown(doc: dict[str, Any]) -> str:
    """The table's markdown, the paper's column order (`table.markdown`)."""
    return table.markdown(doc, ROWS, PAPER_ORDER)


def headline(doc: dict[str, Any]) -> str:
    """The README's part of the table: the paper's layout (planning and completion per row and
    setting) and the skills alone, with the notes; the progressive success and the planning
    without the receptacle stay in the study's README."""
    blocks = markdown(doc).split("\n\n")
    return "\n\n".join(b for b in blocks if not b.startswith(("| row | setting |",)))


def copies(root: Path) -> list[tuple[Path, str, str, Callable[[dict[str, Any]], str]]]:
    """Every rendered copy of the table: (document, begin marker, end marker, renderer)."""
    return [(root / "studies" / "paper_table" / "README.md", TABLE_BEGIN, TABLE_END, markdown),
            (root / "README.md", HEADLINE_BEGIN, HEADLINE_END, headline)]


def rendered_copy(text: str, begin: str, end: str) -> str:
    """The copy a document holds between its two markers."""
    return table.block(text, begin, end)


def with_rendered_copy(text: str, begin: str, end: str, rendered: str) -> str:
    """`text` with the copy between its markers replaced by `rendered`."""
    return table.with_block(text, begin, end, rendered)
