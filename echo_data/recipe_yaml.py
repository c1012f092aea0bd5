"""Reading a recipe file: YAML with unique keys, `extends:` chains merged deepest-first, and
the limits that keep a hostile file from crashing the loader. Every problem is a one-line
`RecipeError` naming the file (`echo_data.recipe` validates what this returns).
"""

from __future__ import annotations

import stat
from pathlib import Path
from typing import Any

import yaml


class RecipeError(ValueError):
    """A recipe problem; `str()` is one line naming the file and the key."""


# A recipe is a few levels deep and extends one or two files; far more is a mistake (or a file
# written to crash the loader: 2,000 nested brackets overflowed Python's stack in a traceback).
MAX_EXTENDS_DEPTH = 16
MAX_NESTING = 32


def _deep_merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _deep_merge(out[k], v)
        else:
            out[k] = v
    return out


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that refuses a key given twice in one mapping (plain YAML keeps the last)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        first_line: dict[Any, int] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                if key in first_line:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key {key!r} (first given at line {first_line[key]})", key_node.start_mark
                    )
                first_line[key] = key_node.start_mark.line + 1
            except TypeError:  # an unhashable key: SafeLoader reports it below
                continue
        return super().construct_mapping(node, deep=deep)


def _resolve(path: Path, chain: tuple[Path, ...]) -> Path:
    """The real path of a recipe file; a symlink loop is one line naming the file that led there."""
    try:
        return path.resolve()
    except (RuntimeError, OSError):  # RuntimeError before Python 3.13, OSError (ELOOP) after
        where = f"{chain[-1]}: extends: {path}" if chain else str(path)
        raise RecipeError(f"{where}: symlink loop (the link points back to itself)") from None


def _deepest(data: Any, limit: int) -> str | None:
    """The key path of the first value nested deeper than `limit` levels (None when none is);
    iterative, so no nesting can exhaust Python's stack."""
    stack: list[tuple[Any, str, int]] = [(data, "", 0)]
    while stack:
        v, where, depth = stack.pop()
        if depth > limit:
            return where or "<root>"
        items = v.items() if isinstance(v, dict) else enumerate(v) if isinstance(v, list) else ()
        for k, x in items:
            stack.append((x, f"{where}.{k}" if where else str(k), depth + 1))
    return None


def _read_yaml(path: Path, chain: tuple[Path, ...] = ()) -> dict[str, Any]:
    """Read a recipe file and resolve its `extends:` chain into one mapping."""
    path = _resolve(path, chain)
    if path in chain:
        raise RecipeError(f"{path}: extends: circular chain {' -> '.join(str(p) for p in chain + (path,))}")
    if len(chain) >= MAX_EXTENDS_DEPTH:
        raise RecipeError(f"{chain[0]}: extends: a chain of more than {MAX_EXTENDS_DEPTH} files (at {path})")
    try:
        mode = path.stat().st_mode
        if not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):  # a FIFO or device would block or stream forever
            raise RecipeError(f"{path}: not a regular file")
        text = path.read_text()
    except FileNotFoundError:
        raise RecipeError(f"{path}: file not found") from None
    except (OSError, UnicodeDecodeError) as e:
        raise RecipeError(f"{path}: cannot read recipe ({e.__class__.__name__}: {getattr(e, 'strerror', None) or e})") from None
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 (a SafeLoader)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise RecipeError(f"{path}: malformed YAML{where}: {problem}") from None
    except RecursionError:  # PyYAML composes nested nodes recursively
        raise RecipeError(f"{path}: nested more than {MAX_NESTING} levels deep") from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise RecipeError(f"{path}: a recipe must be a mapping of keys, got {type(data).__name__}")
    deep = _deepest(data, MAX_NESTING)
    if deep is not None:
        raise RecipeError(f"{path}: {deep}: nested more than {MAX_NESTING} levels deep")
    parent = data.pop("extends", None)
    if parent is not None:
        if not isinstance(parent, str):
            raise RecipeError(f"{path}: extends: must be a file path")
        base = _read_yaml((path.parent / parent), chain + (path,))
        data = _deep_merge(base, data)
    return data


