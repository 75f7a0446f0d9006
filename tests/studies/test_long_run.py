"""Long runs at equal cost per period: the symmetric methods' energy error stays bounded, the others'
grows (fitted slopes of the log-log curves), for the three cases of `chart long-run`."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from harness.fmi.fmus import PROJECT_ROOT, build_dir
from harness.fmi.methods import SYMMETRIC
from harness.studies.long_run import CASES, COST_PER_PERIOD, fitted_slope, long_run, read_csv, tasks_for

GROWING = ("rk4", "nystrom5", "ab4", "ab5", "rkf45")


@pytest.fixture(scope="module")
def series(fmu_paths):
    tasks = tasks_for(build_dir() / "fmus", periods=2000, methods=(*SYMMETRIC, *GROWING))
    return {(s.object, s.method): s for s in long_run(tasks, workers=2)}


def test_fitted_slope_of_known_curves():
    t = np.linspace(0.0, 5000.0, 80001)
    assert fitted_slope(t, 3e-7 * t) == pytest.approx(1.0, abs=0.01)  # sampled on the grid
    assert fitted_slope(t, 1e-9 * t ** 2) == pytest.approx(2.0, abs=0.01)
    assert abs(fitted_slope(t, np.full_like(t, 4e-5))) < 1e-9
    assert fitted_slope(t, np.zeros_like(t)) == 0.0


@pytest.mark.parametrize("case", CASES, ids=[c.object for c in CASES])
def test_symmetric_methods_keep_the_energy_error_bounded(series, case):
    mine = {m: s for (o, m), s in series.items() if o == case.object}
    symmetric = [m for m in SYMMETRIC if m in mine]
    assert symmetric and (case.object == "SimplePendulum") == ("stormer_verlet" in symmetric)
    for method in symmetric:
        s = mine[method]
        assert s.periods == pytest.approx(2000, rel=1e-6), f"{method} stopped at {s.periods} periods"
        assert abs(s.slope) < 0.1, f"{case.object} {method}: slope {s.slope:.2f}"
        assert s.final_error < 0.05
    for method in GROWING:
        assert mine[method].slope > 0.7, f"{case.object} {method}: slope {mine[method].slope:.2f}, expected growth"


def test_every_method_runs_at_about_the_same_cost(series):
    """Equal cost per period: evaluations plus one per state for each Jacobian, within the rounding of
    steps per period (and rkf45's interpolated tolerance)."""
    for (name, method), s in series.items():
        allowed = 0.3 if method == "rkf45" else 0.1
        assert abs(s.cost_per_period / COST_PER_PERIOD - 1) < allowed, (name, method, s.cost_per_period)


def test_an_object_without_a_long_run_case_is_a_one_line_error(fmu_paths, tmp_path):
    result = subprocess.run([sys.executable, "-m", "harness", "chart", "long-run", "--objects", "CartPendulum",
                             "--out", str(tmp_path)], capture_output=True, text=True, cwd=PROJECT_ROOT)
    assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
    assert ("long-run has cases for SimplePendulum, SpringPendulum, DoublePendulum, not for CartPendulum"
            in result.stderr)
    assert not (tmp_path / "long-run.csv").exists()


def test_chart_long_run_writes_its_chart_and_csv(fmu_paths, tmp_path):
    result = subprocess.run([sys.executable, "-m", "harness", "chart", "long-run", "--quick", "--objects",
                             "SimplePendulum", "--out", str(tmp_path), "--workers", "1"],
                            capture_output=True, text=True, cwd=PROJECT_ROOT)
    assert result.returncode == 0, result.stderr
    assert "SimplePendulum (simple pendulum, 2.5 rad swing): fitted energy-error slope" in result.stdout
    rows = read_csv(tmp_path / "long-run.csv")
    assert {r.method for r in rows} >= {"rk4", "stormer_verlet", "gauss_legendre4"}
    assert max(r.periods for r in rows if r.method == "stormer_verlet") == pytest.approx(1000, rel=1e-6)
    assert (tmp_path / "long-run.png").stat().st_size > 10_000 and (tmp_path / "long-run.svg").is_file()
