"""The ids of the built-in sound instances ("phone-train-03": category, split, number) and of
fresh training instances ("phone-fresh-3fa2b1c94d07"): how they are written and read back. The
synthesiser (`sounds.synth`) turns an id into its sound; split from it so the naming has one owner.
"""

from __future__ import annotations

from echo_data.categories import CATEGORY_COUNTS


def builtin_ids() -> list[str]:
    """All built-in ids in a stable order: category (as in CATEGORY_COUNTS), train then test, index."""
    out = []
    for cat, (n_train, n_test) in CATEGORY_COUNTS.items():
        out += [f"{cat}-train-{i:02d}" for i in range(1, n_train + 1)]
        out += [f"{cat}-test-{i:02d}" for i in range(1, n_test + 1)]
    return out


# Every structural choice of a design is a function of the variant index modulo a cycle that
# divides 240 (styles: k mod 3, 4 or 5; sub-styles, patterns, intervals, timbres: (k // styles) mod
# 2, 3, 4 or 5), so variants drawn uniformly modulo 240 sample every structure equally often.
VARIANT_CYCLE = 240
FRESH = "fresh"
FRESH_DIGITS = 12  # 48 bits of the seed: ids stay short, collisions among a build's draws negligible


def fresh_id(category: str, seed: int) -> str:
    """The id of the fresh training instance of `category` drawn from `seed` (an episode-derived seed)."""
    if category not in CATEGORY_COUNTS:
        raise KeyError(f"unknown sound category {category!r}")
    return f"{category}-{FRESH}-{seed % 16**FRESH_DIGITS:0{FRESH_DIGITS}x}"


def is_fresh_id(instance_id: str) -> bool:
    parts = instance_id.split("-")
    return len(parts) == 3 and parts[0] in CATEGORY_COUNTS and parts[1] == FRESH and len(parts[2]) == FRESH_DIGITS and all(
        c in "0123456789abcdef" for c in parts[2]
    )


def parse_builtin_id(instance_id: str) -> tuple[str, str, int]:
    """(category, split, variant) of a built-in or fresh id; variant counts train then test within the
    category (a fresh id is a train instance whose variant is its number modulo VARIANT_CYCLE)."""
    if is_fresh_id(instance_id):
        cat, _, num = instance_id.split("-")
        return cat, "train", int(num, 16) % VARIANT_CYCLE
    try:
        cat, split, num = instance_id.split("-")
        i = int(num)
        n_train, n_test = CATEGORY_COUNTS[cat]
    except (ValueError, KeyError):
        raise KeyError(f"not a built-in sound id: {instance_id!r}") from None
    if split == "train" and 1 <= i <= n_train:
        return cat, split, i - 1
    if split == "test" and 1 <= i <= n_test:
        return cat, split, n_train + i - 1
    raise KeyError(f"not a built-in sound id: {instance_id!r}")
