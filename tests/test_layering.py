"""The import graph holds the layering docs/ARCHITECTURE.md draws: the format library
(`echo_data.dataset`) imports nothing from the layers above it, and only the commands reach into
the application package (`echo_data.app`). Read from the source (lazy imports inside functions
included), so a violation fails here before it shows up as an import cycle."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "echo_data"
# What the format library may build on: its own modules and the layers below it.
DATASET_MAY_IMPORT = ("dataset", "skill_table", "recipe", "records", "episode", "target", "seeds", "protocols", "pcm", "camera", "categories", "media", "acoustics")
# Who may use the application package: the command line, the app itself, and the commands
# that run episodes through its worker pool or its pipeline.
APP_USERS = ("cli", "app", "evaluation", "preview")


def module_name(path: Path) -> str:
    return ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts).removesuffix(".__init__")


def imported_modules(source: str, module: str, is_package: bool = False) -> set[str]:
    """Every `echo_data` module that `source` (the text of `module`) imports, anywhere in it."""
    package = module if is_package else module.rsplit(".", 1)[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            found.update(f"{base}.{a.name}" if base == "echo_data" else base for a in node.names)
    return {m for m in found if m == "echo_data" or m.startswith("echo_data.")}


def imports_of(path: Path) -> set[str]:
    return imported_modules(path.read_text(), module_name(path), path.name == "__init__.py")


def _layer(module: str) -> str:
    return module.split(".")[1] if "." in module else ""


def test_imported_modules_reads_lazy_and_relative_imports() -> None:
    src = "from .schema import STATE\nfrom echo_data import app\ndef f():\n    import echo_data.envs.env\n"
    got = imported_modules(src, "echo_data.dataset.probe")
    assert got == {"echo_data.dataset.schema", "echo_data.app", "echo_data.envs.env"}


@pytest.mark.parametrize("path", sorted((PACKAGE / "dataset").rglob("*.py")), ids=lambda p: p.name)
def test_dataset_imports_nothing_above_it(path: Path) -> None:
    bad = sorted(m for m in imports_of(path) if _layer(m) not in DATASET_MAY_IMPORT)
    assert not bad, f"{path.name} imports {bad}: the format library must not depend on the layers above it"


def test_only_commands_use_the_app_package() -> None:
    bad = {
        str(p.relative_to(PACKAGE)): sorted(m for m in imports_of(p) if _layer(m) == "app")
        for p in PACKAGE.rglob("*.py")
        if _layer(module_name(p)) not in APP_USERS
    }
    assert not {k: v for k, v in bad.items() if v}
