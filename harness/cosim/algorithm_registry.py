"""The master algorithms, registered once: their names (the CLI's choices, scene and SSP settings), the id by which
the C loop (harness/cosim/native/cosim_core.c) knows each one, and whether the page's master (web/master.mjs) runs
it. harness.cosim.algorithms implements each name; this module imports nothing, so that the CLI reads the names
without loading the master."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class AlgorithmEntry:
    name: str
    what: str
    # the C loop's id for it (ALGORITHM_* in cosim_core.c, which refuses an id it does not know); None: the
    # Python loop runs it alone
    code: int | None
    page: bool  # the page's master runs it too


REGISTRY = (
    AlgorithmEntry("jacobi", "every unit takes the inputs of the step's start, then all step", 1, True),
    AlgorithmEntry("gauss-seidel", "the units step in the system's order, each taking what those before it reached",
                   2, True),
)
NAMES = tuple(entry.name for entry in REGISTRY)
ENTRY = {entry.name: entry for entry in REGISTRY}
DEFAULT = "gauss-seidel"
