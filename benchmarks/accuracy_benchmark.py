#!/usr/bin/env python3
"""Time to a given accuracy: SimplePendulum from its default start (0.5 rad) over 10 s, largest
position error of the bob at most 1e-6 m at every output point against the exact elliptic solution.

Three contenders, each at its cheapest setting that reaches the target (searched first, then timed
side by side, interleaved, median of repeats):
  * the FMU through fmpy: the cheapest method and internal step (fewest right-hand-side
    evaluations), stepped by the harness's loop on fmpy's loaded library, and by fmpy's own
    FMU2Slave list API (doStep + getReal per output point);
  * scipy's solve_ivp DOP853 on a Python right-hand side (harness.objects.thesis.equations), loosest rtol = atol;
  * fmpy's simulate_fmu, Model Exchange with CVode, loosest relative tolerance.

The output interval decides how much of the cost is per-call overhead, so the benchmark runs four:
0.01 s (1001 points), 0.1 s, 1 s and 10 s (the end point only).

Then the harness's own cost per output point: the recorder's run (its native loop, many points per
call) against the bare C loop it calls (record_rows over all points in one call, nothing around it),
and against the recorder's Python loop, side by side.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from fmpy import extract, read_model_description, simulate_fmu  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

from harness.fmi.fmu_instance import FmuInstance  # noqa: E402
from harness.fmi.fmus import build_dir, build_fmus  # noqa: E402
from harness.fmi.methods import SOLVERS  # noqa: E402
from harness.fmi.native_calls import RecordUnit  # noqa: E402
from harness.fmi.simulation import Recorder, communication_grid  # noqa: E402
from harness.objects.thesis.equations import Pendulum  # noqa: E402
from harness.objects.thesis.reference import exact_simple_pendulum  # noqa: E402

TARGET, STOP = 1e-6, 10.0
FIXED_METHODS = ("rk4", "nystrom5", "ab4", "ab5", "ab6")
METHOD_CODES = {name: SOLVERS.index(name) + 1 for name in FIXED_METHODS}


# extracted FMUs: removed with this folder when the benchmark exits
SCRATCH = tempfile.TemporaryDirectory(prefix="benchmark_")

def exact_positions(grid: np.ndarray) -> np.ndarray:
    phi, _ = exact_simple_pendulum(0.5, grid)
    return np.column_stack([np.sin(phi), -np.cos(phi)])


def error(positions: np.ndarray, exact: np.ndarray) -> float:
    return float(np.max(np.hypot(*(np.asarray(positions) - exact).T)))


def loosest_tolerance(run, exact: np.ndarray) -> float | None:
    """The loosest tolerance 10^(-k/4) whose result reaches the target (None: none does)."""
    for k in range(16, 56):
        tol = 10.0 ** (-k / 4)
        try:
            if error(run(tol), exact) <= TARGET:
                return tol
        except RuntimeError:  # CVode gives up (too many steps per output interval) at tight tolerances
            continue
    return None


class FmuRunner:
    def __init__(self, fmu: Path, grid: np.ndarray):
        self.instance = FmuInstance(fmu, name="bench")
        self.recorder = Recorder(self.instance, grid, ["x", "y"])  # prepared once, like scipy's compiled tables

    def run(self, method: str, h: float) -> np.ndarray:
        instance = self.instance
        instance.call("fmi2Reset")
        instance.initialize(0.0, solver=method, h=h)
        return self.recorder.run().values[:, 1:3]

    def evaluations(self, method: str, h: float) -> int:
        self.run(method, h)
        return int(self.instance.get("n_rhs")[0])

    def cheapest(self, exact: np.ndarray, output_step: float) -> tuple[str, float, int]:
        best = None
        for method in FIXED_METHODS:
            for substeps in (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 25, 32, 40, 50, 64, 80, 100, 128, 200, 256,
                             400, 500, 800, 1000, 2000, 4000):
                h = output_step / substeps
                if h > 0.05:
                    continue
                positions = self.run(method, h)
                if error(positions, exact) <= TARGET:
                    evaluations = self.evaluations(method, h)
                    if best is None or evaluations < best[2]:
                        best = (method, h, evaluations)
                    break
        return best


def fmpy_list_api(fmu: Path, grid: np.ndarray, method: str, h: float):
    """What an fmpy user writes: FMU2Slave with lists, one doStep and getReal per output point."""
    description = read_model_description(str(fmu))
    refs = {v.name: v.valueReference for v in description.modelVariables}
    unzipped = extract(str(fmu), unzipdir=tempfile.mkdtemp(dir=SCRATCH.name))
    slave = FMU2Slave(guid=description.guid, unzipDirectory=unzipped, modelIdentifier="SimplePendulum",
                      instanceName="list-api")
    slave.instantiate()
    xy = [refs["x"], refs["y"]]

    def run():
        slave.reset()
        slave.setupExperiment(startTime=0.0)
        slave.setInteger([refs["solver"]], [METHOD_CODES[method]])
        slave.setReal([refs["h"]], [h])
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        rows = [slave.getReal(xy)]
        for t, t_next in zip(grid[:-1], grid[1:]):
            slave.doStep(t, t_next - t)
            rows.append(slave.getReal(xy))
        return np.array(rows)
    return run


def interleaved_medians(runs: dict, repeats: int) -> dict[str, float]:
    times = {name: [] for name in runs}
    for _ in range(repeats):
        for name, run in runs.items():
            start = time.perf_counter()
            run()
            times[name].append(time.perf_counter() - start)
    return {name: statistics.median(values) for name, values in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=21)
    args = parser.parse_args()
    build_fmus()
    fmu = build_dir() / "fmus" / "SimplePendulum.fmu"
    pendulum = Pendulum.from_fmu(fmu)
    unzipped = extract(str(fmu), unzipdir=tempfile.mkdtemp(dir=SCRATCH.name))
    description = read_model_description(str(fmu))
    print(f"SimplePendulum, 10 s, target: largest bob position error <= {TARGET:g} m at every output point")
    print(f"{'output step':>11} | {'FMU method, h':>20} {'evals':>6} | {'DOP853 rtol':>11} {'evals':>6} | "
          f"{'CVode rtol':>10} {'evals':>6} | scipy/FMU  CVode/FMU  fmpy-list/FMU")
    for output_step in (0.01, 0.1, 1.0, 10.0):
        grid = communication_grid(0.0, STOP, output_step)
        exact = exact_positions(grid)
        runner = FmuRunner(fmu, grid)
        method, h, fmu_evals = runner.cheapest(exact, output_step)

        def scipy_run(tol):
            return solve_ivp(pendulum.rhs, (0.0, STOP), pendulum.start, method="DOP853", t_eval=grid, rtol=tol,
                             atol=tol)
        scipy_tol = loosest_tolerance(lambda tol: pendulum.outer_mass(scipy_run(tol).y.T), exact)
        scipy_evals = scipy_run(scipy_tol).nfev

        def cvode_run(tol):
            return simulate_fmu(unzipped, model_description=description, fmi_type="ModelExchange", solver="CVode",
                                relative_tolerance=tol, output_interval=output_step, stop_time=STOP,
                                output=["x", "y", "n_rhs"])
        cvode_tol = loosest_tolerance(lambda tol: np.column_stack([(r := cvode_run(tol))["x"], r["y"]]), exact)
        list_api = fmpy_list_api(fmu, grid, method, h)
        assert error(list_api(), exact) <= TARGET
        runs = {"fmu": lambda: runner.run(method, h), "scipy": lambda: scipy_run(scipy_tol), "list": list_api}
        if cvode_tol is not None:
            runs["cvode"] = lambda: cvode_run(cvode_tol)
        medians = interleaved_medians(runs, args.repeats)
        runner.instance.free()
        if cvode_tol is None:  # fmpy's CVode stops after its default 500 steps per output interval
            cvode = f"{'fails':>10} {'':>6}"
            cvode_ratio = "n/a"
        else:
            cvode = f"{cvode_tol:>10.2g} {int(cvode_run(cvode_tol)['n_rhs'][-1]):>6}"
            cvode_ratio = f"{medians['cvode'] / medians['fmu']:.1f}"
        print(f"{output_step:>11g} | {method + ', ' + format(h, '.4g'):>20} {fmu_evals:>6} | {scipy_tol:>11.2g} "
              f"{scipy_evals:>6} | {cvode} | {medians['scipy'] / medians['fmu']:>9.1f}  {cvode_ratio:>9}  "
              f"{medians['list'] / medians['fmu']:>13.2f}")
    print("ratios: median time of the contender / median time of the FMU run through the harness loop "
          f"({args.repeats} interleaved repeats)")
    harness_cost(fmu, args.repeats)


def harness_cost(fmu: Path, repeats: int) -> None:
    """Per output point: the recorder (native loop) minus the bare C loop, and the Python loop."""
    grid = communication_grid(0.0, STOP, 0.01)
    points = len(grid)
    native_instance, python_instance = FmuInstance(fmu, name="native"), FmuInstance(fmu, name="python")
    native = Recorder(native_instance, grid, ["x", "y"])
    python = Recorder(python_instance, grid, ["x", "y"], native=False)
    unit = native._keep
    record_rows = native.rows

    def start(instance):
        instance.reset()
        instance.initialize(0.0, solver="ab6", h=0.01)

    def timed(instance, run) -> float:
        start(instance)  # not timed: the same for all three
        began = time.perf_counter()
        run()
        return time.perf_counter() - began
    times = {"recorder": [], "bare": [], "python": []}
    for _ in range(repeats):
        times["recorder"].append(timed(native_instance, native.run))
        times["bare"].append(timed(native_instance, lambda: record_rows(0, points)))
        times["python"].append(timed(python_instance, python.run))
    median = {k: statistics.median(v) for k, v in times.items()}
    assert isinstance(unit, RecordUnit)
    print(f"\nper output point ({points} points, ab6 at h = 0.01, medians of {repeats} interleaved runs): "
          f"bare C loop {1e6 * median['bare'] / points:.3f} us, recorder {1e6 * median['recorder'] / points:.3f} us "
          f"(harness cost {1e6 * (median['recorder'] - median['bare']) / points:+.3f} us), Python loop "
          f"{1e6 * median['python'] / points:.3f} us ({median['python'] / median['recorder']:.1f} x the recorder)")
    native_instance.free()
    python_instance.free()


if __name__ == "__main__":
    main()
