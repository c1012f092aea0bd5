"""The paper table's computed rows (benchmarks/paper_table.py): a learned-planner row composed
from the planner's run with the experts and the oracle-planner run with the learned skills, and a
skill-alone row read from a chain row."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _paper_table() -> Any:
    sys.path.insert(0, str(ROOT / "benchmarks"))  # it imports its sibling `ablation`
    spec = importlib.util.spec_from_file_location("paper_table", ROOT / "benchmarks" / "paper_table.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


CHAIN = [{"skill": "Navigate", "target": "phone"}, {"skill": "Pick", "target": "phone"}]


def _record(i: int, plan_right: bool, done: int) -> dict[str, Any]:
    """An episode record as `echo-data evaluate` writes it: `done` skills of the 2-skill chain succeeded."""
    skills = [{"skill": c["skill"], "target": c["target"], "success": k < done, "reason": "" if k < done else "timeout", "steps": 5}
              for k, c in enumerate(CHAIN[: done + 1 if done < 2 else 2])] if plan_right else []
    return {"index": i, "episode_id": f"test-{i}", "setting": "object_relocation", "seed": i, "true_chain": CHAIN,
            "planned_chain": CHAIN if plan_right else CHAIN[:1], "plan_correct": plan_right, "skills": skills,
            "skills_completed": done if plan_right else 0, "success": plan_right and done == 2, "steps": 10 * done + 1,
            "navigate": [{"skill_index": 0, "success": done >= 1, "path_length": 1.0, "expert_length": 1.0, "spl": float(done >= 1)}] if plan_right else [],
            "failure": "" if plan_right and done == 2 else "plan wrong" if not plan_right else "Pick(phone): timeout"}


def test_a_learned_planner_row_keeps_the_skills_outcome_only_where_the_plan_is_right() -> None:
    pt = _paper_table()
    plans = {"episodes": [_record(0, True, 2), _record(1, False, 0), _record(2, True, 2), _record(3, False, 0)]}
    skills = {"episodes": [_record(0, True, 2), _record(1, True, 2), _record(2, True, 1), _record(3, True, 0)]}
    row = pt.composed(plans, skills, "test")
    m = row["metrics"]
    assert (m["task_planning"]["k"], m["task_planning"]["n"]) == (2, 4)
    assert (m["skill_completion"]["k"], m["skill_completion"]["n"]) == (1, 4)  # episode 1 succeeded with the true plan, not with this one
    assert [p["k"] for p in m["progressive"]] == [2, 1]
    assert row["skills"]["Navigate"] == pt.skill_success([_record(0, True, 2), _record(2, True, 1)], "Navigate")


def test_a_composed_row_refuses_different_episodes() -> None:
    pt = _paper_table()
    other = dict(_record(1, True, 2), episode_id="test-99")
    with pytest.raises(SystemExit, match="same episodes"):
        pt.composed({"episodes": [_record(0, True, 2), _record(1, True, 2)]}, {"episodes": [_record(0, True, 2), other]}, "test")


def test_a_derived_skill_alone_row_counts_the_skills_attempts() -> None:
    pt = _paper_table()
    row = pt.derived({"episodes": [_record(0, True, 2), _record(1, True, 0), _record(2, True, 1)]}, "Navigate", "test")
    assert (row["skills"]["Navigate"]["k"], row["skills"]["Navigate"]["n"]) == (2, 3)


def test_the_handover_is_the_experts_path_minus_the_driven_one_over_successful_first_navigates() -> None:
    pt = _paper_table()
    eps = [_record(i, True, 2) for i in range(3)] + [_record(3, True, 0)]  # the last Navigate failed: not counted
    for e, driven in zip(eps, (0.5, 0.8, 1.0, 0.1), strict=True):
        e["navigate"][0]["path_length"] = driven
    h = pt.handover(eps)
    assert h is not None and h["n"] == 3 and h["quartiles_m"][1] == 0.2  # 1.0 - 0.8
