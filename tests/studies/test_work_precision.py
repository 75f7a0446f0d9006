"""What the work-precision chart claims: the slopes are the methods' orders, the references are
tight, the peers' errors are measured exactly as ours, the Pareto front is the front, and the sweep
gives the same numbers in a process pool, in one process and on a Dask cluster."""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from harness.cli import main
from harness.fmi.methods import ADAPTIVE, IMPLICIT
from harness.objects.thesis.equations import OUTER_MASS, STATES, Pendulum
from harness.objects.thesis.lagrange import derived_model
from harness.objects.thesis.reference import exact_simple_pendulum, slope, tight_reference
from harness.studies.work_precision import (FIXED_STEP, ORDER, PENDULUMS, REFERENCE_SUBSTEPS, Point, pareto_front,
                                            read_csv, reference_for, settings, work_precision)

ASYMPTOTIC = (3e-13, 2e-2)  # metres: above the rounding floor, below the pre-asymptotic (chaotic) range
# The chaotic double pendulum amplifies the FMUs' rounding: ab6, abm5, abm6 and nystrom5 all end at
# 3e-10 to 5e-10 m with h = 0.01/64, so its floor is higher.
ROUNDING_FLOOR = {"DoublePendulum": 1e-9}


@pytest.fixture(scope="module")
def sweep(fmu_paths, tmp_path_factory):
    out = tmp_path_factory.mktemp("work-precision")
    assert main(["chart", "work-precision", "--out", str(out), "--repeats", "1"]) == 0
    return out, read_csv(out / "work-precision.csv")


def test_the_files_and_the_columns(sweep):
    out, points = sweep
    with open(out / "work-precision.csv") as handle:
        assert next(csv.reader(handle)) == ["object", "method", "h", "tol", "error", "rhs_evals", "seconds",
                                         "reference_error", "jacobian_columns", "order", "event_error",
                                         "reference_event_error"]
    for suffix in ("png", "svg"):
        assert (out / f"work-precision.{suffix}").stat().st_size > 10_000
    # no events, no event charts
    assert all(math.isnan(p.event_error) for p in points) and not (out / "work-precision-events.png").exists()
    for name in PENDULUMS:
        for method in [*FIXED_STEP, *ADAPTIVE, "taylor", "scipy-RK45", "scipy-DOP853", "scipy-LSODA", "fmpy-CVode"]:
            mine = [p for p in points if p.object == name and p.method == method]
            if method == "stormer_verlet" and name != "SimplePendulum":  # its mass matrix varies
                assert not mine
                continue
            assert len(mine) >= 4, (name, method)
            assert all(p.rhs_evals > 0 and p.seconds > 0 and p.error > 0 for p in mine)
            assert all(math.isfinite(p.h) == (method in FIXED_STEP or method == "taylor") for p in mine)
            assert all((p.jacobian_columns > 0) == (method in IMPLICIT) for p in mine)


@pytest.mark.parametrize("name", PENDULUMS)
@pytest.mark.parametrize("method", FIXED_STEP)
def test_slopes_are_the_orders(sweep, name, method):
    """log(error) against log(evaluations) falls with the method's order: fitted through the three
    finest settings whose errors lie in the asymptotic range."""
    if name == "DoublePendulum" and method == "euler":
        pytest.skip("euler reaches the asymptotic range of the chaotic double pendulum only after ~1e9 evaluations")
    if method == "stormer_verlet" and name != "SimplePendulum":
        pytest.skip("stormer_verlet needs a constant mass matrix: the simple pendulum's only")
    if name == "DoublePendulum" and method == "abm6":
        pytest.skip("abm6 reaches the asymptotic range of the chaotic double pendulum only where its rounding, "
                    "amplified by the chaos, takes over (1e-9 m at h = 0.01/16, 1.5e-10 at 0.01/32)")
    floor = ROUNDING_FLOOR.get(name, ASYMPTOTIC[0])
    assert_slope_is_the_order(sweep[1], name, method, lambda p: floor <= p.error <= ASYMPTOTIC[1], 3, 0.3)


# Below this error a setting whose refinement stopped paying is taken to be at its rounding floor: over 10 s
# with 1e5 to 1e7 steps the runs' accumulated rounding is 1e-14 to 1e-12 m, and a stall above that is a fault.
ROUNDING_CEILING = 1e-11


def past_rounding(every: list[Point], method: str, cost, measure: str) -> list[Point]:
    """The settings of `every` (ordered by cost) from the first that lies at the rounding floor on: its error is
    below ROUNDING_CEILING and fell from the next coarser setting's by less than a quarter of what the order
    predicts from the cost ratio (a 4 times finer step of an order-5 method: 1024 predicted, under 256 is a stall).
    Where the rounding takes over depends on the arithmetic's last bits, not on the method's order."""
    for i in range(1, len(every)):
        coarse, fine = getattr(every[i - 1], measure), getattr(every[i], measure)
        predicted = (cost(every[i]) / cost(every[i - 1])) ** ORDER[method]
        if fine < ROUNDING_CEILING and coarse / fine < predicted / 4:
            return every[i:]
    return []


def assert_slope_is_the_order(points: list[Point], name: str, method: str, asymptotic, least: int,
                              tolerance: float, measure: str = "error") -> None:
    """Through the three finest settings that `asymptotic` accepts and that are not past the rounding floor
    (`past_rounding`), at least `least` of them, or two where the next finer setting is already below the range:
    a high order reaches rounding within a halving or two. The fitted slope of log(error) against
    log(evaluations) is minus the method's order. For the implicit methods against log(steps) instead: their
    evaluations per step fall as the step shrinks (fewer Newton iterations), so that their evaluations are not
    proportional to the steps. `measure`: the position error or the events' time error."""
    cost = (lambda p: 1 / p.h) if method in IMPLICIT else (lambda p: p.rhs_evals)  # noqa: E731
    every = sorted((p for p in points if p.object == name and p.method == method), key=cost)
    rounded = past_rounding(every, method, cost, measure)
    resolved = every[:len(every) - len(rounded)]
    mine = [p for p in resolved if asymptotic(p)][-3:]
    at_rounding = bool(mine) and (bool(rounded) or any(
        cost(p) > cost(mine[-1]) and not asymptotic(p) and getattr(p, measure) < getattr(mine[-1], measure)
        for p in resolved))
    assert len(mine) >= (min(least, 2) if at_rounding else least), [getattr(p, measure) for p in every]
    measured = -slope([cost(p) for p in mine], [getattr(p, measure) for p in mine])
    assert abs(measured - ORDER[method]) < tolerance, measured


def assert_tolerances_buy_accuracy(points: list[Point], name: str) -> None:
    """rkf45, gbs and each peer: the tightest tolerance is at least 100 times more accurate than the loosest."""
    for method in (*ADAPTIVE, "scipy-RK45", "scipy-DOP853", "scipy-LSODA", "fmpy-CVode"):
        mine = sorted((p for p in points if p.object == name and p.method == method), key=lambda p: p.tol)
        assert mine[0].error * 100 < mine[-1].error, (method, [p.error for p in mine])


@pytest.mark.parametrize("name", PENDULUMS)
def test_tighter_tolerances_buy_accuracy(sweep, name):
    assert_tolerances_buy_accuracy(sweep[1], name)
    assert_taylor_orders_buy_accuracy(sweep[1], name)


def assert_taylor_orders_buy_accuracy(points: list[Point], name: str) -> None:
    """taylor at h = 0.01 s: 1000 steps of p (p + 1) / 2 evaluations each over the 10 s, and until its error
    reaches the reference's, each order is more accurate than the one below, and order 2p at least 2^p
    times more accurate than order p (an error of order (h / R)^p with h at most half the radius of
    convergence R of the motion's series; the chaotic double pendulum measures about 4 per order)."""
    mine = sorted((p for p in points if p.object == name and p.method == "taylor"), key=lambda p: p.order)
    assert [p.rhs_evals for p in mine] == [1000 * p.order * (p.order + 1) // 2 for p in mine]
    floor = 100 * max(p.reference_error for p in mine)
    resolved = [p for p in mine if p.error > floor]
    assert all(high.error < low.error for low, high in zip(resolved, resolved[1:])), [p.error for p in mine]
    by_order = {p.order: p.error for p in resolved}
    for low in by_order:  # in the asymptotic range: the chaotic double pendulum's order 2 is not
        if 2 * low in by_order and by_order[low] < ASYMPTOTIC[1]:
            assert by_order[2 * low] * 2 ** low <= by_order[low], (low, by_order)


def test_the_pareto_front(sweep):
    for name in PENDULUMS:
        mine = [p for p in sweep[1] if p.object == name]
        front = pareto_front(mine)
        assert len(front) >= 3
        for p in front:  # nothing is both cheaper (or equal) and more accurate
            assert not any(q.rhs_evals <= p.rhs_evals and q.error < p.error for q in mine)
        for q in mine:  # everything else is beaten by a front point
            if q not in front and math.isfinite(q.error):
                assert any(p.rhs_evals <= q.rhs_evals and p.error <= q.error for p in front)


def test_scipy_errors_are_measured_like_ours(sweep, fmu_paths):
    """An independent recomputation of the DOP853 point at tol 1e-8: the right-hand side and the tip
    position from the SymPy derivation, the reference from the exact solution."""
    names, function, positions, q, qd = derived_model("SimplePendulum")
    pendulum = Pendulum.from_fmu(fmu_paths["SimplePendulum"])
    values = dict(pendulum.parameters, F_x=0.0, F_y=0.0)

    def evaluate(phi: float, omega: float) -> list[float]:
        return function(*[{"phi": phi, "omega": omega}.get(n, values.get(n)) for n in names])

    t = np.linspace(0, 10, 1001)
    solution = solve_ivp(lambda _, y: [y[1], evaluate(*y)[0]], (0, 10), pendulum.start, method="DOP853", t_eval=t,
                         rtol=1e-8, atol=1e-8)
    ours = [evaluate(*y)[-2:] for y in solution.y.T]
    phi, _ = exact_simple_pendulum(pendulum.start[0], t)
    exact = np.column_stack([np.sin(phi), -np.cos(phi)])
    error = np.max(np.hypot(*(np.array(ours) - exact).T))
    listed = next(p for p in sweep[1] if p.object == "SimplePendulum" and p.method == "scipy-DOP853" and p.tol == 1e-8)
    assert listed.error == pytest.approx(error, rel=1e-6)


def test_cvode_errors_are_measured_like_ours(sweep, fmu_paths):
    """fmpy's own simulate_fmu at the listed tolerance, positions read from the FMU's outputs."""
    from fmpy import simulate_fmu
    result = simulate_fmu(str(fmu_paths["SimplePendulum"]), fmi_type="ModelExchange", solver="CVode",
                          relative_tolerance=1e-8, output_interval=0.01, stop_time=10.0, output=["x", "y", "n_rhs"])
    phi, _ = exact_simple_pendulum(0.5, result["time"])
    error = np.max(np.hypot(result["x"] - np.sin(phi), result["y"] + np.cos(phi)))
    listed = next(p for p in sweep[1] if p.object == "SimplePendulum" and p.method == "fmpy-CVode" and p.tol == 1e-8)
    assert listed.error == pytest.approx(error, rel=1e-9)
    assert listed.rhs_evals == result["n_rhs"][-1] > 1000  # one evaluation at least per output point


@pytest.mark.parametrize("name", PENDULUMS)
def test_outer_mass_is_what_the_fmu_reports(open_fmu, name):
    """The peers' positions come from Pendulum.outer_mass, ours from the FMU's outputs: the same numbers."""
    instance = open_fmu(name)
    instance.initialize()
    pendulum = Pendulum.from_fmu(instance.path)
    for step in range(50):
        assert instance.do_step(step * 0.02, 0.02) == 0
        states = np.array([instance.get(*STATES[name])])
        assert np.allclose(pendulum.outer_mass(states)[0], instance.get(*OUTER_MASS[name]), rtol=0, atol=1e-14)


def test_the_long_double_reference_against_the_exact_solution(fmu_paths):
    pendulum = Pendulum.from_fmu(fmu_paths["SimplePendulum"], {"phi": 2.5})
    numeric = tight_reference(pendulum, 10.0, 0.01, REFERENCE_SUBSTEPS["SimplePendulum"], exact=False)
    exact = tight_reference(pendulum, 10.0, 0.01)
    assert np.max(np.hypot(*(numeric.positions - exact.positions).T)) < 1e-13
    assert numeric.estimated_error < 1e-12


@pytest.mark.parametrize("name", ["DoublePendulum", "SpringPendulum"])
def test_the_references_are_tight(fmu_paths, name):
    """The step-halving estimate of the long-double run; and DOP853 at rtol 1e-13 (a different method
    in double precision) agrees to 1e-7 m over the chaotic 10 s."""
    pendulum = Pendulum.from_fmu(fmu_paths[name])
    reference = reference_for(str(fmu_paths[name]))
    assert reference.estimated_error < 1e-12
    t = np.linspace(0, 10, 1001)
    solution = solve_ivp(pendulum.rhs, (0, 10), pendulum.start, method="DOP853", t_eval=t, rtol=1e-13, atol=1e-13)
    assert np.max(np.hypot(*(pendulum.outer_mass(solution.y.T) - reference.positions).T)) < 1e-7


def _comparable(points: list[Point]) -> list[tuple]:
    return [(p.object, p.method, repr(p.h), repr(p.tol), p.error, p.rhs_evals) for p in points]


def test_dask_gives_the_numbers_of_the_process_pool(fmu_paths):
    distributed = pytest.importorskip("distributed")
    tasks = [t for t in settings(["SimplePendulum"], repeats=1) if t.method in ("rk4", "ab3", "scipy-DOP853")]
    pool = work_precision(tasks)
    serial = work_precision(tasks, workers=1)
    local = work_precision(tasks, scheduler="local", workers=2)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster:
        remote = work_precision(tasks, scheduler=cluster.scheduler_address)
    assert _comparable(pool) == _comparable(serial) == _comparable(local) == _comparable(remote)


def test_an_unreachable_scheduler_is_a_one_line_error(capsys):
    assert main(["chart", "work-precision", "--out", "/tmp/unused-chart", "--objects", "SimplePendulum",
                 "--scheduler", "127.0.0.1:1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("harness: error: --scheduler 127.0.0.1:1: cannot connect") and err.count("\n") == 1


def test_an_unknown_object_is_a_one_line_error(capsys):
    assert main(["chart", "work-precision", "--out", "/tmp/unused-chart", "--objects", "Pendel"]) == 2
    assert "Pendel is not one of" in capsys.readouterr().err


def test_model_exchange_counts_its_evaluations(open_fmu):
    """n_rhs in Model Exchange: one per new state the importer evaluates, none for repeated reads."""
    import ctypes
    instance = open_fmu("SimplePendulum", kind="ME")
    instance.initialize()
    assert instance.call("fmi2EnterContinuousTimeMode") == 0
    before = instance.get("n_rhs")[0]
    derivatives = (ctypes.c_double * 2)()
    for k in range(5):
        states = (ctypes.c_double * 2)(0.1 * k, 0.0)
        assert instance.call("fmi2SetContinuousStates", states, 2) == 0
        assert instance.call("fmi2GetDerivatives", derivatives, 2) == 0
        assert instance.call("fmi2GetDerivatives", derivatives, 2) == 0
    assert instance.get("n_rhs")[0] - before == 5

