"""Write docs/recipe_reference.md from the recipe models (echo_data/recipe.py): every key, its
type, default, allowed range and the comment the model gives it. Generated so it cannot drift
from the code: the docs build (scripts/docs_hooks.py) and tests/test_docs.py refuse a committed
page that differs from this rendering.

Usage: python scripts/gen_recipe_reference.py [--check]
"""

from __future__ import annotations

import argparse
import inspect
import re
import sys
import typing
from pathlib import Path
from typing import Any

from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "recipe_reference.md"
FIELD = re.compile(r"^    (\w+)\s*:")
COMMENT = re.compile(r"^\s*#\s?(.*)$")


def comments(model: type[BaseModel]) -> dict[str, str]:
    """Each field's comment in the model's source: the `#` lines just above it and its trailing one."""
    out: dict[str, str] = {}
    above: list[str] = []
    for line in inspect.getsource(model).splitlines()[1:]:
        if m := COMMENT.match(line):
            above.append(m.group(1).strip())
            continue
        if (f := FIELD.match(line)) and f.group(1) in model.model_fields:
            trailing = line.split("  # ", 1)[1].strip() if "  # " in line else ""
            out[f.group(1)] = " ".join([*above, trailing]).strip()
        above = []
    return out


def type_name(annotation: Any) -> str:
    """A field's type as a reader writes it in YAML terms."""
    text = str(annotation) if typing.get_origin(annotation) else getattr(annotation, "__name__", str(annotation))
    return re.sub(r"\b(typing|echo_data\.recipe)\.", "", text).replace("NoneType", "None")


def default(field: FieldInfo) -> str:
    """The default as YAML would spell it (`required` when there is none)."""
    if field.default_factory is not None:
        value = field.default_factory()  # type: ignore[call-arg]
    elif field.default is PydanticUndefined:
        return "required"
    else:
        value = field.default
    if isinstance(value, BaseModel):
        return "see below"
    return f"`{value!r}`".replace("'", '"') if value is not None else "`null`"


def limits(field: FieldInfo) -> str:
    """The range and pattern constraints the model enforces."""
    words = []
    for m in field.metadata:
        for attr, sign in (("ge", "≥"), ("gt", ">"), ("le", "≤"), ("lt", "<"), ("max_length", "length ≤"), ("pattern", "matches")):
            if getattr(m, attr, None) is not None:
                words.append(f"{sign} `{getattr(m, attr)}`")
    return ", ".join(words)


def nested(annotation: Any) -> type[BaseModel] | None:
    return annotation if isinstance(annotation, type) and issubclass(annotation, BaseModel) else None


def section(key: str, model: type[BaseModel], out: list[str]) -> None:
    """The table of `model` under heading `key`, then its nested models' tables."""
    notes = comments(model)
    out += [f"## `{key}`", "", inspect.cleandoc(model.__dict__.get("__doc__") or ""), "", "| key | type | default | allowed | notes |", "|---|---|---|---|---|"]
    subs = []
    for name, field in model.model_fields.items():
        sub = nested(field.annotation)
        if sub is not None:
            subs.append((f"{key}.{name}" if key != "recipe" else name, sub))
        kind = f"[`{subs[-1][0]}`](#{subs[-1][0].replace('.', '')})" if sub is not None else f"`{type_name(field.annotation)}`".replace("|", "\\|")
        note = notes.get(name, "").replace("|", "\\|")
        out.append(f"| `{name}` | {kind} | {default(field)} | {limits(field)} | {note} |")
    out.append("")
    for sub_key, sub in subs:
        section(sub_key, sub, out)


def render() -> str:
    """The whole page."""
    from echo_data.recipe import Recipe

    out = ["# Recipes reference", "",
           "Generated from the recipe models in `echo_data/recipe.py` by `scripts/gen_recipe_reference.py`; "
           "do not edit by hand. A recipe is YAML; `extends: FILE` merges it over another (paths relative to the "
           "recipe). `recipes/base.yaml` lists every key with its default, and [Recipes](recipes.md) shows the "
           "shipped ones. Unknown keys, wrong types and out-of-range values are one-line errors naming the key.", ""]
    section("recipe", Recipe, out)
    return "\n".join(out).rstrip() + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="exit 1 when the committed page differs from the models")
    a = ap.parse_args()
    page = render()
    if a.check:
        if not PAGE.is_file() or PAGE.read_text() != page:
            sys.exit(f"{PAGE.relative_to(ROOT)} is stale: python scripts/gen_recipe_reference.py")
        return
    PAGE.write_text(page)


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    main()
