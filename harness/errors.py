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
