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
from harness.fmi.native_calls import AT_FLOATS, AT_INTEGERS, AT_STEP, RecordUnit, fill_calls, load_record_loop
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
    (after each reset and initialization): the outputs of each communication point go straight into
    the rows of preallocated tables. The loop runs in C (harness/fmi/native/record_loop.c, many rows
    per call) when it is built, else in Python through the instance's own prototypes; both have one
    contract (rows(first, end) below) and give the same table. This is the loop `simulate`, the
    sweeps and the benchmarks use."""

    CHUNK_SECONDS = 0.1  # native calls grow from one row to about this long: between two calls an interrupt
    # is seen (the rows the interrupted call wrote are kept) and progress is shown

    def __init__(self, instance: FmuInstance, grid: np.ndarray, outputs: list[str], native: bool = True):
        self.instance = instance
        real_names, integer_names = instance.recorded_outputs(outputs)
        self.columns = ["time"] + real_names + integer_names
        check_table_size(len(grid), len(self.columns))
        self.n_real, self.n_int = len(real_names), len(integer_names)
        self.real_vrs = (ctypes.c_uint * max(self.n_real, 1))(*[instance.reference(n) for n in real_names])
        self.grid = np.ascontiguousarray(grid, dtype=float)
        self.times = self.grid.tolist()
        self.reals = np.zeros((len(grid), max(self.n_real, 1)))
        self.integer_reader = instance.integer_reader(integer_names)
        self.integers = np.zeros((len(grid), max(self.n_int, 1)), dtype=self.integer_reader.dtype)
        library = load_record_loop() if native else None
        self.rows = self._native_rows(library) if library is not None else self._python_rows()
        self.native = library is not None

    def _native_rows(self, library):
        unit = RecordUnit()
        fill_calls(unit.calls, self.instance.raw, self.integer_reader)
        unit.n_real, unit.n_int = self.n_real, self.n_int
        unit.real_vrs, unit.int_vrs = ctypes.addressof(self.real_vrs), ctypes.addressof(self.integer_reader.vrs)
        unit.reals, unit.real_stride = self.reals.ctypes.data, self.reals.strides[0]
        unit.ints, unit.int_stride = self.integers.ctypes.data, self.integers.strides[0]
        record_rows, grid, unit_p = library.record_rows, self.grid.ctypes.data, ctypes.byref(unit)
        done, where = ctypes.c_long(), ctypes.c_int()
        self._keep = unit
        self._rows_written = done  # set by each call before it returns: the rows kept after an interrupt

        def rows(first: int, end: int) -> tuple[int, int, int]:
            status = record_rows(unit_p, grid, first, end, ctypes.byref(done), ctypes.byref(where))
            return status, done.value, where.value
        return rows

    def _python_rows(self):
        raw = self.instance.raw
        component, do_step, read_row, times = raw.component, raw.do_step, self._read_row, self.times

        def rows(first: int, end: int) -> tuple[int, int, int]:
            for i in range(first, end):
                if i > 0:
                    status = do_step(component, times[i - 1], times[i] - times[i - 1], 1)
                    if status == DISCARD or status >= ERROR:
                        return status, i, AT_STEP
                status, where = read_row(i)
                if status >= ERROR:
                    return status, i, where
            return 0, end, AT_STEP
        return rows

    def run(self, keep_interrupted: bool = False, progress: Progress | None = None) -> SimulationResult:
        instance, times, rows = self.instance, self.times, self.rows
        discarded_at = None
        total = len(times)
        interrupted = False
        done, chunk = 0, 1  # Python: a row per call, so none is lost
        if self.native:
            self._rows_written.value = 0  # not the last run's count
        try:
            while done < total:
                started = time.perf_counter()
                status, done, where = rows(done, min(total, done + chunk))
                if status == DISCARD and where == AT_STEP:
                    t = times[done - 1]
                    discarded_at = instance.last_successful_time()
                    if discarded_at > t:  # the state it got to is a row of its own; else it is row done - 1
                        status, where = self._read_row(done)
                        if status >= ERROR:
                            self._raise(status, done, where)
                        done += 1
                    break
                if status >= ERROR:
                    self._raise(status, done, where)
                if progress is not None and done < total and (self.native or not done & 63):
                    progress(times[done - 1], (done - 1) / (total - 1))
                if self.native:  # calls of about CHUNK_SECONDS each, growing at most fourfold
                    elapsed = time.perf_counter() - started
                    chunk = int(min(max(chunk * self.CHUNK_SECONDS / max(elapsed, 1e-9), 1), 4 * chunk, 1 << 24))
        except KeyboardInterrupt:  # the rows before the interrupted step are kept, if the caller wants them
            if not keep_interrupted:
                raise
            if self.native:  # the call the interrupt came in wrote rows before it returned
                done = max(done, self._rows_written.value)
            interrupted, discarded_at = True, None
        table = np.empty((done, len(self.columns)))
        table[:, 0] = self.grid[:done]
        if discarded_at is not None and done > 1 and discarded_at > self.grid[done - 2]:
            table[-1, 0] = discarded_at  # the row of the state the discarded step got to
        table[:, 1:1 + self.n_real] = self.reals[:done, :self.n_real]
        table[:, 1 + self.n_real:] = self.integers[:done, :self.n_int]
        return SimulationResult(self.columns, table, instance.path.stem, discarded_at,
                                [str(m) for m in instance.log.messages], interrupted)

    def _read_row(self, row: int) -> tuple[int, int]:
        """The outputs of the instance as it is now into `row`: (status, the call that failed)."""
        raw = self.instance.raw
        status = raw.get_real(raw.component, self.real_vrs, self.n_real, self.reals[row].ctypes.data)
        if status >= ERROR:
            return status, AT_FLOATS
        if self.n_int and (status := self.integer_reader.read(self.integers[row].ctypes.data)) >= ERROR:
            return status, AT_INTEGERS
        return 0, AT_STEP

    def _raise(self, status: int, row: int, where: int):
        instance = self.instance
        if where == AT_STEP:
            t = self.times[row - 1]
            raise HarnessError(f"{instance.path.name}: {instance.prefix}DoStep at t = {t} returned "
                               f"{STATUS_NAMES[status]}: {instance.last_message()}")
        raise HarnessError(f"{instance.path.name}: reading outputs returned {STATUS_NAMES[status]}: "
                           f"{instance.last_message()}")
