"""The import graph holds the layering docs/ARCHITECTURE.md draws: the format library
(`echo_data.dataset`) imports nothing from the layers above it, only the commands reach into
the application package (`echo_data.app`), at most `MAX_UPWARD` imports go from a lower layer to
a higher one, and no module imports itself through others (no circles). Read from the source
(lazy imports inside functions included; imports under `if TYPE_CHECKING:` are annotations,
not dependencies, and are left out), so a violation fails here before it shows up as an import
cycle."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "echo_data"
# What the format library may build on: its own modules and the layers below it.
DATASET_MAY_IMPORT = ("dataset", "skill_table", "recipe", "recipe_sections", "recipe_yaml", "records", "episode", "floorplan", "target", "seeds", "protocols", "pcm", "camera", "categories", "media", "acoustics")
# Who may use the application package: the command line, the app itself, and the commands
# that run episodes through its worker pool or its pipeline.
APP_USERS = ("cli", "app", "evaluation", "preview")


def module_name(path: Path) -> str:
    return ".".join(path.relative_to(PACKAGE.parent).with_suffix("").parts).removesuffix(".__init__")


def imported_modules(source: str, module: str, is_package: bool = False, runtime: bool = False) -> set[str]:
    """Every `echo_data` module that `source` (the text of `module`) imports, anywhere in it
    (`runtime`: but under `if TYPE_CHECKING:`). `from pkg import mod` names `pkg.mod` when that
    is a module, else `pkg` (a name defined in the package)."""
    package = module if is_package else module.rsplit(".", 1)[0]
    tree = ast.parse(source)
    found: set[str] = set()
    for node in _runtime_nodes(tree) if runtime else ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            found.update(f"{base}.{a.name}" if _exists(f"{base}.{a.name}") else base for a in node.names)
    return {m for m in found if (m == "echo_data" or m.startswith("echo_data.")) and m != module}


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


# The layers of docs/ARCHITECTURE.md, bottom first: a module belongs to the first entry naming
# its longest dotted prefix below `echo_data` (so `learn.cli` is a command, `learn.fit` application).
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("vocabulary", ("", "recipe", "records", "episode", "floorplan", "target", "targets", "seeds", "protocols", "outputs", "pcm",
                    "media", "camera", "categories", "skill_table", "recipe_sections", "recipe_yaml")),
    ("simulation", ("world", "robot", "scene", "acoustics", "sounds")),
    ("format", ("dataset",)),
    ("skills", ("skills",)),
    ("environment", ("envs",)),
    ("agents", ("agents",)),
    ("pictures", ("viz",)),
    ("application", ("app", "evaluation", "learn")),
    ("commands", ("cli", "doctor", "preview", "view", "app.commands", "sounds.cli", "learn.cli", "evaluation.cli")),
)
# Upward imports the structure tolerates (issue 46: at most three).
MAX_UPWARD = 3


def layer_index(module: str) -> int:
    """The height of `module`'s layer in LAYERS (0 the vocabulary)."""
    parts = module.split(".")[1:]
    for n in range(len(parts), -1, -1):
        prefix = ".".join(parts[:n])
        for height, (_, names) in enumerate(LAYERS):
            if prefix in names:
                return height
    raise AssertionError(f"{module}: in no layer of LAYERS (add it where docs/ARCHITECTURE.md draws it)")


def _runtime_nodes(tree: ast.AST) -> list[ast.AST]:
    """Every node of `tree` but those under `if TYPE_CHECKING:`."""
    out: list[ast.AST] = []
    todo = [tree]
    while todo:
        node = todo.pop()
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            todo.extend(node.orelse)
            continue
        out.append(node)
        todo.extend(ast.iter_child_nodes(node))
    return out


def _exists(module: str) -> bool:
    path = PACKAGE.parent / Path(*module.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def runtime_imports(path: Path) -> set[str]:
    """The `echo_data` modules `path` imports when it runs."""
    return imported_modules(path.read_text(), module_name(path), path.name == "__init__.py", runtime=True)


def import_graph() -> dict[str, set[str]]:
    return {module_name(p): runtime_imports(p) for p in sorted(PACKAGE.rglob("*.py"))}


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    return sorted(f"{a} -> {b}" for a, deps in graph.items() for b in deps if layer_index(b) > layer_index(a))


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_circles_are_found() -> None:
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert layer_index("echo_data.learn.cli") > layer_index("echo_data.learn.fit") > layer_index("echo_data.recipe")


def test_type_checking_imports_are_not_dependencies(tmp_path: Path) -> None:
    tree = ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import echo_data.world\nimport echo_data.seeds\n")
    names = {a.name for n in _runtime_nodes(tree) if isinstance(n, ast.Import) for a in n.names}
    assert names == {"echo_data.seeds"}


def test_few_upward_imports() -> None:
    up = upward_imports(import_graph())
    assert len(up) <= MAX_UPWARD, f"{len(up)} imports go from a lower layer to a higher one: {up}"


def test_no_import_circles() -> None:
    assert not circles(import_graph())
