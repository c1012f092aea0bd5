"""MkDocs hooks (mkdocs.yml `hooks:`): the studies' READMEs become the site's study pages, and the
build refuses a recipes reference that no longer matches the recipe models."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from typing import Any

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, Files

ROOT = Path(__file__).resolve().parents[1]


def on_pre_build(config: Any) -> None:
    """Fail the build when docs/recipe_reference.md is not the rendering of echo_data/recipe.py."""
    spec = importlib.util.spec_from_file_location("gen_recipe_reference", ROOT / "scripts" / "gen_recipe_reference.py")
    assert spec is not None and spec.loader is not None
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    if gen.PAGE.read_text() != gen.render():
        raise PluginError("docs/recipe_reference.md is stale: python scripts/gen_recipe_reference.py")


def study_page(readme: Path) -> str:
    """A study's README as a site page: links into the repository resolve from docs/."""
    text = readme.read_text().replace("](../../docs/", "](../")
    return re.sub(r"\]\(\.\./(\w+)/README\.md\)", r"](\1.md)", text)  # another study's README: its page beside this one


def studies_page(readme: Path) -> str:
    """studies/README.md (the list of studies) as the site's page studies.md."""
    return re.sub(r"\]\((\w+)/README\.md\)", r"](studies/\1.md)", readme.read_text()).replace("](../docs/", "](")


def on_files(files: Files, config: Any) -> Files:
    """Add studies/README.md as the page studies.md and studies/<name>/README.md as studies/<name>.md."""
    files.append(File.generated(config, "studies.md", content=studies_page(ROOT / "studies" / "README.md")))
    for readme in sorted((ROOT / "studies").glob("*/README.md")):
        files.append(File.generated(config, f"studies/{readme.parent.name}.md", content=study_page(readme)))
    return files
