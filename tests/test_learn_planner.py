"""The planner's multi-event parts without a dataset: the priority-rule order, the mix of two
single events, the time-pooled audio encoder and the error tally."""

from __future__ import annotations

import numpy as np
from support.torch_module import torch  # skips the module where the test extra leaves torch out (3.12)

CATS = ["alarm", "doorbell", "furby", "phone", "sink"]
PRIORITY = ["sink", "doorbell", "alarm", "phone", "furby"]


def test_priority_order_follows_the_recipe_rule_not_the_scores() -> None:
    from echo_data.learn.planner import decode

    logits = np.array([-5.0, -5.0, -5.0, 2.0, 1.0])  # phone and sink sound
    scores = np.array([0.0, 0.0, 0.0, 3.0, -3.0])  # the learned scores put phone first
    assert decode(logits, scores, CATS) == ["phone", "sink"]
    assert decode(logits, scores, CATS, priority=PRIORITY) == ["sink", "phone"]
    assert decode(logits, scores, CATS, [["phone"], ["phone", "sink"]], PRIORITY) == ["sink", "phone"]


def test_mix_adds_powers_and_unites_labels_in_priority_order() -> None:
    """Two equal sources heard at once are 10 log10(2) = 3.01 dB louder than one (incoherent
    sum of intensities); a source 20 dB below another raises it by 10 log10(1.01) = 0.043 dB."""
    from echo_data.learn.planner import mix_examples

    std = torch.tensor([10.0, 20.0]).view(1, 2, 1, 1)
    mean = torch.tensor([-60.0, -50.0]).view(1, 2, 1, 1)
    db_a = torch.full((2, 2, 4, 5), -40.0)
    db_b = torch.stack([torch.full((2, 4, 5), -40.0), torch.full((2, 4, 5), -60.0)])
    ya, yb = torch.zeros(2, 5), torch.zeros(2, 5)
    ya[:, CATS.index("phone")] = 1.0
    yb[0, CATS.index("sink")] = 1.0
    yb[1, CATS.index("doorbell")] = 1.0
    rank = {CATS.index(c): k for k, c in enumerate(PRIORITY)}
    mixed, y, pairs = mix_examples((db_a - mean) / std, (db_b - mean) / std, ya, yb, std, mean, rank)
    heard = mixed * std + mean
    assert torch.allclose(heard[0], torch.full_like(heard[0], -40.0 + 10 * np.log10(2)), atol=1e-4)
    assert torch.allclose(heard[1], torch.full_like(heard[1], -40.0 + 10 * np.log10(1.01)), atol=1e-4)
    assert y[0].tolist() == [0, 0, 0, 1, 1] and y[1].tolist() == [0, 1, 0, 1, 0]
    assert pairs.tolist() == [[CATS.index("sink"), CATS.index("phone")], [CATS.index("doorbell"), CATS.index("phone")]]


def test_pooled_encoder_hears_a_pattern_wherever_it_sounds_flat_does_not() -> None:
    """A tone burst moved by 16 frames (a multiple of the encoder's total stride, 8) in silence
    gives the pooled code unchanged; the flattened SoundSpaces code changes."""
    from echo_data.learn.models import AudioEncoder, PooledAudioEncoder

    torch.manual_seed(0)
    early, late = torch.zeros(1, 2, 64, 101), torch.zeros(1, 2, 64, 101)
    burst = torch.randn(2, 12, 10)
    early[0, :, 20:32, 24:34] = burst
    late[0, :, 20:32, 40:50] = burst
    pooled, flat = PooledAudioEncoder(64, 101).eval(), AudioEncoder(64, 101).eval()
    with torch.no_grad():
        assert torch.allclose(pooled(early), pooled(late), atol=1e-5)
        assert not torch.allclose(flat(early), flat(late), atol=1e-3)
        swapped = early.flip(1)  # the ears stay apart
        assert not torch.equal(pooled(early), pooled(swapped))


def test_errors_tell_order_missed_extra_and_swapped() -> None:
    from echo_data.learn.planner import errors

    said = [["sink", "phone"], ["phone", "sink"], ["sink"], ["sink", "alarm"], ["doorbell"]]
    true = [["sink", "phone"], ["sink", "phone"], ["sink", "phone"], ["sink"], ["sink"]]
    e = errors(said, true)
    assert e["wrong"] == 4 and e["of"] == 5
    assert e["kinds"] == {"extra": 1, "missed": 1, "order": 1, "swapped": 1}
    assert e["pairs"]["sink+phone -> sink"] == 1 and sum(e["pairs"].values()) == 4


def test_planner_options_are_generated_from_its_config() -> None:
    """`train planner` offers one option per `opt` field of PlannerConfig (as the skill learners
    do from theirs), with the config's default in the help: a new field is an option at once."""
    import typer

    from echo_data.cli import app
    from echo_data.learn.planner_config import PlannerConfig

    command = typer.main.get_command(app).commands["train"].commands["planner"]  # type: ignore[attr-defined]
    helps = {p.name: p for p in command.params}
    names = [f.name for f in PlannerConfig.options()]
    assert len(names) >= 14 and "batch_size" not in names  # internal constants stay out of the CLI
    for f in PlannerConfig.options():
        assert f.name in helps and f.metadata["help"] in helps[f.name].help, f.name
    assert "(default 60)" in helps["epochs"].help and "(default episodes)" in helps["val_by"].help
    assert "--no-augment" in helps["augment"].secondary_opts and helps["mix"].max == 0.99
