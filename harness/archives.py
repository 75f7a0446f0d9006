"""Reading zip archives (FMUs, SSP files) without trusting them.

Every member that is read or extracted is checked first: a relative name of forward-slash parts
with no drive, device or parent part, no encryption, a compression method the FMI and SSP standards
allow (store or deflate), and the archive as a whole within MAX_MEMBERS members and MAX_BYTES of
uncompressed data. Only the members a caller asks for are extracted, and corrupt data ends in a
one-line HarnessError instead of whichever exception zipfile or zlib raises.
"""
from __future__ import annotations

import atexit
import os
import shutil
import tempfile
import zipfile
import zlib
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path, PurePosixPath
from typing import IO

from harness.errors import HarnessError
from harness.interrupts import held

MAX_MEMBERS = 10_000
MAX_BYTES = 1 << 30  # uncompressed bytes extracted from one archive
MAX_READ = 64 << 20  # bytes of one member read into memory (a model description, an SSD)
MAX_NAME = 1024      # characters in a member's name; 255 per part, as file systems allow
ALLOWED_METHODS = {zipfile.ZIP_STORED: "store", zipfile.ZIP_DEFLATED: "deflate"}

# what zipfile and zlib raise for data that is not what the archive's directory says
CORRUPT = (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, RuntimeError, ValueError)


def name_problem(name: str) -> str | None:
    """Why a member name cannot be extracted safely, or None."""
    if len(name) > MAX_NAME:
        return f"is longer than {MAX_NAME} characters"
    if "\\" in name:
        return "contains a backslash (zip names use forward slashes)"
    if ":" in name:
        return "contains a drive or device letter (':')"
    if name.startswith("/"):
        return "is absolute"
    if any(ord(c) < 32 for c in name):
        return "contains a control character"
    parts = PurePosixPath(name).parts
    if ".." in parts:
        return "leaves the archive ('..')"
    if any(len(part.encode("utf-8", "surrogateescape")) > 255 for part in parts):
        return "has a part longer than 255 bytes"
    return None


def _shown(name: str) -> str:
    return repr(name if len(name) <= 80 else name[:77] + "...")


def member_problem(info: zipfile.ZipInfo) -> str | None:
    problem = name_problem(info.filename)
    if problem:
        return f"member {_shown(info.filename)} {problem}"
    if info.flag_bits & 0x1:
        return f"member {_shown(info.filename)} is encrypted"
    if info.compress_type not in ALLOWED_METHODS:
        return (f"member {_shown(info.filename)} uses compression method {info.compress_type} "
                f"(allowed: {', '.join(f'{k} ({v})' for k, v in ALLOWED_METHODS.items())})")
    return None


@contextmanager
def open_archive(source: str | Path | IO[bytes], what: str) -> Iterator[zipfile.ZipFile]:
    """The zip archive, its member count checked; `what` names it in errors."""
    try:
        archive = zipfile.ZipFile(source)
    except (OSError, *CORRUPT) as error:
        raise HarnessError(f"{what}: not a zip archive ({_reason(error)})") from None
    with archive:
        if len(archive.infolist()) > MAX_MEMBERS:
            raise HarnessError(f"{what}: {len(archive.infolist())} members, more than the {MAX_MEMBERS} allowed")
        yield archive


def _reason(error: BaseException) -> str:
    lines = str(error).strip().splitlines()
    return lines[0] if lines else type(error).__name__


def _checked(archive: zipfile.ZipFile, name: str, what: str) -> zipfile.ZipInfo:
    try:
        info = archive.getinfo(name)
    except KeyError:
        raise HarnessError(f"{what}: no member {_shown(name)}") from None
    problem = member_problem(info)
    if problem:
        raise HarnessError(f"{what}: {problem}")
    return info


def read_member(archive: zipfile.ZipFile, name: str, what: str, limit: int = MAX_READ) -> bytes:
    """One member's bytes, at most `limit` of them."""
    info = _checked(archive, name, what)
    if info.file_size > limit:
        raise HarnessError(f"{what}: member {_shown(name)} has {info.file_size} bytes, more than the {limit} allowed")
    try:
        with archive.open(info) as stream:
            return stream.read(limit + 1)[:limit]
    except CORRUPT as error:
        raise HarnessError(f"{what}: member {_shown(name)} is corrupt ({_reason(error)})") from None


def extract_members(archive: zipfile.ZipFile, target: Path, wanted: Callable[[str], bool], what: str) -> int:
    """Extracts the members whose names `wanted` accepts into target; returns how many. Sizes are
    counted as the data comes out, not taken from the archive's directory."""
    chosen = [info for info in archive.infolist() if wanted(info.filename)]
    total = 0
    for info in chosen:
        problem = member_problem(info)
        if problem:
            raise HarnessError(f"{what}: {problem}")
    for info in chosen:
        destination = target.joinpath(*PurePosixPath(info.filename).parts)
        try:
            if info.is_dir():
                destination.mkdir(parents=True, exist_ok=True)
                continue
            destination.parent.mkdir(parents=True, exist_ok=True)
            with archive.open(info) as source, destination.open("wb") as sink:
                while chunk := source.read(1 << 20):
                    total += len(chunk)
                    if total > MAX_BYTES:
                        raise HarnessError(f"{what}: more than {MAX_BYTES} bytes to extract (the bound)")
                    sink.write(chunk)
        except CORRUPT as error:
            raise HarnessError(f"{what}: member {_shown(info.filename)} is corrupt ({_reason(error)})") from None
        except OSError as error:
            raise HarnessError(f"{what}: cannot extract {_shown(info.filename)} to {target} "
                               f"({error.strerror or _reason(error)})") from None
    return len(chosen)


# The temporary folders made here and not removed yet, with the process that made them: an interrupt
# can come between a folder's making and its owner's taking it (a function returns it, the caller has
# not stored it yet); what is left when the process exits is removed then.
_FOLDERS: dict[Path, int] = {}


def temporary_folder(prefix: str) -> Path:
    """A new temporary folder, for `remove_folder` to remove, and removed at exit at the latest."""
    with held():
        folder = Path(tempfile.mkdtemp(prefix=prefix))
        _FOLDERS[folder] = os.getpid()
    return folder


def remove_folder(folder: str | Path) -> None:
    """A folder and all in it, gone (if it is there); an interrupt does not stop it half way."""
    with held():
        shutil.rmtree(folder, ignore_errors=True)
        _FOLDERS.pop(Path(folder), None)


@atexit.register
def _remove_folders_left() -> None:
    for folder, pid in list(_FOLDERS.items()):
        if pid == os.getpid():  # not a forked child's copy of its parent's list
            remove_folder(folder)


@contextmanager
def scratch_folder(prefix: str) -> Iterator[Path]:
    """A temporary folder removed when the block ends, however it ends."""
    folder = temporary_folder(prefix)
    try:
        yield folder
    finally:
        remove_folder(folder)


# x86_64 Linux in FMI 2.0 and FMI 3.0
THIS_PLATFORM = ("linux64", "x86_64-linux")


def extract_fmu(fmu: Path, platforms: tuple[str, ...] = THIS_PLATFORM) -> Path:
    """The parts of an FMU an importer needs (model description, this platform's binaries,
    resources) in a new temporary folder; the caller removes it (`remove_folder`). Nothing is left
    behind on error."""
    folder = temporary_folder("fmu_")
    binaries = tuple(f"binaries/{platform}/" for platform in platforms)
    try:
        with open_archive(fmu, str(fmu)) as archive:
            extract_members(archive, folder, lambda name: name == "modelDescription.xml"
                            or name.startswith((*binaries, "resources/")), str(fmu))
    except BaseException:
        remove_folder(folder)
        raise
    return folder
