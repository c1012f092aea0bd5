"""Derived random streams are salted in one module: salts are distinct, and no other module
seeds a generator with a salt literal of its own."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from echo_data import seeds

PACKAGE = Path(seeds.__file__).parent
SALTED = re.compile(r"(default_rng|SeedSequence)\(\s*(np\.random\.SeedSequence\()?\[[^\]]*0x[0-9A-Fa-f]+")


def test_salts_are_distinct() -> None:
    salts = {k: v for k, v in vars(seeds).items() if k.isupper() and isinstance(v, int)}
    assert len(salts) >= 8 and len(set(salts.values())) == len(salts)


def test_streams_of_different_purposes_differ_and_repeat() -> None:
    a = seeds.derived_rng(seeds.LIGHTING, 7).random(4)
    assert np.array_equal(a, seeds.derived_rng(seeds.LIGHTING, 7).random(4))
    assert not np.array_equal(a, seeds.derived_rng(seeds.FURNISHINGS, 7).random(4))


def test_no_salt_literals_outside_the_seeds_module() -> None:
    assert SALTED.search("np.random.default_rng([seed, 0x50F7])")  # the pattern sees what it forbids
    bad = [str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py") if p.name != "seeds.py" and SALTED.search(p.read_text())]
    assert not bad
