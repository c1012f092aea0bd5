"""Where a command writes, checked before it works, and write errors said in one line.

Why: `evaluate`, `export`, `view` and `train` used to run for minutes and then fail with a
traceback on a read-only or impossible `--out`. Each checks its target here first (the probe
is `outputs.check_output_path`, the build's own: a folder created and removed where the output would go) and
turns an `OSError` while writing into one line naming the option and the file.
"""

from __future__ import annotations

from pathlib import Path


class TargetError(ValueError):
    """An output target that cannot be written: one line naming the option."""


def check_folder(path: Path, option: str) -> None:
    """`path` can be a folder we write into (absent, or a folder, somewhere writable)."""
    from echo_data.outputs import OutputError, check_output_path

    try:
        check_output_path(path)
    except OutputError as e:
        raise TargetError(f"{option} {e}") from None


def check_file(path: Path, option: str) -> None:
    """`path` can be a file we write (not a folder; its folder absent or writable)."""
    from echo_data.outputs import OutputError, check_output_path

    if path.is_dir():
        raise TargetError(f"{option} {path}: is a folder")
    try:
        check_output_path(path.parent)
    except OutputError as e:
        raise TargetError(f"{option} {path}: cannot be written there ({e})") from None


def write_failed(option: str, path: Path, e: OSError) -> str:
    """The one line for an `OSError` met while making `path` (the target of `option`): a file
    outside the target was being read, not written."""
    name = Path(e.filename) if e.filename else path
    inside = name.absolute().is_relative_to(path.absolute()) or name.absolute() == path.absolute().parent
    inside = inside or (name.absolute().parent == path.absolute().parent and name.name.startswith(f".{path.name}."))  # its temporary sibling
    if not inside:
        return f"{option} {path}: cannot read {name} ({e.strerror or e})"
    return f"{option} {path}: cannot write {name} ({e.strerror or e})"
