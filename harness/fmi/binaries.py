"""What a platform binary must be before it is loaded into this process.

Loading maps the file's segments into memory; a segment that lies past the end of a truncated file
is a bus error (SIGBUS) at the first touch, which kills the process before any clean-up runs. So
the ELF headers are read first and every loadable segment and the section table must lie inside
the file. (A binary that is complete but wrong is the FMU's own code, which any importer runs.)
"""
from __future__ import annotations

import re
import struct
from pathlib import Path

from harness.errors import HarnessError

IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
ELF_MAGIC = b"\x7fELF"
ELF_64, LITTLE_ENDIAN, X86_64, PT_LOAD = 2, 1, 62, 1


def checked_identifier(identifier: str | None, where: str) -> str:
    """A modelIdentifier names a file in binaries/<platform>/: a C identifier, so never a path."""
    if not identifier or not IDENTIFIER.fullmatch(identifier):
        raise HarnessError(f"{where}: modelIdentifier {identifier!r} is not a C identifier (letters, digits, "
                           "underscores); it must name a binary, not a path")
    return identifier


def elf_problem(library: Path) -> str | None:
    """Why the x86_64 Linux shared library cannot be loaded safely, or None."""
    try:
        data = library.read_bytes()
    except OSError as error:
        return f"cannot be read ({error.strerror})"
    if len(data) < 64 or data[:4] != ELF_MAGIC:
        return "is not an ELF shared library"
    if data[4] != ELF_64 or data[5] != LITTLE_ENDIAN:
        return "is not a 64-bit little-endian ELF file"
    machine, = struct.unpack_from("<H", data, 18)
    if machine != X86_64:
        return f"is built for machine {machine}, not x86_64"
    phoff, shoff = struct.unpack_from("<QQ", data, 32)
    phentsize, phnum, shentsize, shnum = struct.unpack_from("<HHHH", data, 54)
    if phentsize < 56 or phoff + phentsize * phnum > len(data):
        return f"is truncated ({len(data)} bytes; its program headers lie beyond)"
    if shnum and shoff + shentsize * shnum > len(data):
        return f"is truncated ({len(data)} bytes; its section table lies beyond)"
    for k in range(phnum):
        kind, = struct.unpack_from("<I", data, phoff + k * phentsize)
        offset, = struct.unpack_from("<Q", data, phoff + k * phentsize + 8)
        size, = struct.unpack_from("<Q", data, phoff + k * phentsize + 32)
        if kind == PT_LOAD and offset + size > len(data):
            return f"is truncated ({len(data)} bytes; a loadable segment ends at byte {offset + size})"
    return None
