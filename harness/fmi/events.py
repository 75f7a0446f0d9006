"""When an FMU's events happen, as the FMU itself locates them.

FMI 2.0 Co-Simulation hides an event inside the step that holds it; FMI 3.0 Co-Simulation, when the
importer allows early return, ends the step at each event it handles and reports its time as
fmi3DoStep's lastSuccessfulTime. Stepping on the same communication grid as a recorded run, and going
on from each early return to the grid point, takes the same internal steps as that run.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.fmi.fmu_instance import DISCARD, ERROR, FmuInstance
from harness.fmi.fmus import FMI3_FOLDER

MAX_EVENTS = 100_000  # per run: a run that reports more (an event recurring at once) is cut off, not followed


@dataclass
class EventTimes:
    times: list[float]  # one per event instant (a cascade of impulses at one instant is one event)
    completed: bool  # False: the run stopped (discard, error, MAX_EVENTS) after the last time listed


def fmi3_counterpart(fmu: str | Path) -> Path | None:
    """The FMI 3.0 build of a project FMU or of one `harness derive` wrote (fmi3/<name>.fmu beside it)."""
    path = Path(fmu).parent / FMI3_FOLDER / Path(fmu).name
    return path if path.is_file() else None


def event_times(instance: FmuInstance, grid: np.ndarray) -> EventTimes:
    """The events an initialized FMI 3.0 Co-Simulation instance, made with `early_return`, handles from
    grid[0] to grid[-1], stepping on the grid."""
    times: list[float] = []
    for start, end in zip(grid[:-1].tolist(), grid[1:].tolist()):
        t = start
        while t < end:
            status = instance.do_step(t, end - t)
            if status == DISCARD or status >= ERROR or len(times) >= MAX_EVENTS:
                return EventTimes(times, False)
            if not instance.returned_early():
                break
            t = instance.last_successful_time()
            times.append(t)
    return EventTimes(times, True)


def matched_error(times: list[float], reference: list[float]) -> float:
    """The largest difference between the event times and the reference's, matched in order over the events
    both have (a run whose last event falls just beyond the end has one fewer); inf when either has none, or
    their counts differ by more than one (an event missed or one too many)."""
    if not times or not reference or abs(len(times) - len(reference)) > 1:
        return float("inf") if (times or reference) else float("nan")
    n = min(len(times), len(reference))
    return float(np.max(np.abs(np.subtract(times[:n], reference[:n]))))
