"""Work-precision: what accuracy a given cost buys, for any object and method, with the peers.

Each point runs 10 s from the FMU's default start values and parameters with a communication step of
0.01 s. `error` is the largest Euclidean distance in metres between the traced point (the thesis
pendulums' outer mass, any other object's last point, in 2-D or 3-D) and the reference over those
points. The references: the exact elliptic solution for SimplePendulum, a long-double fifth-order
run over the hand-coded equations with a step-halving error estimate for the other thesis pendulums
(`harness.objects.thesis.reference`), the FMU's own nystrom5 at halved steps for every other object
(`harness.studies.references`); each point carries its reference's estimated error. The fixed steps
are scaled to the object's default step (Kapitza's pendulum, h = 1e-4 s, gets 64 times finer ones).
The scipy peers integrate the hand-coded equations (thesis pendulums) or the SymPy derivation's
(`harness.objects.motion`); an object with constraints has fmpy's CVode as its peer (Model Exchange,
the impacts as events) and its errors run through every impact. Cost is counted as evaluations (the
FMU's `n_rhs`, scipy's `nfev`; the implicit methods' Jacobians apart, as `jacobian_columns`, one
directional derivative per state for each, and compared at one right-hand side each: `evaluations`
is the sum) and as seconds (median of repeats, the instance loaded once and reset between repeats).
"""
from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from harness.cosim.structure import Component
from harness.fmi.events import event_times, fmi3_counterpart, matched_error
from harness.fmi.fmu_instance import FmuInstance, accepted_methods, float_start_values, read_description
from harness.errors import HarnessError
from harness.fmi.methods import ADAPTIVE, FIXED_STEP, METHODS, ORDER
from harness.fmi.results import rows_on_grid
from harness.fmi.simulation import Recorder, communication_grid
from harness.objects.derivation import derive
from harness.objects.motion import ObjectMotion
from harness.objects.proof import object_file_in
from harness.objects.thesis.equations import OUTER_MASS, Pendulum
from harness.objects.thesis.reference import tight_reference
from harness.studies.records import columns_of, read_records, write_records
from harness.studies.references import REFERENCE_METHOD, REFERENCE_ORDER, ObjectRunner, fmu_reference, traced_columns
from harness.studies.sweep import run_sweep

STOP, STEP = 10.0, 0.01
PENDULUMS = ("SimplePendulum", "DoublePendulum", "SpringPendulum")
# Substeps per communication step, by order: enough that every method's error reaches the
# asymptotic range (below about 2e-2 m; the chaotic DoublePendulum gets there last) and, for the
# higher orders, the rounding floor. Euler never gets there on the DoublePendulum (it would need
# about 1e9 evaluations).
SUBSTEPS = {1: (4, 16, 64, 256, 1024, 4096), 2: (2, 4, 8, 16, 32, 64, 128, 256, 512, 1024),
            3: (2, 4, 8, 16, 32, 64, 128, 256), 4: (1, 2, 4, 8, 16, 32, 64), 5: (1, 2, 4, 8, 16, 32),
            6: (1, 2, 4, 8, 16)}
ADAPTIVE_TOLERANCES = (1e-6, 1e-8, 1e-10, 1e-12, 1e-14)  # rkf45's and gbs's
# taylor over its orders, one fixed step per communication step (which ends every step here: its own
# step from tol would be longer, but the chart measures the error at every output point)
TAYLOR_SWEEP_ORDERS = (2, 3, 4, 5, 6, 8, 10, 12, 16, 20)
SCIPY_METHODS = ("RK45", "DOP853", "LSODA")
PEER_TOLERANCES = (1e-4, 1e-6, 1e-8, 1e-10)


@dataclass
class Point:
    object: str
    method: str
    h: float  # internal step (fixed-step methods); NaN otherwise
    tol: float  # tolerance (rkf45, gbs and the peers; 0 for taylor's fixed step); NaN otherwise
    error: float  # metres; inf when the run stopped early (fmi2Discard)
    rhs_evals: int
    seconds: float
    reference_error: float  # metres: the reference's estimated error (errors below it are not resolved)
    jacobian_columns: int = 0  # the implicit methods' Jacobians, in directional derivatives
    order: int = 0  # taylor's taylor_order; 0 for the other methods
    # seconds, objects with events only (NaN otherwise): the largest error of an event's time, and the
    # reference's estimate of its own
    event_error: float = math.nan
    reference_event_error: float = math.nan

    @property
    def evaluations(self) -> int:
        """The cost the chart and the Pareto front compare: right-hand sides plus Jacobian columns."""
        return self.rhs_evals + self.jacobian_columns


@dataclass(frozen=True)
class Task:
    """One point to compute; plain data so that it can be sent to another process or a Dask worker."""
    object: str
    method: str
    h: float
    tol: float
    fmu: str
    repeats: int
    order: int = 0  # taylor_order for taylor


def step_scale(fmu: str | Path) -> int:
    """The power of two by which an object's fixed steps are finer than the thesis pendulums', from its
    default step (0.008 s for theirs)."""
    default_h = next(float(v.start) for v in read_description(Path(fmu)).modelVariables if v.name == "h")
    return 2 ** max(0, round(math.log2(0.008 / default_h)))


def chart_methods() -> list[str]:
    """What a chart may be limited to: the FMUs' methods and the peers."""
    return [m.name for m in METHODS] + [f"scipy-{m}" for m in SCIPY_METHODS] + ["fmpy-CVode"]


def settings(objects=PENDULUMS, repeats: int = 3, fmu_dir: Path | None = None, quick: bool = False,
             methods: list[str] | None = None) -> list[Task]:
    """Every point of the chart; quick: every other step and tolerance (a chart in a few seconds); methods:
    only these (`chart_methods`)."""
    unknown = sorted(set(methods or ()) - set(chart_methods()))
    if unknown:
        raise HarnessError(f"--methods: {', '.join(unknown)} is not one of {', '.join(chart_methods())}")
    from harness.fmi.fmus import build_dir
    folder = Path(fmu_dir) if fmu_dir else build_dir() / "fmus"
    nan = math.nan
    thin = (lambda values: values[::2]) if quick else (lambda values: values)  # noqa: E731
    tasks = []
    for name in objects:
        fmu = str(folder / f"{name}.fmu")
        scale = step_scale(fmu)
        accepted = accepted_methods(fmu)
        for method in (m for m in FIXED_STEP if m in accepted):
            tasks += [Task(name, method, STEP / (k * scale), nan, fmu, repeats)
                      for k in thin(SUBSTEPS[ORDER[method]])]
        tasks += [Task(name, method, nan, tol, fmu, repeats) for method in ADAPTIVE
                  for tol in thin(ADAPTIVE_TOLERANCES)]
        if "taylor" in accepted:
            tasks += [Task(name, "taylor", STEP / scale, 0.0, fmu, repeats, order)
                      for order in thin(TAYLOR_SWEEP_ORDERS)]
        if not read_description(Path(fmu)).numberOfEventIndicators:  # scipy's peers know no impacts
            tasks += [Task(name, f"scipy-{m}", nan, tol, fmu, repeats) for m in SCIPY_METHODS
                      for tol in thin(PEER_TOLERANCES)]
        tasks += [Task(name, "fmpy-CVode", nan, tol, fmu, repeats) for tol in thin(PEER_TOLERANCES)]
    return [task for task in tasks if task.method in methods] if methods else tasks


# Reference steps per communication step: the step-halving estimate then stays below 1e-12 m.
REFERENCE_SUBSTEPS = {"SimplePendulum": 16, "DoublePendulum": 40, "SpringPendulum": 16}
REFERENCE_TARGET = 1e-12  # metres: the estimate the FMU reference of any other object aims at


@dataclass
class TracedReference:
    positions: np.ndarray  # (outputs, 2 or 3): the traced point at 0, STEP, ..., STOP
    estimated_error: float  # metres
    event_times: list[float] | None = None  # an object with events: when they happen
    estimated_event_error: float = math.nan  # seconds


def reference_for(fmu: str) -> TracedReference:
    """The tight reference of an FMU's default run."""
    name = read_description(Path(fmu)).coSimulation.modelIdentifier
    if name in OUTER_MASS:
        reference = tight_reference(Pendulum.from_fmu(fmu), STOP, STEP, REFERENCE_SUBSTEPS[name])
        return TracedReference(reference.positions, reference.estimated_error)
    with ObjectRunner(Component(name, Path(fmu)), STOP, STEP, [traced_columns(fmu)]) as runner:
        positions, estimate, h = fmu_reference(runner, runner.default_h / 8, REFERENCE_TARGET)
        settings = runner.settings(REFERENCE_METHOD, h)
        coarser = runner.settings(REFERENCE_METHOD, 2 * h)
    reference = TracedReference(positions[:, 0, :], estimate)
    fine, coarse = fmu_event_times(fmu, settings), fmu_event_times(fmu, coarser)
    if fine is not None and coarse is not None:
        reference.event_times = fine
        reference.estimated_event_error = matched_error(coarse, fine) / (2 ** REFERENCE_ORDER - 1)
    return reference


def fmu_event_times(fmu: str, start: dict) -> list[float] | None:
    """When the events of an FMU's run on the chart's grid happen, from its FMI 3.0 build (early return):
    None for an object without events or without that build, [] when the run stops early."""
    counterpart = fmi3_counterpart(fmu)
    if not read_description(Path(fmu)).numberOfEventIndicators or counterpart is None:
        return None
    with FmuInstance(counterpart, name="events", early_return=True) as instance:
        instance.initialize(0.0, **start)
        events = event_times(instance, communication_grid(0.0, STOP, STEP))
    return events.times if events.completed else []


@lru_cache(maxsize=None)  # per worker process: the derivation of a large object takes about a second
def peer_equations(fmu: str) -> Pendulum | ObjectMotion:
    """The equations the scipy peers integrate: hand-coded for the thesis pendulums, the SymPy
    derivation's for every other object; values are the FMU's start values."""
    description = read_description(Path(fmu))
    if description.coSimulation.modelIdentifier in OUTER_MASS:
        return Pendulum.from_fmu(fmu)
    return ObjectMotion(derive(object_file_in(fmu)), float_start_values(description))


def position_error(positions: np.ndarray, reference: TracedReference) -> float:
    if len(positions) != len(reference.positions):
        return math.inf
    return float(np.max(np.linalg.norm(positions - reference.positions, axis=1)))


def _median_seconds(run, repeats: int):
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def _event_error(times: list[float] | None, reference: TracedReference) -> float:
    return math.nan if times is None or reference.event_times is None else matched_error(times, reference.event_times)


def _fmu_point(task: Task, reference: TracedReference) -> Point:
    grid = communication_grid(0.0, STOP, STEP)
    start = {"solver": task.method}
    start.update({"tol": task.tol} if math.isnan(task.h) else {"h": task.h})
    if task.order:
        start.update(tol=task.tol, taylor_order=task.order)
    times = fmu_event_times(task.fmu, start) if reference.event_times is not None else None
    columns = traced_columns(task.fmu)
    with FmuInstance(task.fmu, name=task.object) as instance:
        recorder = Recorder(instance, grid, list(columns))

        def run():
            instance.reset()
            instance.initialize(0.0, **start)
            return recorder.run()
        seconds, result = _median_seconds(run, task.repeats)
        evaluations, work = int(instance.get("n_rhs")[0]), instance.work()
    error = math.inf if result.discarded_at is not None else \
        position_error(result.values[:, 1:1 + len(columns)], reference)
    return Point(task.object, task.method, task.h, task.tol, error, evaluations, seconds, reference.estimated_error,
                 work - evaluations, task.order, _event_error(times, reference), reference.estimated_event_error)


def _scipy_point(task: Task, reference: TracedReference) -> Point:
    from scipy.integrate import solve_ivp
    equations = peer_equations(task.fmu)
    grid = communication_grid(0.0, STOP, STEP)

    def run():
        return solve_ivp(equations.rhs, (0.0, STOP), equations.start, method=task.method.split("-", 1)[1],
                         t_eval=grid, rtol=task.tol, atol=task.tol)
    seconds, solution = _median_seconds(run, task.repeats)
    error = position_error(equations.traced_point(solution.y.T, solution.t), reference) if solution.success \
        else math.inf
    return Point(task.object, task.method, task.h, task.tol, error, int(solution.nfev), seconds,
                 reference.estimated_error)


def _cvode_point(task: Task, reference: TracedReference) -> Point:
    from fmpy import simulate_fmu
    from fmpy.model_description import read_model_description
    from harness.archives import extract_fmu, remove_folder
    description = read_model_description(task.fmu)  # read once: simulate_fmu would parse it every run
    columns = traced_columns(task.fmu)
    description_names = {v.name for v in description.modelVariables}
    unzipped = str(extract_fmu(Path(task.fmu)))  # once per point, not per repeat

    def run():
        return simulate_fmu(unzipped, model_description=description, fmi_type="ModelExchange", solver="CVode",
                            relative_tolerance=task.tol, output_interval=STEP, stop_time=STOP,
                            output=[*columns, "n_rhs", *(["n_events"] if "n_events" in description_names else [])])
    try:
        seconds, result = _median_seconds(run, task.repeats)
    finally:
        remove_folder(unzipped)
    # fmpy records the rows before and after each event: an event is where n_events changes
    changed = np.flatnonzero(np.diff(result["n_events"])) + 1 if "n_events" in result.dtype.names else []
    times = sorted({float(result["time"][k]) for k in changed})
    result = result[rows_on_grid(result["time"], communication_grid(0.0, STOP, STEP))]  # not the events' rows
    positions = np.column_stack([result[n] for n in columns])
    return Point(task.object, task.method, task.h, task.tol, position_error(positions, reference),
                 int(result["n_rhs"][-1]), seconds, reference.estimated_error,
                 event_error=_event_error(times, reference), reference_event_error=reference.estimated_event_error)


def compute(job: tuple[Task, TracedReference]) -> Point:
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


def pareto_front(points: list[Point], cost: str = "evaluations", measure: str = "error") -> list[Point]:
    """The points no other point beats in both cost and error (`measure`: error or event_error), cheapest
    first."""
    finite = sorted((p for p in points if math.isfinite(getattr(p, measure))),
                    key=lambda p: (getattr(p, cost), getattr(p, measure)))
    front, best = [], math.inf
    for p in finite:
        if getattr(p, measure) < best:
            front.append(p)
            best = getattr(p, measure)
    return front


def write_csv(points: list[Point], path: Path) -> None:
    write_records(points, path, columns_of(Point))


def read_csv(path: Path) -> list[Point]:
    return read_records(path, Point)
