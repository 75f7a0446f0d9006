"""Files the harness writes: checked before any work starts, written through a temporary file beside
the target and renamed over it when writing ends.

The rename happens however writing ends (finished, stopped by a discard, failed, interrupted), so
that rows computed so far are kept; a failure of the writing itself (a full disk), or one before
any row was written, removes the temporary file and leaves the target as it was. Two runs writing the same file never interleave
their rows: each renames its own complete file, and the last one wins.
"""
from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TextIO

from harness.errors import HarnessError


def output_file(text: str | Path, option: str, inputs: tuple[str | Path | None, ...] = ()) -> Path:
    """The path of a file to write, refused at once if it cannot be one: a folder, a parent that is
    a file, or one of the command's own inputs."""
    path = Path(text)
    if str(text) == "" or path.name in ("", ".", ".."):
        raise HarnessError(f"{option} {str(text)!r}: names no file")
    if path.is_dir():
        raise HarnessError(f"{option} {path}: is a folder, not a file")
    if path.exists() and not path.is_file():  # a device such as /dev/null would be replaced by the rename
        raise HarnessError(f"{option} {path}: is not a regular file (a device, pipe or socket); choose a file")
    for given in inputs:
        if given is not None and Path(given).exists() and path.exists() and path.resolve() == Path(given).resolve():
            raise HarnessError(f"{option} {path}: is this command's input; choose another file")
    if path.suffix.lower() in (".fmu", ".ssp", ".ssd", ".json", ".toml") and path.exists():
        raise HarnessError(f"{option} {path}: is an existing {path.suffix} input file; choose another file")
    _check_parents(path, option)
    return path


def _check_parents(path: Path, option: str) -> None:
    """The nearest existing parent must be a folder (one to be created below a file cannot be)."""
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise HarnessError(f"{option} {path}: {parent} is a file, not a folder")
            return


def output_folder(text: str | Path, option: str) -> Path:
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise HarnessError(f"{option} {path}: is a file, not a folder")
    _check_parents(path, option)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise HarnessError(f"{option} {path}: cannot create the folder ({error.strerror})") from None
    return path


class _Sink:
    """The temporary file's stream; a failed write marks the file as lost."""

    def __init__(self, path: Path, stream: TextIO):
        self.path, self.stream, self.failed = path, stream, False
        self.writes = 0  # calls of write() after the header

    def write(self, text: str) -> None:
        self.writes += 1
        try:
            self.stream.write(text)
        except OSError as error:
            self.failed = True
            raise HarnessError(f"{self.path}: cannot write ({error.strerror or error})") from None


@contextmanager
def written(path: Path, header: str | None = None) -> Iterator[_Sink]:
    """A text sink whose content replaces `path` when the block ends (see the module's note). When
    the block fails before anything but the header was written, `path` is left as it was."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        descriptor, temporary = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    except OSError as error:
        raise HarnessError(f"{path}: cannot write here ({error.strerror})") from None
    sink = _Sink(path, os.fdopen(descriptor, "w", newline="\n"))
    try:
        if header is not None:
            sink.write(header)
            sink.writes = 0
        yield sink
    except BaseException:
        if not sink.writes:
            sink.failed = True  # nothing computed: keep what was there
        raise
    finally:
        _finish(sink, temporary)


def _finish(sink: _Sink, temporary: str) -> None:
    try:
        try:
            sink.stream.close()  # flushes: it can fail on a full disk
        except OSError as error:
            sink.failed = True
            raise HarnessError(f"{sink.path}: cannot write ({error.strerror or error})") from None
        if not sink.failed:
            try:
                os.replace(temporary, sink.path)
            except OSError as error:
                sink.failed = True
                raise HarnessError(f"{sink.path}: cannot write ({error.strerror or error})") from None
    finally:
        if sink.failed and os.path.exists(temporary):
            os.unlink(temporary)
