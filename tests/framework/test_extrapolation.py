"""Gragg-Bulirsch-Stoer extrapolation (solver = gbs): its error follows tol on the exact pendulum, its
order control climbs to high columns at tight tolerances (up to gbs_columns), its fixed step (tol = 0)
converges at order 2 gbs_columns, polynomial motion is exact, every object agrees with an independent
integrator, energy is kept, and its counters, work bound, bad settings and FMU state behave like
rkf45's."""
from __future__ import annotations

import numpy as np
import pytest

from harness.errors import HarnessError
from harness.fmi.fmu_instance import FmuInstance
from harness.fmi.methods import GBS_COLUMNS
from harness.objects.registry import compliant_names, object_names
from harness.objects.thesis.reference import exact_simple_pendulum, slope

from method_checks import assert_polynomial_motion_is_exact, states_under_a_varying_force

PHI0 = 0.5
TOLERANCES = (1e-5, 1e-7, 1e-9, 1e-11, 1e-13)


def pendulum_error(fmu, t: float) -> float:
    phi, omega = fmu.get("phi", "omega")
    phi_exact, omega_exact = exact_simple_pendulum(PHI0, t)
    return max(abs(phi - phi_exact), abs(omega - omega_exact) / np.sqrt(9.81))


def columns_for(evaluations_per_step: float) -> float:
    """The extrapolation column k whose table costs this much: 1 + k^2 right-hand sides."""
    return float(np.sqrt(max(evaluations_per_step - 1.0, 0.0)))


@pytest.fixture(scope="module")
def pendulum_runs(fmu_paths):
    """gbs and rkf45 over 10 s of the pendulum at phi0 = 0.5 in communication steps of 0.5 s, per tol:
    (error against the elliptic solution, n_steps, n_rhs, n_rejected)."""
    runs = {}
    with FmuInstance(fmu_paths["SimplePendulum"]) as fmu:
        for solver in ("gbs", "rkf45"):
            for tol in TOLERANCES:
                fmu.reset()
                fmu.initialize(solver=solver, tol=tol, phi=PHI0)
                for k in range(20):
                    assert fmu.do_step(0.5 * k, 0.5) == 0, fmu.last_message()
                runs[solver, tol] = (pendulum_error(fmu, 10.0), *fmu.get("n_steps", "n_rhs", "n_rejected"))
    return runs


def test_the_error_follows_tol(pendulum_runs):
    """Over 10 s the global error stays within 100 tol of the elliptic solution (down to rounding) and
    falls with tol at a slope near 1 (tolerance proportionality)."""
    errors = [pendulum_runs["gbs", tol][0] for tol in TOLERANCES]
    for tol, error in zip(TOLERANCES, errors):
        assert error < max(100 * tol, 1e-12), (tol, error)
    assert 0.7 < slope(TOLERANCES[:4], errors[:4]) < 1.3, errors


def test_the_order_climbs_with_the_tolerance(pendulum_runs):
    """Tighter tolerances are met by higher columns, not only by shorter steps: the evaluations per step
    (1 + k^2 for column k) grow from tol 1e-5 to 1e-13, and at 1e-13 gbs needs a fifth of rkf45's
    evaluations."""
    per_step = [pendulum_runs["gbs", tol][2] / pendulum_runs["gbs", tol][1] for tol in TOLERANCES]
    assert columns_for(per_step[-1]) > columns_for(per_step[0]) + 1, per_step
    assert columns_for(per_step[-1]) <= GBS_COLUMNS
    assert pendulum_runs["gbs", 1e-13][2] * 5 < pendulum_runs["rkf45", 1e-13][2]


def test_energy_is_kept_at_the_tolerance(open_fmu):
    """The double pendulum from its horizontal release, 20 s at tol 1e-10: the energy stays within
    1e-7 of its start (its scale is 10 J)."""
    fmu = open_fmu("DoublePendulum")
    fmu.initialize(solver="gbs", tol=1e-10)
    start = fmu.get("E")[0]
    drift = 0.0
    for k in range(40):
        assert fmu.do_step(0.5 * k, 0.5) == 0, fmu.last_message()
        drift = max(drift, abs(fmu.get("E")[0] - start))
    assert drift < 1e-7


def test_polynomial_motion_is_exact(free_fall_ball):
    """Free fall (a parabola): the modified midpoint rule is exact on it, so the error estimate is zero and
    one step of 1 s per communication step gives it to rounding, none rejected; under a force ramp (a
    cubic) the extrapolated columns are exact as well."""
    settings = {"solver": "gbs", "tol": 1e-8, "h": 1.0}
    assert assert_polynomial_motion_is_exact(free_fall_ball, settings, settings) == (5, 0)


@pytest.mark.parametrize("name", object_names())
def test_every_object_agrees_with_an_independent_integrator(open_fmu, fmu_paths, name):
    """gbs at tol 1e-12 against rkf45 at 1e-13 over 1 s with a force varying in time on the first
    input: within 1e-8 in every state."""
    names, gbs = states_under_a_varying_force(open_fmu, fmu_paths[name], name, {"solver": "gbs", "tol": 1e-12})
    _, rkf45 = states_under_a_varying_force(open_fmu, fmu_paths[name], name, {"solver": "rkf45", "tol": 1e-13})
    # Hertz's delta^1.5 has unbounded higher derivatives where a contact begins: both step controls
    # resolve its onset less well than smooth motion
    bound = 1e-7 if name in compliant_names() else 1e-8
    assert np.max(np.abs(gbs - rkf45) / (1 + np.abs(rkf45))) < bound, (names, gbs, rkf45)


def test_the_work_bound_stops_a_call_with_a_discard(open_fmu):
    """A communication step of 1e6 s at tol 1e-13: gbs stops at its bound of right-hand sides per call,
    says so, and keeps the last successful time and state."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="gbs", tol=1e-13, phi=PHI0)
    assert fmu.do_step(0.0, 1e6) == 2
    message = fmu.last_message()
    assert "gbs with tol = 1e-13 used its 10000000 right-hand-side evaluations" in message
    reached = fmu.last_successful_time()
    assert 0.0 < reached < 1e6
    assert fmu.get("n_rhs")[0] <= 10_000_000
    assert pendulum_error(fmu, reached) < 1e-6


@pytest.mark.parametrize("cut,tol", [(0.5, 1e-9), (0.3, 1e-9), (0.3, 0.0)])
def test_state_round_trip(open_fmu, cut, tol):
    """The step proposal and the target column travel in the FMU state: going on from a restored state
    repeats the run bit for bit (also with the fixed step)."""
    fmu = open_fmu("DoublePendulum")
    fmu.initialize(solver="gbs", tol=tol, h=0.02, phi1=1.0)
    assert fmu.do_step(0.0, cut) == 0
    state = fmu.get_state()
    assert fmu.do_step(cut, 0.5) == 0
    straight = fmu.get("phi1", "phi2", "omega1", "omega2", "n_steps", "n_rhs", "n_rejected")
    fmu.set_state(state)
    assert fmu.do_step(cut, 0.5) == 0
    assert fmu.get("phi1", "phi2", "omega1", "omega2", "n_steps", "n_rhs", "n_rejected") == straight
    fmu.free_state(state)


@pytest.mark.parametrize("columns,substeps", [(2, [20, 40, 80]), (3, [10, 20, 40]), (4, [8, 16, 32])])
def test_the_fixed_step_order_is_twice_the_column(open_fmu, columns, substeps):
    """With tol = 0, gbs takes the fixed step h and column gbs_columns: over 2 s the global error against the
    elliptic solution falls as h^(2 k), and each step costs 1 + k^2 evaluations."""
    steps = [2.0 / n for n in substeps]
    errors = []
    for h in steps:
        fmu = open_fmu("SimplePendulum")
        fmu.initialize(solver="gbs", tol=0.0, gbs_columns=columns, h=h, phi=PHI0)
        assert fmu.do_step(0.0, 2.0) == 0
        errors.append(pendulum_error(fmu, 2.0))
        assert fmu.get("n_steps", "n_rhs") == [round(2.0 / h), round(2.0 / h) * (1 + columns ** 2)]
    assert min(errors) > 1e-13, errors
    assert abs(slope(steps, errors) - 2 * columns) < 0.3, errors


@pytest.mark.parametrize("columns", [2, 3, 5])
def test_gbs_columns_caps_the_order_control(open_fmu, columns):
    """With tol > 0, gbs_columns is the highest column: no attempt costs more than 1 + k^2 evaluations,
    and the error over 10 s still follows tol = 1e-10."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="gbs", tol=1e-10, gbs_columns=columns, phi=PHI0)
    for k in range(20):
        assert fmu.do_step(0.5 * k, 0.5) == 0, fmu.last_message()
    n_steps, n_rhs, n_rejected = fmu.get("n_steps", "n_rhs", "n_rejected")
    assert n_rhs <= (n_steps + n_rejected) * (1 + columns ** 2)
    target = max(2, columns - 1)  # the highest target: one column stays above it (unless that is 2)
    assert n_rhs > (n_steps + n_rejected) * (1 + (target - 1) ** 2)  # it climbs to that target
    assert pendulum_error(fmu, 10.0) < 100 * 1e-10


@pytest.mark.parametrize("columns", [1, GBS_COLUMNS + 1])
def test_gbs_columns_out_of_range_is_refused(open_fmu, columns):
    fmu = open_fmu("SimplePendulum")
    with pytest.raises(HarnessError) as error:
        fmu.initialize(solver="gbs", gbs_columns=columns)
    message = str(error.value)
    assert "gbs_columns" in message and f"= {columns}" in message and f"[2, {GBS_COLUMNS}]" in message


def test_fmi3_sets_gbs_columns(fmu_paths):
    """The FMI 3.0 build takes gbs_columns as an Int64 and runs the same numbers as the FMI 2.0 build."""
    from harness.fmi.fmus import build_dir
    ends = []
    for path in (fmu_paths["SimplePendulum"], build_dir() / "fmus" / "fmi3" / "SimplePendulum.fmu"):
        with FmuInstance(path) as fmu:
            fmu.initialize(solver="gbs", gbs_columns=3, tol=0.0, h=0.1, phi=PHI0)
            assert fmu.get("gbs_columns") == [3]
            assert fmu.do_step(0.0, 1.0) == 0
            ends.append(fmu.get("phi", "omega", "n_rhs"))
    assert ends[0] == ends[1] and ends[0][2] == 10 * 10


def test_a_tolerance_out_of_reach_is_refused(open_fmu):
    """Below 1e-15 the columns agree to rounding before the error test passes: refused by name at
    fmi2DoStep instead of shrinking the step until the work bound."""
    fmu = open_fmu("DoublePendulum")
    fmu.initialize(solver="gbs", tol=1e-16)
    assert fmu.do_step(0.0, 0.5) == 3
    message = fmu.last_message()
    assert "gbs with tol = 1e-16: out of reach in double precision" in message and "[1e-15, 1]" in message


def test_short_communication_steps_take_the_first_column_that_passes(open_fmu):
    """Communication steps of 1 ms, each shorter than the step gbs proposes: every step lands on the
    communication point and takes the first column that passes there (the control's target is kept for
    full steps), so that 2,000 of them cost at most 10 evaluations each (column 3) at tol 1e-10 and
    stay within 100 tol of the elliptic solution."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="gbs", tol=1e-10, phi=PHI0)
    for k in range(2000):
        assert fmu.do_step(k * 1e-3, 1e-3) == 0
    assert fmu.get("n_rhs")[0] <= 2000 * 10
    assert pendulum_error(fmu, 2.0) < 100 * 1e-10
