"""Long runs: the energy error of every method over thousands of periods, at equal cost per period.

Over a long run what shows is whether the energy drifts, and that depends on whether the method is
symmetric, not on its order. Each case is an object in regular (periodic or quasi-periodic) motion
without damping or force, so that its exact energy is constant. Each method runs at the cost per
period of COST_PER_PERIOD evaluations, counted as right-hand-side evaluations plus, for the implicit
methods, one per state for each Jacobian (`FmuInstance.work`: each Jacobian column is one directional
derivative, which costs about one right-hand side); the step (or rkf45's tolerance) is found by a short calibration
run of the same layout. The energy error is |E(t) - E(0)| over the largest kinetic energy of the
first periods (the swing's energy), its running maximum recorded at about 16 points per period;
`slope` is the least-squares slope of its logarithm against the logarithm of time from 10 periods
on: about 0 for bounded error, 1 for a linear drift.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from harness.fmi.fmu_instance import FmuInstance, accepted_methods
from harness.fmi.simulation import Recorder, communication_grid
from harness.objects.thesis.reference import slope
from harness.studies.records import columns_of, read_records, write_records
from harness.studies.sweep import run_sweep

COST_PER_PERIOD = 256
PERIODS = 10_000
POINTS_PER_PERIOD = 16
CALIBRATION_PERIODS = 20
FIT_FROM = 10  # periods: the slope is fitted from here to the end
SAMPLES = 60   # log-spaced samples of each curve kept for the chart and the CSV


@dataclass(frozen=True)
class LongRunCase:
    object: str
    start: dict
    description: str
    velocity: str  # a velocity whose downward zero crossings mark the periods

    @property
    def start_items(self) -> tuple:
        return tuple(sorted(self.start.items()))


CASES = (
    LongRunCase("SimplePendulum", {"phi": 2.5}, "simple pendulum, 2.5 rad swing", "omega"),
    LongRunCase("SpringPendulum", {"phi": 0.3, "eps": 9.81 / 15 + 0.05}, "spring pendulum, 0.3 rad, 5 cm beyond rest",
                "omega"),
    LongRunCase("DoublePendulum", {"phi1": 0.1, "phi2": 0.1}, "double pendulum, 0.1 rad (regular)", "omega1"),
)


@dataclass(frozen=True)
class Task:
    case: LongRunCase
    fmu: str
    method: str
    period: float
    swing_energy: float
    periods: int
    cost_per_period: float


@dataclass
class Series:
    object: str
    method: str
    h: float                  # internal step (NaN for rkf45)
    tol: float                # rkf45's tolerance (NaN otherwise)
    cost_per_period: float    # measured over the whole run
    periods: float            # reached (fewer when a step was discarded)
    final_error: float        # relative energy error at the end
    slope: float              # fitted d log(error) / d log(t)
    times: list[float] = field(default_factory=list)   # in periods
    errors: list[float] = field(default_factory=list)  # running maximum of the relative energy error


@dataclass
class SeriesRow:
    """Series as CSV rows: one per sample."""
    object: str
    method: str
    h: float
    tol: float
    cost_per_period: float
    slope: float
    periods: float
    energy_error: float


def period_of(case: LongRunCase, fmu: str) -> tuple[float, float]:
    """The case's period (mean spacing of the velocity's downward zero crossings over 30 s of a fine
    run) and its swing energy (largest kinetic energy over that time)."""
    with FmuInstance(fmu, name="period") as instance:
        grid = communication_grid(0.0, 30.0, 0.001)
        recorder = Recorder(instance, grid, [case.velocity, "E_kin"])
        instance.initialize(0.0, solver="gauss_legendre4", h=0.001, **case.start)
        values = recorder.run().values
    velocity = values[:, 1]
    crossings = np.flatnonzero((velocity[:-1] > 0) & (velocity[1:] <= 0))
    if len(crossings) < 2:
        raise ValueError(f"{case.object}: no period within 30 s from {case.start}")
    return float(np.mean(np.diff(grid[crossings]))), float(values[:, 2].max())


class _Runner:
    def __init__(self, task: Task):
        self.task = task
        self.instance = FmuInstance(task.fmu, name=task.case.object)

    def run(self, setting: dict, periods: float, steps_per_output: int | None):
        """Runs `periods` periods; outputs every steps_per_output internal steps (rkf45: 16 per period)."""
        task = self.task
        step = setting["h"] * steps_per_output if steps_per_output else task.period / POINTS_PER_PERIOD
        self.instance.reset()
        self.instance.initialize(0.0, solver=task.method, **setting, **task.case.start)
        result = Recorder(self.instance, communication_grid(0.0, periods * task.period, step), ["E"]).run()
        reached = result.values[-1, 0] / task.period
        return result, self.instance.work() / max(reached, 1e-300)


def _layout(period: float, steps_per_period: float) -> tuple[dict, int]:
    n = max(1, round(steps_per_period))
    return {"h": period / n}, max(1, round(n / POINTS_PER_PERIOD))


def _calibrated(runner: _Runner) -> tuple[dict, int | None]:
    """The setting whose cost per period is closest to the task's, found on short runs."""
    task = runner.task
    if task.method == "rkf45":
        tolerances = 10.0 ** -np.arange(2.0, 13.0)
        costs = [runner.run({"tol": tol}, CALIBRATION_PERIODS, None)[1] for tol in tolerances]
        tol = 10 ** float(np.interp(math.log10(task.cost_per_period), np.log10(costs), np.log10(tolerances)))
        return {"tol": tol}, None
    # The implicit methods' cost per step grows with the step (more Newton iterations), and too long a
    # step does not converge at all: a few rounds, keeping the last step that ran.
    steps, good = task.cost_per_period / 4, None
    for _ in range(5):
        setting, every = _layout(task.period, steps)
        result, cost = runner.run(setting, CALIBRATION_PERIODS, every)
        if result.discarded_at is not None:
            steps *= 2
            continue
        good = steps
        steps *= task.cost_per_period / cost
    return _layout(task.period, good if good is not None else steps)


def energy_curve(result, task: Task) -> tuple[np.ndarray, np.ndarray]:
    times = result.values[:, 0] / task.period
    energy = result.values[:, 1]
    return times, np.maximum.accumulate(np.abs(energy - energy[0])) / task.swing_energy


def fitted_slope(times: np.ndarray, errors: np.ndarray, start: float = FIT_FROM) -> float:
    """Least-squares slope of log(error) against log(t) over log-spaced samples from `start` on."""
    if times[-1] <= start * 2:
        return math.nan
    samples = np.geomspace(start, times[-1], 40)
    values = errors[np.searchsorted(times, samples).clip(0, len(times) - 1)]
    keep = values > 0
    if keep.sum() < 3:
        return 0.0  # exactly conserved: no growth
    return slope(samples[keep], values[keep])


def compute(task: Task) -> Series:
    runner = _Runner(task)
    try:
        setting, every = _calibrated(runner)
        result, cost = runner.run(setting, task.periods, every)
    finally:
        runner.instance.free()
    times, errors = energy_curve(result, task)
    if times[-1] > 0:
        samples = np.unique(np.searchsorted(times, np.geomspace(min(1.0, times[-1]), times[-1], SAMPLES))
                            .clip(0, len(times) - 1))
    else:  # the first step was discarded
        samples = np.array([0])
    return Series(task.case.object, task.method, setting.get("h", math.nan), setting.get("tol", math.nan), cost,
                  float(times[-1]), float(errors[-1]), fitted_slope(times, errors), times[samples].tolist(),
                  errors[samples].tolist())


def tasks_for(fmu_dir: Path, cases=CASES, periods: int = PERIODS, methods: tuple[str, ...] | None = None,
              cost_per_period: float = COST_PER_PERIOD) -> list[Task]:
    tasks = []
    for case in cases:
        fmu = str(Path(fmu_dir) / f"{case.object}.fmu")
        period, swing = period_of(case, fmu)
        tasks += [Task(case, fmu, method, period, swing, periods, cost_per_period)
                  for method in accepted_methods(fmu) if methods is None or method in methods]
    return tasks


def long_run(tasks: list[Task], scheduler: str | None = None, workers: int | None = None) -> list[Series]:
    return run_sweep(compute, tasks, scheduler, workers)


def write_csv(series: list[Series], path: Path) -> None:
    rows = [SeriesRow(s.object, s.method, s.h, s.tol, s.cost_per_period, s.slope, t, e)
            for s in series for t, e in zip(s.times, s.errors)]
    write_records(rows, path, columns_of(SeriesRow))


def read_csv(path: Path) -> list[SeriesRow]:
    return read_records(path, SeriesRow)


def series_from_rows(rows: list[SeriesRow]) -> list[Series]:
    """The series a CSV holds, for drawing the chart again without running them."""
    grouped: dict[tuple[str, str], list[SeriesRow]] = {}
    for row in rows:
        grouped.setdefault((row.object, row.method), []).append(row)
    return [Series(first.object, first.method, first.h, first.tol, first.cost_per_period, mine[-1].periods,
                   mine[-1].energy_error, first.slope, [r.periods for r in mine], [r.energy_error for r in mine])
            for mine in grouped.values() for first in [mine[0]]]
