"""Simulating one FMU in Co-Simulation: a fixed communication grid, every output recorded.

Unlike fmpy's simulate_fmu, a step that returns fmi2Discard ends the run with the last good point
recorded and a note, instead of looping forever.
"""
from __future__ import annotations

import ctypes
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.errors import HarnessError
from harness.fmi.fmu_instance import DISCARD, ERROR, STATUS_NAMES, FmuInstance
from harness.fmi.results import TimeTable


@dataclass
class SimulationResult(TimeTable):
    fmu: str = ""
    discarded_at: float | None = None  # time of the last good point when a step was discarded
    messages: list[str] = field(default_factory=list)
    interrupted: bool = False  # stopped by an interrupt (Ctrl-C): the rows before it are kept


MAX_POINTS = 10_000_000  # communication points of one run: the rows of its table
MAX_CELLS = 100_000_000  # numbers in one run's table (800 MB): memory is taken before the run starts


def check_table_size(points: int, columns: int) -> None:
    """Refuses a table too large to hold, before it is allocated (an allocation the system grants
    lazily would otherwise end the process later, out of memory)."""
    if points * columns > MAX_CELLS:
        raise HarnessError(f"{points} communication points of {columns} columns would be {points * columns:.3g} "
                           f"numbers ({points * columns * 8 / 1e9:.1f} GB), more than the {MAX_CELLS:.0e} allowed: "
                           "choose a larger step or a shorter time")


class Progress:
    """A line on stderr every `interval` seconds of a long run: how far it is and about how long is
    left. Calling it is cheap when no line is due."""

    def __init__(self, stop: float, interval: float = 2.0):
        self.stop, self.interval = stop, interval
        self.started = self.last = time.monotonic()

    def __call__(self, t: float, fraction: float) -> None:
        now = time.monotonic()
        if now - self.last < self.interval:
            return
        self.last = now
        left = (now - self.started) * (1 - fraction) / fraction if fraction > 0 else math.inf
        print(f"  t = {t:.4g} of {self.stop:g} s ({100 * fraction:.0f}%, about {_duration(left)} left)",
              file=sys.stderr)


def _duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "an unknown time"
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min" if seconds < 7200 else \
        f"{seconds / 3600:.1f} h"


def communication_grid(start_time: float, stop_time: float, step: float) -> np.ndarray:
    """start, start + step, ..., stop: points computed from their index (never accumulated). The
    start is always a point of its own, however short the run."""
    for what, value in (("start time", start_time), ("stop time", stop_time), ("communication step", step)):
        if not math.isfinite(value):
            raise HarnessError(f"{what} {value} must be a finite number")
    if not step > 0:
        raise HarnessError(f"communication step {step} must be a positive number")
    if not stop_time > start_time:
        raise HarnessError(f"stop time {stop_time} must be after the start time {start_time}")
    points = (stop_time - start_time) / step
    if points > MAX_POINTS:
        raise HarnessError(f"{stop_time - start_time:g} s in steps of {step:g} s would be {points:.3g} communication "
                           f"points, more than the {MAX_POINTS:.0e} allowed: choose a larger step")
    n = max(1, math.ceil(points - 1e-9))
    grid = start_time + step * np.arange(n + 1)
    grid[-1] = stop_time
    if np.any(np.diff(grid) <= 0):
        raise HarnessError(f"a step of {step:g} s does not advance the time at t = {stop_time:g} s "
                           "(below the resolution of double precision)")
    return grid


def simulate(fmu: str | Path, stop_time: float, step: float = 0.01, start_time: float = 0.0,
             start_values: dict | None = None, outputs: list[str] | None = None,
             unzipdir: str | None = None, keep_interrupted: bool = False,
             progress: bool = False) -> SimulationResult:
    """Runs the FMU from start_time to stop_time; start_values by name (solver="rk4", h=0.008, ...).
    unzipdir: an already extracted copy of the FMU, to save extracting it again. keep_interrupted:
    Ctrl-C ends the run with the rows so far (`interrupted` set) instead of raising KeyboardInterrupt.
    progress: a line on stderr every two seconds of a long run."""
    grid = communication_grid(start_time, stop_time, step)
    with FmuInstance(fmu, name=Path(fmu).stem, unzipdir=unzipdir) as instance:
        instance.initialize(start_time, **(start_values or {}))
        if outputs is None:
            outputs = [v.name for v in instance.model_description.modelVariables if v.causality == "output"]
        return Recorder(instance, grid, outputs).run(keep_interrupted, Progress(stop_time) if progress else None)


class Recorder:
    """The stepping loop of one instance over one grid, prepared once and run as often as needed
    (after each reset and initialization): the get-float call writes straight into the rows of a
    preallocated table through the instance's own prototypes. This is the loop the sweeps and the
    benchmarks time."""

    def __init__(self, instance: FmuInstance, grid: np.ndarray, outputs: list[str]):
        self.instance = instance
        real_names, integer_names = instance.recorded_outputs(outputs)
        self.columns = ["time"] + real_names + integer_names
        check_table_size(len(grid), len(self.columns))
        self.n_real, self.n_int = len(real_names), len(integer_names)
        self.real_vrs = (ctypes.c_uint * self.n_real)(*[instance.reference(n) for n in real_names])
        self.grid = np.asarray(grid, dtype=float)
        self.times = self.grid.tolist()
        self.reals = np.zeros((len(grid), max(self.n_real, 1)))
        integers = instance.integer_reader(integer_names)
        self.read_integers = integers.read
        self.integers = np.zeros((len(grid), max(self.n_int, 1)), dtype=integers.dtype)
        # row addresses, computed once
        self.real_rows = (self.reals.__array_interface__["data"][0] + self.reals.strides[0] * np.arange(len(grid))).tolist()
        self.int_rows = (self.integers.__array_interface__["data"][0]
                         + self.integers.strides[0] * np.arange(len(grid))).tolist()

    def run(self, keep_interrupted: bool = False, progress: Progress | None = None) -> SimulationResult:
        instance = self.instance
        name = instance.path.name
        raw = instance.raw
        component, get_real, read_integers, do_step = raw.component, raw.get_real, self.read_integers, raw.do_step
        real_vrs, n_real, n_int = self.real_vrs, self.n_real, self.n_int
        real_rows, int_rows, times = self.real_rows, self.int_rows, self.times
        discarded_at = None

        def record(row: int) -> None:
            status = get_real(component, real_vrs, n_real, real_rows[row])
            if n_int:
                status = max(status, read_integers(int_rows[row]))
            if status >= ERROR:
                raise HarnessError(f"{name}: reading outputs returned {STATUS_NAMES[status]}: "
                                   f"{instance.last_message()}")

        rows = len(times)
        interrupted = False
        record(0)
        i = 1
        try:
            for i in range(1, len(times)):
                t = times[i - 1]
                status = do_step(component, t, times[i] - t, 1)
                if status == DISCARD:
                    discarded_at = instance.last_successful_time()
                    rows = i
                    if discarded_at > t:  # the state it got to is a row of its own; else it is row i - 1
                        record(i)
                        rows = i + 1
                    break
                if status >= ERROR:
                    raise HarnessError(f"{name}: {instance.prefix}DoStep at t = {t} returned {STATUS_NAMES[status]}: "
                                       f"{instance.last_message()}")
                record(i)
                if progress is not None and not i & 63:
                    progress(times[i], i / (rows - 1))
        except KeyboardInterrupt:  # the rows before the interrupted step are kept, if the caller wants them
            if not keep_interrupted:
                raise
            interrupted, rows, discarded_at = True, i, None
        table = np.empty((rows, len(self.columns)))
        table[:, 0] = self.grid[:rows]
        if discarded_at is not None and rows > 1 and discarded_at > self.grid[rows - 2]:
            table[-1, 0] = discarded_at  # the row of the state the discarded step got to
        table[:, 1:1 + n_real] = self.reals[:rows, :n_real]
        table[:, 1 + n_real:] = self.integers[:rows, :n_int]
        return SimulationResult(self.columns, table, instance.path.stem, discarded_at,
                                [str(m) for m in instance.log.messages], interrupted)
