"""The one exception type the command line reports as a one-line message."""
from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


class HarnessError(Exception):
    """A user error or a failed run: reported without a traceback, exit code 2."""


@contextmanager
def where(place: str, unpacked: str | Path | None = None) -> Iterator[None]:
    """Names the file or part a HarnessError from inside the block is about, unless it already does.
    `unpacked`: a temporary folder holding what was taken out of `place` (an archive); its path in a
    message becomes the member's place in the archive (x.ssp/resources/a.fmu)."""
    try:
        yield
    except HarnessError as error:
        text = str(error)
        if unpacked is not None:
            text = text.replace(f"{unpacked}/", f"{place}/")
        if place and not text.startswith(place):
            text = f"{place}: {text}"
        if text == str(error):
            raise
        raise HarnessError(text) from None


def first_problem(error: BaseException) -> str:
    """A library's exception in one line: its first line, and where that only announces a list
    ("Failed to validate modelDescription.xml:" followed by "- ERROR (line 5, ...): ..." lines, as
    fmpy's schema validations word it), the first item of the list and how many more follow."""
    lines = [line.strip() for line in str(error).strip().splitlines() if line.strip()]
    if not lines:
        return type(error).__name__
    items = [line.removeprefix("- ").removeprefix("ERROR ") for line in lines[1:]]
    if not lines[0].endswith(":") or not items:
        return lines[0]
    more = f"; and {len(items) - 1} more" if len(items) > 1 else ""
    return f"{lines[0]} {items[0].rstrip('.')}{more}"
