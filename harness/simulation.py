"""Simulating one FMU in Co-Simulation: a fixed communication grid, every output recorded.

Unlike fmpy's simulate_fmu, a step that returns fmi2Discard ends the run with the last good point
recorded and a note, instead of looping forever.
"""
from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.errors import HarnessError
from harness.fmu_instance import DISCARD, ERROR, STATUS_NAMES, FmuInstance
from harness.results import TimeTable


@dataclass
class SimulationResult(TimeTable):
    fmu: str = ""
    discarded_at: float | None = None  # time of the last good point when a step was discarded
    messages: list[str] = field(default_factory=list)


def communication_grid(start_time: float, stop_time: float, step: float) -> np.ndarray:
    """start, start + step, ..., stop: points computed from their index (never accumulated)."""
    if not (step > 0) or not math.isfinite(step):
        raise HarnessError(f"communication step {step} must be a positive number")
    if not (stop_time > start_time):
        raise HarnessError(f"stop time {stop_time} must be after the start time {start_time}")
    n = math.ceil((stop_time - start_time) / step - 1e-9)
    grid = start_time + step * np.arange(n + 1)
    grid[-1] = stop_time
    return grid


def simulate(fmu: str | Path, stop_time: float, step: float = 0.01, start_time: float = 0.0,
             start_values: dict | None = None, outputs: list[str] | None = None,
             unzipdir: str | None = None) -> SimulationResult:
    """Runs the FMU from start_time to stop_time; start_values by name (solver="rk4", h=0.008, ...).
    unzipdir: an already extracted copy of the FMU, to save extracting it again."""
    grid = communication_grid(start_time, stop_time, step)
    with FmuInstance(fmu, name=Path(fmu).stem, unzipdir=unzipdir) as instance:
        instance.initialize(start_time, **(start_values or {}))
        if outputs is None:
            outputs = [v.name for v in instance.model_description.modelVariables if v.causality == "output"]
        return run_initialized(instance, grid, outputs)


def run_initialized(instance: FmuInstance, grid: np.ndarray, outputs: list[str]) -> SimulationResult:
    """Steps an initialized instance over the grid, recording the outputs at every point (Real
    columns first). Raw calls into preallocated arrays: this is also the loop benchmarks time."""
    name = instance.path.name
    real_names = [n for n in outputs if instance.variables[n].type == "Real"]
    integer_names = [n for n in outputs if n not in real_names]
    columns = ["time"] + real_names + integer_names
    real_vrs = (ctypes.c_uint * len(real_names))(*[instance.reference(n) for n in real_names])
    integer_vrs = (ctypes.c_uint * len(integer_names))(*[instance.reference(n) for n in integer_names])
    real_out = (ctypes.c_double * len(real_names))()
    integer_out = (ctypes.c_int * len(integer_names))()
    table = np.empty((len(grid), len(columns)))
    discarded_at = None
    rows = 0

    def record(t: float) -> None:
        status = max(instance.call("fmi2GetReal", real_vrs, len(real_names), real_out),
                     instance.call("fmi2GetInteger", integer_vrs, len(integer_names), integer_out))
        if status >= ERROR:
            raise HarnessError(f"{name}: reading outputs returned {STATUS_NAMES[status]}: {instance.last_message()}")
        table[rows, 0] = t
        table[rows, 1:1 + len(real_names)] = real_out
        table[rows, 1 + len(real_names):] = integer_out

    for i, t in enumerate(grid):
        record(t)
        rows += 1
        if i + 1 == len(grid):
            break
        status = instance.do_step(t, grid[i + 1] - t)
        if status == DISCARD:
            discarded_at = instance.last_successful_time()
            record(discarded_at)
            rows += 1
            break
        if status >= ERROR:
            raise HarnessError(f"{name}: fmi2DoStep at t = {t} returned {STATUS_NAMES[status]}: "
                               f"{instance.last_message()}")
    return SimulationResult(columns, table[:rows], instance.path.stem, discarded_at,
                            [str(m) for m in instance.log.messages])
