"""Coupling error: what each master configuration costs and how accurate it is on any scene of
objects joined by Springs (by default the coupled-pendulums scene).

The reference is the scene's monolithic system, derived from its objects' energies and its springs
(`harness.studies.monolithic`) and integrated by scipy's DOP853 at rtol = atol = 1e-12, with the
parameters and start values the system gives its components. `error` is the largest Euclidean
distance of any object point from the reference over the communication points; cost is
right-hand-side evaluations summed over the components (rolled-back passes included), fmi2DoStep
calls, and seconds of the master's run (median of repeats; loading and instantiating not included).
"""
from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.cosim.master import Master, MasterOptions
from harness.cosim.structure import System
from harness.errors import HarnessError
from harness.fmi.simulation import communication_grid
from harness.studies.monolithic import MonolithicScene, largest_point_error
from harness.studies.records import columns_of, read_records, write_records
from harness.studies.sweep import run_sweep

CONFIGURATIONS = (("jacobi", "hold", None), ("jacobi", "linear", None), ("gauss-seidel", "hold", None),
                  ("gauss-seidel", "linear", None), ("jacobi", "linear", 1e-10), ("gauss-seidel", "linear", 1e-10))
STEPS = (0.04, 0.02, 0.01, 0.005, 0.0025)


@dataclass
class CouplingPoint:
    algorithm: str
    extrapolation: str
    iterate: float  # iteration tolerance; NaN for a single pass
    step: float
    error: float  # metres; inf when the run stopped early
    rhs_evals: int
    do_steps: int
    seconds: float

    @property
    def configuration(self) -> str:
        return f"{self.algorithm}, {self.extrapolation}" + ("" if math.isnan(self.iterate) else ", iterated")


def derived_reference(system: System, times: np.ndarray) -> tuple[dict[str, np.ndarray], list[tuple[str, str]]]:
    """The scene's monolithic reference (`harness.studies.monolithic`) at `times`: its columns and the
    (x, y) column pairs of every object point. Refuses a scene it cannot derive. (FMI 3.0 receivers take the
    linear extrapolation the studies compare through intermediate updates; the master refuses, by name, one
    whose FMU does not let it set their inputs so.)"""
    scene = MonolithicScene(system)
    if scene.contacts:
        raise HarnessError(f"{system.name}: its Contact elements' contacts last about a tenth of a millisecond, "
                           f"which the coupling chart's macro steps ({max(STEPS):g} to {min(STEPS):g} s) step over: "
                           "chart it with `harness chart contacts`")
    return scene.solve(times), scene.point_columns()


def coupling_error(result, reference: dict[str, np.ndarray], pairs: list[tuple[str, str]]) -> float:
    """The largest distance of any object point from the reference (whose grid holds the result's
    times); inf when the run stopped early."""
    if result.stopped_at is not None:
        return math.inf
    rows = np.searchsorted(reference["time"], result.time - 1e-9 * np.maximum(1.0, np.abs(result.time)))
    if len(rows) and (rows[-1] >= len(reference["time"]) or
                      not np.allclose(reference["time"][rows], result.time, rtol=1e-9, atol=1e-12)):
        raise HarnessError("the reference's grid does not hold the run's communication points")
    return largest_point_error(result, {name: column[rows] for name, column in reference.items()}, pairs)


def timed_runs(system: System, options: MasterOptions, repeats: int):
    """The last of `repeats` runs and the median of their seconds (loading and instantiating not timed)."""
    times, result = [], None
    for _ in range(repeats):
        with Master(system, options) as master:
            start = time.perf_counter()
            result = master.run()
            times.append(time.perf_counter() - start)
    return result, statistics.median(times)


def measure(job: tuple) -> CouplingPoint:
    """One configuration at one communication step (runs in a worker)."""
    system, (algorithm, extrapolation, iterate), step, stop, repeats, (reference, pairs) = job
    options = MasterOptions(stop=stop, step=step, algorithm=algorithm, extrapolation=extrapolation,
                            iterate_tol=iterate)
    result, seconds = timed_runs(system, options, repeats)
    # Every pass over a macro step steps each component once. A rolled-back pass restores the FMUs'
    # counters with their state, so its evaluations are counted at the kept pass's (fixed-step work).
    passes = result.iterations if iterate is not None else result.macro_steps + result.retries
    do_steps = passes * len(system.components)
    kept = sum(int(result[c][-1]) for c in result.columns if c.endswith(".n_rhs"))
    rhs = round(kept * passes / max(result.macro_steps, 1))
    return CouplingPoint(algorithm, extrapolation, math.nan if iterate is None else iterate, step,
                         coupling_error(result, reference, pairs), rhs, do_steps, seconds)


def coupling_sweep(system: System, stop: float | None = None, steps=STEPS, configurations=CONFIGURATIONS,
                   repeats: int = 3, scheduler: str | None = None, workers: int | None = None) -> list[CouplingPoint]:
    stop = stop if stop is not None else (system.stop or 10.0)
    finest = min(steps)
    if any(abs(step / finest - round(step / finest)) > 1e-9 for step in steps):
        raise HarnessError(f"the communication steps {steps} must be whole multiples of the finest, {finest:g}")
    grid = communication_grid(0.0, stop, finest)  # a bad stop time fails here, before any work
    measured_on = derived_reference(system, grid)  # once, at the finest grid: every coarser one is a subset
    jobs = [(system, configuration, step, stop, repeats, measured_on)
            for configuration in configurations for step in steps]
    return run_sweep(measure, jobs, scheduler, workers)


def write_csv(points: list[CouplingPoint], path: Path) -> None:
    write_records(points, path, columns_of(CouplingPoint))


def read_csv(path: Path) -> list[CouplingPoint]:
    return read_records(path, CouplingPoint)
