"""Work-precision: what accuracy a given cost buys, for every pendulum and method, with the peers.

Each point runs 10 s from the FMU's default start values and parameters with a communication step of
0.01 s. `error` is the largest Euclidean distance in metres between the outer mass and the
reference over those points (`reference.tight_reference`: the exact elliptic solution for
SimplePendulum, a long-double fifth-order run with a step-halving error estimate for the others).
Cost is counted as right-hand-side evaluations (the FMU's `n_rhs`, scipy's `nfev`) and as seconds
(median of repeats, the instance loaded once and reset between repeats).
"""
from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.fmi.fmu_instance import FmuInstance
from harness.fmi.methods import FIXED_STEP, ORDER
from harness.fmi.simulation import Recorder, communication_grid
from harness.objects.thesis.equations import OUTER_MASS, Pendulum
from harness.objects.thesis.reference import Reference, tight_reference
from harness.studies.records import columns_of, read_records, write_records
from harness.studies.sweep import run_sweep

STOP, STEP = 10.0, 0.01
PENDULUMS = ("SimplePendulum", "DoublePendulum", "SpringPendulum")
# Substeps per communication step, by order: enough that every method's error reaches the
# asymptotic range (below about 2e-2 m; the chaotic DoublePendulum gets there last) and, for the
# higher orders, the rounding floor. Euler never gets there on the DoublePendulum (it would need
# about 1e9 evaluations).
SUBSTEPS = {1: (4, 16, 64, 256, 1024, 4096), 2: (2, 4, 8, 16, 32, 64, 128, 256, 512, 1024),
            3: (2, 4, 8, 16, 32, 64, 128, 256), 4: (1, 2, 4, 8, 16, 32, 64), 5: (1, 2, 4, 8, 16),
            6: (1, 2, 4, 8, 16)}
RKF45_TOLERANCES = (1e-6, 1e-8, 1e-10, 1e-12, 1e-14)
SCIPY_METHODS = ("RK45", "DOP853", "LSODA")
PEER_TOLERANCES = (1e-4, 1e-6, 1e-8, 1e-10)


@dataclass
class Point:
    object: str
    method: str
    h: float  # internal step (fixed-step methods); NaN otherwise
    tol: float  # tolerance (rkf45 and the peers); NaN otherwise
    error: float  # metres; inf when the run stopped early (fmi2Discard)
    rhs_evals: int
    seconds: float


@dataclass(frozen=True)
class Task:
    """One point to compute; plain data so that it can be sent to another process or a Dask worker."""
    object: str
    method: str
    h: float
    tol: float
    fmu: str
    repeats: int


def settings(objects=PENDULUMS, repeats: int = 3, fmu_dir: Path | None = None, quick: bool = False) -> list[Task]:
    """Every point of the chart; quick: every other step and tolerance (a chart in a few seconds)."""
    from harness.fmi.fmus import build_dir
    folder = Path(fmu_dir) if fmu_dir else build_dir() / "fmus"
    nan = math.nan
    thin = (lambda values: values[::2]) if quick else (lambda values: values)  # noqa: E731
    tasks = []
    for name in objects:
        fmu = str(folder / f"{name}.fmu")
        for method in FIXED_STEP:
            tasks += [Task(name, method, STEP / k, nan, fmu, repeats) for k in thin(SUBSTEPS[ORDER[method]])]
        tasks += [Task(name, "rkf45", nan, tol, fmu, repeats) for tol in thin(RKF45_TOLERANCES)]
        tasks += [Task(name, f"scipy-{m}", nan, tol, fmu, repeats) for m in SCIPY_METHODS
                  for tol in thin(PEER_TOLERANCES)]
        tasks += [Task(name, "fmpy-CVode", nan, tol, fmu, repeats) for tol in thin(PEER_TOLERANCES)]
    return tasks


# Reference steps per communication step: the step-halving estimate then stays below 1e-12 m.
REFERENCE_SUBSTEPS = {"SimplePendulum": 16, "DoublePendulum": 40, "SpringPendulum": 16}


def reference_for(fmu: str) -> Reference:
    """The tight reference of an FMU's default run."""
    pendulum = Pendulum.from_fmu(fmu)
    return tight_reference(pendulum, STOP, STEP, REFERENCE_SUBSTEPS[pendulum.name])


def position_error(positions: np.ndarray, reference: Reference) -> float:
    if len(positions) != len(reference.positions):
        return math.inf
    return float(np.max(np.hypot(*(positions - reference.positions).T)))


def _median_seconds(run, repeats: int):
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def _fmu_point(task: Task, reference: Reference) -> Point:
    grid = communication_grid(0.0, STOP, STEP)
    start = {"solver": task.method}
    start.update({"h": task.h} if task.method != "rkf45" else {"tol": task.tol})
    with FmuInstance(task.fmu, name=task.object) as instance:
        recorder = Recorder(instance, grid, list(OUTER_MASS[task.object]))

        def run():
            instance._require(instance.call("fmi2Reset"), "fmi2Reset")
            instance.initialize(0.0, **start)
            return recorder.run()
        seconds, result = _median_seconds(run, task.repeats)
        evaluations = int(instance.get("n_rhs")[0])
    error = math.inf if result.discarded_at is not None else position_error(result.values[:, 1:3], reference)
    return Point(task.object, task.method, task.h, task.tol, error, evaluations, seconds)


def _scipy_point(task: Task, reference: Reference) -> Point:
    from scipy.integrate import solve_ivp
    pendulum = Pendulum.from_fmu(task.fmu)
    grid = communication_grid(0.0, STOP, STEP)

    def run():
        return solve_ivp(pendulum.rhs, (0.0, STOP), pendulum.start, method=task.method.split("-", 1)[1],
                         t_eval=grid, rtol=task.tol, atol=task.tol)
    seconds, solution = _median_seconds(run, task.repeats)
    error = position_error(pendulum.outer_mass(solution.y.T), reference) if solution.success else math.inf
    return Point(task.object, task.method, task.h, task.tol, error, int(solution.nfev), seconds)


def _cvode_point(task: Task, reference: Reference) -> Point:
    from fmpy import simulate_fmu
    from fmpy.model_description import read_model_description
    from fmpy import extract
    description = read_model_description(task.fmu)  # read once: simulate_fmu would parse it every run
    unzipped = extract(task.fmu)  # once per point, not per repeat

    def run():
        return simulate_fmu(unzipped, model_description=description, fmi_type="ModelExchange", solver="CVode",
                            relative_tolerance=task.tol, output_interval=STEP, stop_time=STOP,
                            output=[*OUTER_MASS[task.object], "n_rhs"])
    seconds, result = _median_seconds(run, task.repeats)
    positions = np.column_stack([result[n] for n in OUTER_MASS[task.object]])
    return Point(task.object, task.method, task.h, task.tol, position_error(positions, reference),
                 int(result["n_rhs"][-1]), seconds)


def compute(job: tuple[Task, Reference]) -> Point:
    """One point: an FMU run, a scipy run or fmpy's Model Exchange run with CVode."""
    task, reference = job
    if task.method.startswith("scipy-"):
        return _scipy_point(task, reference)
    if task.method == "fmpy-CVode":
        return _cvode_point(task, reference)
    return _fmu_point(task, reference)


def work_precision(tasks: list[Task], scheduler: str | None = None, workers: int | None = None) -> list[Point]:
    """All points, computed in parallel (see `harness.studies.sweep`); the references first, once per FMU."""
    fmus = sorted({task.fmu for task in tasks})
    references = dict(zip(fmus, run_sweep(reference_for, fmus, scheduler, workers)))
    return run_sweep(compute, [(task, references[task.fmu]) for task in tasks], scheduler, workers)


def pareto_front(points: list[Point], cost: str = "rhs_evals") -> list[Point]:
    """The points no other point beats in both cost and error, cheapest first."""
    finite = sorted((p for p in points if math.isfinite(p.error)), key=lambda p: (getattr(p, cost), p.error))
    front, best = [], math.inf
    for p in finite:
        if p.error < best:
            front.append(p)
            best = p.error
    return front


def write_csv(points: list[Point], path: Path) -> None:
    write_records(points, path, columns_of(Point))


def read_csv(path: Path) -> list[Point]:
    return read_records(path, Point)
