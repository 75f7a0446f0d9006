"""Files the harness writes: checked before any work starts, written through a temporary file beside
the target and renamed over it when writing ends.

The rename happens however writing ends (finished, stopped by a discard, failed, interrupted), so
that rows computed so far are kept; a failure of the writing itself (a full disk), or one before
any row was written, removes the temporary file and leaves the target as it was. Two runs writing
the same file never interleave their rows: each renames its own complete file, and the last one wins.
"""
from __future__ import annotations

import csv
import io
import os
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

from harness.errors import HarnessError
from harness.interrupts import held


PICTURE_FORMATS = (".png", ".svg", ".pdf")


def output_file(text: str | Path, option: str, inputs: tuple[str | Path | None, ...] = (),
                formats: tuple[str, ...] | None = None, outputs: dict[str, Path] | None = None,
                replaces: str | None = None) -> Path:
    """The path of a file to write, refused at once if it cannot be one: a folder, a device, a parent
    that is a file, one of the command's inputs or a file inside an input folder, another output of
    the same command (`outputs`, by option), or (with `formats`) a name without one of those
    suffixes. A symbolic link is written through: the file it names is replaced, the link stays. An
    existing input-like file (.fmu, .ssp, ...) is only replaced by the command that makes that kind
    (`replaces`: its suffix)."""
    path = Path(text)
    if str(text) == "" or path.name in ("", ".", ".."):
        raise HarnessError(f"{option} {str(text)!r}: names no file")
    if formats is not None and path.suffix.lower() not in formats:
        raise HarnessError(f"{option} {path}: the file name must end in {', '.join(formats)}")
    path = writable_file(path, option)
    target = _resolved(path, option)
    for given in inputs:
        if given is None or str(given) == "":
            continue
        try:
            source = Path(given).resolve()
        except (RuntimeError, OSError):  # a link loop: the command's own reading reports it
            continue
        if target == source:
            raise HarnessError(f"{option} {path}: is this command's input; choose another file")
        if source.is_dir() and path.exists() and target.is_relative_to(source):
            raise HarnessError(f"{option} {path}: is a file of this command's input folder {given}; "
                               "choose another file")
    for other, taken in (outputs or {}).items():
        if target == _resolved(Path(taken), other):
            raise HarnessError(f"{option} {path}: is already the {other} file; choose another file")
    if path.suffix.lower() in (".fmu", ".ssp", ".ssd", ".json", ".toml") and path.exists() \
            and path.suffix.lower() != replaces:
        raise HarnessError(f"{option} {path}: is an existing {path.suffix} input file; choose another file")
    _check_parents(path, option)
    return path


def _resolved(path: Path, option: str) -> Path:
    try:
        return path.resolve()
    except (RuntimeError, OSError):  # Python 3.11 raises RuntimeError for a loop of symbolic links
        raise HarnessError(f"{option} {path}: is a loop of symbolic links") from None


def _check_parents(path: Path, option: str) -> None:
    """The nearest existing parent must be a folder (one to be created below a file cannot be)."""
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise HarnessError(f"{option} {path}: {parent} is a file, not a folder")
            return


def usable_folder(text: str | Path, option: str) -> Path:
    """The folder `text`, checked but not made: an existing folder, or one that can be made below one."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise HarnessError(f"{option} {path}: is a file, not a folder")
    _check_parents(path, option)
    return path


def output_folder(text: str | Path, option: str) -> Path:
    path = usable_folder(text, option)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise HarnessError(f"{option} {path}: cannot create the folder ({error.strerror})") from None
    return path


def csv_header(columns: list[str]) -> str:
    """A CSV header line: names holding a comma, quote or line break (an FMU's structured names such
    as a[1,2]) are quoted as RFC 4180 says, so that the header keeps one cell per column."""
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(columns)
    return buffer.getvalue()


class _Sink:
    """The temporary file's stream; a failed write marks the file as lost."""

    def __init__(self, path: Path, stream: IO, temporary: str):
        self.path, self.stream, self.temporary, self.failed = path, stream, temporary, False
        self.writes = 0  # calls of write() after the header

    def write(self, text: str | bytes) -> None:
        self.writes += 1
        try:
            self.stream.write(text)
        except OSError as error:
            self.failed = True
            raise HarnessError(f"{self.path}: cannot write ({error.strerror or error})") from None


@contextmanager
def written(path: Path, header: str | None = None, binary: bool = False) -> Iterator[_Sink]:
    """A text sink whose content replaces `path` when the block ends (see the module's note). When
    the block fails before anything but the header was written, `path` is left as it was."""
    path = writable_file(path, "output")
    sink = None
    try:
        with held():  # the temporary file, once it exists, is in the sink that _finish ends
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                # a short prefix: the temporary name must fit where the target's own name just fits
                descriptor, temporary = tempfile.mkstemp(prefix=f".{path.name[:40]}.", suffix=".part",
                                                         dir=path.parent)
            except OSError as error:
                raise HarnessError(f"{path}: cannot write here ({error.strerror})") from None
            sink = _Sink(path, os.fdopen(descriptor, "wb" if binary else "w", **({} if binary else {"newline": "\n"})),
                         temporary)
            try:
                os.fchmod(descriptor, _mode_for(path))
            except OSError as error:
                raise HarnessError(f"{path}: cannot write here ({error.strerror})") from None
        if header is not None:
            sink.write(header)
            sink.writes = 0
        yield sink
    except BaseException:
        if sink is not None and not sink.writes:
            sink.failed = True  # nothing computed: keep what was there
        raise
    finally:
        if sink is not None:
            _finish(sink)


def writable_file(path: Path, option: str) -> Path:
    """The file a write replaces (checked again when writing starts, also for the names a command
    chooses itself inside an output folder): a symbolic link is written through; a folder, device
    or pipe is refused, since the rename would replace it (/dev/null, say)."""
    if path.is_symlink():
        path = _resolved(path, option)
    if path.is_dir():
        raise HarnessError(f"{option} {path}: is a folder, not a file")
    if path.exists() and not path.is_file():
        raise HarnessError(f"{option} {path}: is not a regular file (a device, pipe or socket); choose another")
    return path


def _mode_for(path: Path) -> int:
    """The permissions a plain open() would give: those of the file replaced, else 0666 less the
    umask (mkstemp makes its file 0600)."""
    try:
        return stat.S_IMODE(path.stat().st_mode)
    except OSError:
        mask = os.umask(0o022)
        os.umask(mask)
        return 0o666 & ~mask


def write_figure(figure, path: Path, dpi: int = 110) -> None:
    """A matplotlib figure, rendered in memory and written like every output (see written())."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format=path.suffix.lstrip(".").lower(), dpi=dpi)
    with written(path, binary=True) as sink:
        sink.write(buffer.getvalue())


def _finish(sink: _Sink) -> None:
    with held():  # an interrupt neither loses the rows nor leaves the temporary file
        _end(sink, sink.temporary)


def _end(sink: _Sink, temporary: str) -> None:
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
