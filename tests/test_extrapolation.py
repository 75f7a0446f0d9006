"""Gragg-Bulirsch-Stoer extrapolation (solver = gbs): its error follows tol on the exact pendulum, its
order control climbs to high columns at tight tolerances, polynomial motion is exact, every object
agrees with an independent integrator, energy is kept, and its counters, work bound, bad settings and
FMU state behave like rkf45's."""
from __future__ import annotations

import numpy as np
import pytest

from harness.fmi.fmu_instance import FmuInstance
from harness.fmi.methods import GBS_COLUMNS
from harness.objects.registry import object_names
from harness.objects.thesis.reference import exact_simple_pendulum, slope

from method_checks import assert_polynomial_motion_is_exact, ball_fmu, states_under_a_varying_force

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


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    return ball_fmu(tmp_path_factory.mktemp("ball"))


def test_polynomial_motion_is_exact(ball):
    """Free fall (a parabola): the modified midpoint rule is exact on it, so the error estimate is zero and
    one step of 1 s per communication step gives it to rounding, none rejected; under a force ramp (a
    cubic) the extrapolated columns are exact as well."""
    settings = {"solver": "gbs", "tol": 1e-8, "h": 1.0}
    assert assert_polynomial_motion_is_exact(ball, settings, settings) == (5, 0)


@pytest.mark.parametrize("name", object_names())
def test_every_object_agrees_with_an_independent_integrator(open_fmu, fmu_paths, name):
    """gbs at tol 1e-12 against rkf45 at 1e-13 over 1 s with a force varying in time on the first
    input: within 1e-8 in every state."""
    names, gbs = states_under_a_varying_force(open_fmu, fmu_paths[name], name, {"solver": "gbs", "tol": 1e-12})
    _, rkf45 = states_under_a_varying_force(open_fmu, fmu_paths[name], name, {"solver": "rkf45", "tol": 1e-13})
    assert np.max(np.abs(gbs - rkf45) / (1 + np.abs(rkf45))) < 1e-8, (names, gbs, rkf45)


def test_gbs_refuses_tol_zero(open_fmu):
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="gbs", tol=0.0)
    assert fmu.do_step(0.0, 0.1) == 3
    assert "gbs needs a tolerance: variable tol = 0 is out of its range (0, 1]" in fmu.last_message()


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


@pytest.mark.parametrize("cut", [0.5, 0.3])
def test_state_round_trip(open_fmu, cut):
    """The step proposal and the target column travel in the FMU state: going on from a restored state
    repeats the run bit for bit."""
    fmu = open_fmu("DoublePendulum")
    fmu.initialize(solver="gbs", tol=1e-9, phi1=1.0)
    assert fmu.do_step(0.0, cut) == 0
    state = fmu.get_state()
    assert fmu.do_step(cut, 0.5) == 0
    straight = fmu.get("phi1", "phi2", "omega1", "omega2", "n_steps", "n_rhs", "n_rejected")
    fmu.set_state(state)
    assert fmu.do_step(cut, 0.5) == 0
    assert fmu.get("phi1", "phi2", "omega1", "omega2", "n_steps", "n_rhs", "n_rejected") == straight
    fmu.free_state(state)
