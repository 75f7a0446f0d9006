"""The Taylor method (solver = taylor): its order at several values of taylor_order on the exact
pendulum, exactness where the motion is a polynomial, agreement with an independent integrator on
every object (mass matrices, forces, driven pivots), the step chosen from its coefficients for tol,
its counters, bad settings, and the FMU state."""
from __future__ import annotations

import numpy as np
import pytest

from harness.errors import HarnessError
from harness.fmi.methods import TAYLOR_ORDERS
from harness.objects.registry import constrained_names, object_names
from harness.objects.thesis.reference import exact_simple_pendulum, slope

from method_checks import assert_polynomial_motion_is_exact, states_under_a_varying_force

PHI0 = 0.5


def charge(order: int) -> int:
    """Evaluations a Taylor step counts: coefficient k costs about k + 1 multiply-adds per operation."""
    return order * (order + 1) // 2


def pendulum_error(fmu, t: float) -> float:
    phi, omega = fmu.get("phi", "omega")
    phi_exact, omega_exact = exact_simple_pendulum(PHI0, t)
    return max(abs(phi - phi_exact), abs(omega - omega_exact) / np.sqrt(9.81))


@pytest.mark.parametrize("order,substeps", [(2, [100, 200, 400]), (3, [40, 80, 160]), (4, [20, 40, 80]),
                                            (6, [10, 20, 40]), (8, [16, 20, 32, 40])])
def test_the_order_is_taylor_order(open_fmu, order, substeps):
    """Fixed step (tol = 0) over 2 s, steps that divide it: the global error falls as h^order against
    the elliptic solution. (Above order 8 the error reaches rounding before its slope settles: order
    10 measures 11.0 between h = 2/16 and 2/32 s and is at 1e-15 by 2/40.)"""
    steps = [2.0 / n for n in substeps]
    errors = []
    for h in steps:
        fmu = open_fmu("SimplePendulum")
        fmu.initialize(solver="taylor", taylor_order=order, tol=0.0, h=h, phi=PHI0)
        assert fmu.do_step(0.0, 2.0) == 0
        errors.append(pendulum_error(fmu, 2.0))
    assert min(errors) > 1e-13, errors  # above rounding: the slope is truncation's
    assert abs(slope(steps, errors) - order) < 0.3, errors


def test_a_high_order_is_exact_to_rounding_at_large_steps(open_fmu):
    """Order 30 at h = 0.25 s (a twelfth of the period): 10 s within 1e-13 of the elliptic solution."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="taylor", taylor_order=30, tol=0.0, h=0.25, phi=PHI0)
    assert fmu.do_step(0.0, 10.0) == 0
    assert pendulum_error(fmu, 10.0) < 1e-13
    assert fmu.get("n_steps", "n_rhs") == [40, 40 * charge(30)]


def test_polynomial_motion_is_exact_per_step(free_fall_ball):
    """Free fall is a parabola and, under a force growing linearly in time (its derivative set), a
    cubic: orders 2 and 3 give them exactly with one step per communication step of 1 s."""
    assert_polynomial_motion_is_exact(free_fall_ball, {"solver": "taylor", "taylor_order": 2, "tol": 0.0, "h": 1.0},
                                      {"solver": "taylor", "taylor_order": 3, "tol": 0.0, "h": 1.0})


@pytest.mark.parametrize("name", [n for n in object_names() if n not in constrained_names()])  # refused there
def test_every_object_agrees_with_an_independent_integrator(open_fmu, fmu_paths, name):
    """taylor (order 20, tol 1e-13) against rkf45 at tol 1e-13 (the generated right-hand side, not
    the recurrences) over 1 s with a force varying in time on its first input: within 1e-8 in every
    state."""
    names, taylor = states_under_a_varying_force(open_fmu, fmu_paths[name], name,
                                                 {"solver": "taylor", "taylor_order": 20, "tol": 1e-13})
    _, rkf45 = states_under_a_varying_force(open_fmu, fmu_paths[name], name, {"solver": "rkf45", "tol": 1e-13})
    assert np.max(np.abs(taylor - rkf45) / (1 + np.abs(rkf45))) < 1e-8, (names, taylor, rkf45)


def test_the_step_follows_tol(open_fmu):
    """With tol > 0 the error over 10 s stays within 100 tol of the elliptic solution and fewer,
    longer steps come with a looser tol; a step of order p counts p (p + 1) / 2 evaluations."""
    steps = {}
    for tol in (1e-8, 1e-11, 1e-14):
        fmu = open_fmu("SimplePendulum")
        fmu.initialize(solver="taylor", taylor_order=16, tol=tol, phi=PHI0)
        assert fmu.do_step(0.0, 10.0) == 0
        assert pendulum_error(fmu, 10.0) < max(100 * tol, 1e-13)
        n_steps, n_rhs = fmu.get("n_steps", "n_rhs")
        assert n_rhs == charge(16) * n_steps
        steps[tol] = n_steps
    assert steps[1e-8] < steps[1e-11] < steps[1e-14]


@pytest.mark.parametrize("order", [1, TAYLOR_ORDERS[1] + 1])
def test_taylor_order_out_of_range_is_refused(open_fmu, order):
    fmu = open_fmu("SimplePendulum")
    with pytest.raises(HarnessError) as error:
        fmu.initialize(solver="taylor", taylor_order=order)
    message = str(error.value)
    assert "taylor_order" in message and f"= {order}" in message
    assert f"[{TAYLOR_ORDERS[0]}, {TAYLOR_ORDERS[1]}]" in message


def test_rkf45_refuses_tol_zero(open_fmu):
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="rkf45", tol=0.0)
    assert fmu.do_step(0.0, 0.1) == 3
    assert "rkf45 needs a tolerance: variable tol = 0" in fmu.last_message()


@pytest.mark.parametrize("tol", [0.0, 1e-10])
def test_state_round_trip(open_fmu, tol):
    fmu = open_fmu("DoublePendulum")
    fmu.initialize(solver="taylor", tol=tol, h=0.02, phi1=1.0)
    assert fmu.do_step(0.0, 0.5) == 0
    state = fmu.get_state()
    assert fmu.do_step(0.5, 0.5) == 0
    straight = fmu.get("phi1", "phi2", "omega1", "omega2", "n_steps", "n_rhs")
    fmu.set_state(state)
    assert fmu.do_step(0.5, 0.5) == 0
    assert fmu.get("phi1", "phi2", "omega1", "omega2", "n_steps", "n_rhs") == straight
    fmu.free_state(state)


@pytest.mark.parametrize("order", [4, 8, 12, 20])
def test_a_release_at_90_degrees_keeps_its_step_bounded(open_fmu, order):
    """Released from rest at phi1 = phi2 = pi/2 (the double pendulum's default start), the angles'
    series have only every fourth power, so that the last two coefficients are rounding noise at
    orders divisible by 4: the step comes from the last four. One call of 0.875 s with tol = 1e-10
    agrees with rkf45 at 1e-13 and keeps the energy."""
    ends = []
    for settings in ({"solver": "taylor", "taylor_order": order, "tol": 1e-10}, {"solver": "rkf45", "tol": 1e-13}):
        fmu = open_fmu("DoublePendulum")
        fmu.initialize(**settings)
        start_energy = fmu.get("E")[0]
        assert fmu.do_step(0.0, 0.875) == 0
        ends.append(np.array(fmu.get("phi1", "phi2", "omega1", "omega2")))
        assert abs(fmu.get("E")[0] - start_energy) < 1e-6
        if settings["solver"] == "taylor":
            assert fmu.get("n_steps")[0] > 10
    assert np.max(np.abs(ends[0] - ends[1])) < 1e-6, ends


def test_a_tolerance_out_of_reach_says_so(open_fmu):
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="taylor", taylor_order=2, tol=1e-300)
    assert fmu.do_step(0.0, 1.0) == 2
    message = fmu.last_message()
    assert "taylor of order 2 with tol = 1e-300" in message and "take a larger tol or a higher taylor_order" in message
    assert fmu.last_successful_time() == 0.0


def test_fmi3_sets_and_checks_taylor_order(fmu_paths):
    """The FMI 3.0 build takes taylor_order as an Int64 parameter (as its enumerations), refuses one out
    of range by name, and runs the order it was given: the same numbers as the FMI 2.0 build."""
    from harness.fmi.fmu_instance import FmuInstance
    from harness.fmi.fmus import build_dir
    ends = []
    for path in (fmu_paths["SimplePendulum"], build_dir() / "fmus" / "fmi3" / "SimplePendulum.fmu"):
        with FmuInstance(path) as fmu:
            assert fmu.set(taylor_order=31) == 3
            assert "taylor_order" in fmu.last_message() and "[2, 30]" in fmu.last_message()
            fmu.initialize(solver="taylor", taylor_order=5, tol=0.0, h=0.1, phi=PHI0)
            assert fmu.get("taylor_order") == [5]
            assert fmu.do_step(0.0, 1.0) == 0
            ends.append(fmu.get("phi", "omega", "n_rhs"))
    assert ends[0] == ends[1] and ends[0][2] == 10 * charge(5)
