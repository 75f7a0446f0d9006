"""The work-precision chart for objects made from object files: a 2-D object with a force input (the
cart pendulum), a 3-D one (the spherical pendulum) and a driven one with a fine default step
(Kapitza's pendulum). Its slopes are the methods' orders, its references are tight by an independent
method, and the scipy peers integrate equations that agree with the independent numeric route."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from harness.cli import main
from harness.fmi.events import matched_error
from harness.objects.motion import ObjectMotion
from harness.objects.numeric_route import NumericLagrangian
from harness.objects.object_file import read_object_file
from harness.objects.proof import random_values
from harness.objects.registry import constrained_names, object_file, object_names
from harness.studies.work_precision import (ADAPTIVE, FIXED_STEP, STEP, STOP, peer_equations, read_csv, reference_for,
                                            step_scale)
from test_work_precision import assert_slope_is_the_order, assert_tolerances_buy_accuracy

OBJECTS = ("CartPendulum", "SphericalPendulum", "KapitzaPendulum")
NEW_OBJECTS = [name for name in object_names() if name not in ("SimplePendulum", "DoublePendulum", "SpringPendulum")]


@pytest.fixture(scope="module")
def sweep(fmu_paths, tmp_path_factory):
    out = tmp_path_factory.mktemp("work-precision-objects")
    assert main(["chart", "work-precision", "--out", str(out), "--repeats", "1", "--quick",
                 "--objects", *OBJECTS]) == 0
    return out, read_csv(out / "work-precision.csv")


def test_every_method_and_peer_has_points(sweep):
    out, points = sweep
    assert (out / "work-precision.png").stat().st_size > 10_000
    for name in OBJECTS:
        for method in [*FIXED_STEP, *ADAPTIVE, "taylor", "scipy-RK45", "scipy-DOP853", "scipy-LSODA", "fmpy-CVode"]:
            mine = [p for p in points if p.object == name and p.method == method]
            if method == "stormer_verlet":  # none of these objects has a constant mass matrix
                assert not mine
                continue
            assert len(mine) >= 2, (name, method)
            assert all(p.rhs_evals > 0 and p.error > 0 for p in mine), (name, method)
        assert all(p.reference_error < 1e-12 for p in points if p.object == name)


def test_the_fixed_steps_follow_the_default_step(sweep):
    """Kapitza's pendulum (h = 1e-4 s by default) gets steps 64 times finer than the others (0.008 s)."""
    finest = {name: min(p.h for p in sweep[1] if p.object == name and p.method == "rk4") for name in OBJECTS}
    assert finest["KapitzaPendulum"] == pytest.approx(finest["CartPendulum"] / 64)
    assert finest["CartPendulum"] == pytest.approx(STEP / 64)


@pytest.mark.parametrize("name", OBJECTS)
@pytest.mark.parametrize("method", ["heun", "rk3", "rk4", "nystrom5", "ab4", "ab6"])
def test_slopes_are_the_orders(sweep, name, method):
    """Through the finest settings whose errors lie above 100 times the reference's estimate and
    below 1e-3 m, short of the rounding floor: log(error) against log(evaluations) falls with the method's
    order."""
    assert_slope_is_the_order(sweep[1], name, method, lambda p: 100 * p.reference_error <= p.error <= 1e-3, 2, 0.35)


@pytest.mark.parametrize("name", OBJECTS)
def test_tighter_tolerances_buy_accuracy(sweep, name):
    assert_tolerances_buy_accuracy(sweep[1], name)


@pytest.mark.parametrize("name", ["CartPendulum", "SphericalPendulum"])
def test_the_fmu_reference_against_an_independent_method(fmu_paths, name):
    """The FMU's nystrom5 reference and scipy's DOP853 at rtol 1e-12 over the SymPy derivation's
    equations (another method, another code path) agree to 1e-9 m over 10 s."""
    reference = reference_for(str(fmu_paths[name]))
    equations = peer_equations(str(fmu_paths[name]))
    t = np.linspace(0.0, STOP, int(round(STOP / STEP)) + 1)
    solution = solve_ivp(equations.rhs, (0.0, STOP), equations.start, method="DOP853", t_eval=t, rtol=1e-12,
                         atol=1e-12)
    assert solution.success
    traced = equations.traced_point(solution.y.T, solution.t)
    assert traced.shape == reference.positions.shape == (len(t), 3 if name == "SphericalPendulum" else 2)
    assert np.max(np.linalg.norm(traced - reference.positions, axis=1)) < 1e-9


@pytest.mark.parametrize("name", [n for n in NEW_OBJECTS if n not in constrained_names()])  # no peer for those
def test_the_peers_equations_are_the_numeric_routes(derivation, name):
    """The scipy peers' right-hand side (lambdified from the derivation) against accelerations from
    finite differences of the plainly evaluated T and U, with forces, damping and time."""
    spec = read_object_file(object_file(name))
    derived, route = derivation(name), NumericLagrangian(spec)
    rng = np.random.default_rng(11)
    n = len(spec.coordinates)
    for _ in range(4):
        values = random_values(spec, rng)
        motion = ObjectMotion(derived, values)
        got = np.array(motion.rhs(values["t"], motion.start))
        expected = route.accelerations(values, values["t"])
        assert np.allclose(got[:n], motion.start[n:], rtol=0, atol=0)
        assert np.max(np.abs(got[n:] - expected)) <= 1e-9 * max(1.0, float(np.max(np.abs(expected))))


@pytest.mark.parametrize("name", ["KapitzaPendulum", "SphericalPendulum"])
def test_the_peers_traced_point_is_what_the_fmu_reports(open_fmu, fmu_paths, name):
    """Positions from the peers' equations equal the FMU's outputs, the driven anchor's time included."""
    from harness.studies.references import traced_columns
    instance = open_fmu(name)
    instance.initialize()
    equations = peer_equations(str(fmu_paths[name]))
    spec = read_object_file(object_file(name))
    states = [c.name for c in spec.coordinates] + [c.velocity for c in spec.coordinates]
    columns = traced_columns(fmu_paths[name])
    time = 0.0
    for _ in range(20):
        assert instance.do_step(time, 0.0123) == 0
        time += 0.0123
        position = equations.traced_point(np.array([instance.get(*states)]), np.array([time]))[0]
        assert np.allclose(position, instance.get(*columns), rtol=0, atol=1e-14)
        assert math.isfinite(position[0])


def test_step_scale_is_a_power_of_two(fmu_paths):
    assert step_scale(fmu_paths["SimplePendulum"]) == 1
    assert step_scale(fmu_paths["KapitzaPendulum"]) == 64


@pytest.fixture(scope="module")
def impact_sweep(fmu_paths, tmp_path_factory):
    """The chart on an object with impacts: the pendulum striking a wall (restitution 0.9), 10 s."""
    out = tmp_path_factory.mktemp("work-precision-impacts")
    assert main(["chart", "work-precision", "--out", str(out), "--repeats", "1", "--quick",
                 "--objects", "WallPendulum"]) == 0
    assert all((out / f"{stem}.png").is_file() for stem in ("work-precision-events", "work-precision-events-time"))
    return read_csv(out / "work-precision.csv")


def test_work_precision_through_impacts(impact_sweep):
    """Every method and CVode (Model Exchange, the impacts as its events) have points, taylor and stormer_verlet
    too (the wall pendulum's motion is free between impacts); the slopes through the impacts are the methods'
    orders, as without impacts; tighter tolerances buy accuracy. No scipy peer (it knows no impacts)."""
    points = impact_sweep
    methods = {p.method for p in points}
    assert "scipy-RK45" not in methods
    assert set(FIXED_STEP) | set(ADAPTIVE) | {"fmpy-CVode"} <= methods
    assert all(p.reference_error < 1e-12 for p in points)
    # above 1e-12 m: rounding summed over 10^5 steps and the impacts' projections (rk4 ends at 5e-14 m)
    for method in ("heun", "rk3", "rk4", "nystrom5", "ab4", "stormer_verlet"):
        assert_slope_is_the_order(points, "WallPendulum", method, lambda p: 1e-12 <= p.error <= 1e-3, 2, 0.35)
    # rkf45's steps are capped by the communication step at loose tolerances here (the same 1e-9 m at tol
    # 1e-6 and 1e-10), so tightening buys less than on the free objects
    for method in (*ADAPTIVE, "fmpy-CVode"):
        mine = sorted((p for p in points if p.method == method), key=lambda p: p.tol)
        errors = [p.error for p in mine]
        assert errors[0] * 30 < errors[-1], (method, errors)


def test_event_times_through_impacts(impact_sweep, fmu_paths):
    """The chart's second measure on an object with events: when each impact happens. The reference's impact
    times (the FMU's nystrom5 at its finest step, from FMI 3.0's early returns) agree with the pendulum
    equation integrated here by SciPy with the wall as its event; every method's event times are measured
    (the same eight impacts), and their error falls at the method's order, as the position error does."""
    from test_constraints import _wall_reference
    reference = reference_for(str(fmu_paths["WallPendulum"]))
    _, impacts = _wall_reference(STOP)
    assert len(reference.event_times) == len(impacts) == 8
    assert np.max(np.abs(np.subtract(reference.event_times, impacts))) < 1e-11
    assert reference.estimated_event_error < 1e-13
    points = impact_sweep
    assert all(math.isfinite(p.event_error) and p.reference_event_error < 1e-13 for p in points), \
        [(p.method, p.event_error) for p in points if not math.isfinite(p.event_error)]
    for method in ("heun", "rk3", "rk4", "nystrom5", "ab4"):
        assert_slope_is_the_order(points, "WallPendulum", method, lambda p: 1e-13 <= p.event_error <= 1e-3, 2, 0.35,
                                  "event_error")
    cvode = sorted((p for p in points if p.method == "fmpy-CVode"), key=lambda p: p.tol)
    assert cvode[0].event_error * 100 < cvode[-1].event_error


def test_event_times_are_matched_in_order():
    """An event just beyond the end in one run but not the other is left out; a missed event is not."""
    reference = [1.0, 2.0, 3.0]
    assert matched_error([1.0, 2.0 + 1e-9, 3.0], reference) == pytest.approx(1e-9)
    assert matched_error([1.0, 2.0 + 1e-9], reference) == pytest.approx(1e-9)
    assert matched_error([1.0], reference) == math.inf
    assert matched_error([], reference) == math.inf
    assert math.isnan(matched_error([], []))
