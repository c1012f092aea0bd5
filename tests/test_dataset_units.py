"""Small pieces: mergeable statistics, the schema against `datasets`' own, shard planning."""

from __future__ import annotations

import math

import numpy as np
from support.synth import synth_recipe

from echo_data.dataset import stats
from echo_data.dataset.manifest import plan_shards
from echo_data.dataset.schema import StepLayout, array3d_column, column_to_numpy


def test_merged_stats_equal_direct_computation() -> None:
    rng = np.random.default_rng(0)
    parts = [rng.normal(loc=i, scale=1 + i, size=(50 + 30 * i, 3)) for i in range(4)]
    merged = stats.finalize(stats.merge([stats.summarize(p, len(p)) for p in parts]))
    allv = np.concatenate(parts)
    np.testing.assert_allclose(merged["mean"], allv.mean(0), rtol=1e-10)
    np.testing.assert_allclose(merged["std"], allv.std(0), rtol=1e-10)
    np.testing.assert_array_equal(merged["min"], allv.min(0))
    np.testing.assert_array_equal(merged["max"], allv.max(0))
    assert merged["count"] == [len(allv)]
    q50 = np.quantile(allv, 0.5, axis=0)
    spread = allv.std(0)
    assert np.all(np.abs(np.asarray(merged["q50"]) - q50) < 0.1 * spread)
    assert np.all(np.asarray(merged["q01"]) < np.asarray(merged["q50"])) and np.all(np.asarray(merged["q50"]) < merged["q99"])


def test_schema_matches_datasets_features() -> None:
    import datasets  # the test extra installs it: a missing one fails, never skips
    layout = StepLayout.from_recipe(synth_recipe())
    theirs = datasets.Features.from_dict(layout.hf_features()).arrow_schema
    ours = layout.schema()
    assert ours.names == theirs.names
    for a, b in zip(ours, theirs):
        ta = a.type.storage_type if hasattr(a.type, "storage_type") else a.type
        tb = b.type.storage_type if hasattr(b.type, "storage_type") else b.type
        assert ta.equals(tb), a.name
        if hasattr(b.type, "extension_name"):
            assert a.type.extension_name == b.type.extension_name
            assert a.type.__arrow_ext_serialize__() == b.type.__arrow_ext_serialize__()


def test_array3d_round_trip() -> None:
    x = np.arange(2 * 65 * 26 * 2, dtype=np.float32).reshape(2, 65, 26, 2)
    col = array3d_column(x)
    np.testing.assert_array_equal(column_to_numpy(col, (65, 26, 2)), x)
    np.testing.assert_array_equal(column_to_numpy(col.slice(1, 1), (65, 26, 2)), x[1:])


def test_shard_plan_is_fixed_by_split_and_index() -> None:
    r = synth_recipe(splits={"test": 7, "train": 33})
    plans = plan_shards(r, None)
    assert list(plans) == ["train", "test"]
    assert len(plans["train"]) == math.ceil(33 / 2) and plans["train"][-1].file == "data/train-00016-of-00017.parquet"
    assert [list(p.indices) for p in plans["test"]][-1] == [6]
    assert [len(p) for p in plan_shards(r, 3).values()] == [2, 2]
    assert list(plan_shards(synth_recipe(splits={"train": 0, "test": 2}), None)["train"]) == []
