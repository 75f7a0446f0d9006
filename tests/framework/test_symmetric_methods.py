"""The symmetric methods (implicit midpoint, 2-stage Gauss-Legendre, Stormer-Verlet) through the FMUs:
time reversibility, the Newton iteration's counters and its failure, the constant-mass-matrix
condition of Stormer-Verlet, damping and varying inputs at the methods' orders."""
from __future__ import annotations

import numpy as np
import pytest

from harness.errors import HarnessError
from harness.fmi.fmu_instance import FmuInstance
from harness.fmi.fmus import build_dir
from harness.fmi.methods import IMPLICIT, METHOD, SOLVERS, SYMMETRIC
from harness.objects.thesis.reference import slope
from harness.studies.stability import method_tables

STARTS = {  # conservative, autonomous motion: reversing the velocities reverses time
    "SimplePendulum": ({"phi": 2.5, "omega": 0.0}, ("omega",)),
    "DoublePendulum": ({"phi1": 0.3, "phi2": -0.2, "omega1": 0.0, "omega2": 0.0}, ("omega1", "omega2")),
    "SpringPendulum": ({"phi": 0.4, "omega": 0.0, "eps": 0.05, "v_eps": 0.0}, ("omega", "v_eps")),
}


def run(open_fmu, name: str, solver: str, h: float, start: dict, T: float, **extra) -> tuple[int, dict, FmuInstance]:
    fmu = open_fmu(name)
    fmu.initialize(0.0, solver=solver, h=h, **start, **extra)
    status = fmu.do_step(0.0, T)
    return status, dict(zip(start, fmu.get(*start))), fmu


def available(name: str, solver: str) -> bool:
    return name == "SimplePendulum" or not METHOD[solver].needs_constant_mass


@pytest.mark.parametrize("name", list(STARTS))
def test_forward_then_backward_returns_to_the_start(open_fmu, name):
    """A symmetric method is its own adjoint: run 10 s, reverse the velocities, run 10 s again and the
    start comes back up to rounding (and the Newton tolerance), while rk4 at the same step misses by
    its global error."""
    start, velocities = STARTS[name]
    misses = {}
    for solver in ("rk4", *[s for s in SYMMETRIC if available(name, s)]):
        status, end, _ = run(open_fmu, name, solver, 0.01, start, 10.0)
        assert status == 0
        reversed_end = {k: -v if k in velocities else v for k, v in end.items()}
        status, back, _ = run(open_fmu, name, solver, 0.01, reversed_end, 10.0)
        assert status == 0
        misses[solver] = max(abs((-back[k] if k in velocities else back[k]) - start[k]) for k in start)
    for solver in misses:
        if solver != "rk4":
            assert misses[solver] < 1e-11, misses
            assert misses["rk4"] > 1e3 * misses[solver], misses


@pytest.mark.parametrize("solver", IMPLICIT)
def test_newton_counters(open_fmu, solver):
    """One Jacobian per step (and one right-hand side for it); each iteration evaluates the right-hand
    side once per implicit stage, an explicit stage (a zero row of A: the trapezoid rule's first) once
    per step; a few iterations per step at a small step, never more than the limit."""
    a = np.array(method_tables()[solver]["a"])
    explicit = int(np.sum(~a.any(axis=1)))
    status, _, fmu = run(open_fmu, "DoublePendulum", solver, 0.005, {"phi1": 1.0, "phi2": 0.5}, 2.0)
    assert status == 0
    n_rhs, n_steps, n_jacobians, n_iterations = fmu.get("n_rhs", "n_steps", "n_jacobians", "n_iterations")
    assert n_steps == 400 and n_jacobians == n_steps
    assert n_rhs == (len(a) - explicit) * n_iterations + explicit * n_steps + n_jacobians
    assert 2 * n_steps <= n_iterations <= 6 * n_steps


def test_stormer_verlet_costs_one_evaluation_per_step(open_fmu):
    status, _, fmu = run(open_fmu, "SimplePendulum", "stormer_verlet", 0.01, {"phi": 1.0}, 2.0)
    n_rhs, n_steps, n_jacobians, n_iterations = fmu.get("n_rhs", "n_steps", "n_jacobians", "n_iterations")
    assert status == 0 and n_steps == 200 and (n_jacobians, n_iterations) == (0, 0)
    assert n_rhs == n_steps + 1  # one more at the start of each checked block of 256 steps: one block here


@pytest.mark.parametrize("solver", IMPLICIT)
def test_newton_failure_is_a_discard_at_the_last_good_step(open_fmu, solver):
    """h = 1 s on a pendulum swinging near the top: the iteration does not converge. The step stops at
    the last good substep with fmi2Discard and says why and what to do."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(0.0, solver=solver, h=1.0, phi=3.0)
    assert fmu.do_step(0.0, 10.0) == 2
    message = fmu.last_message()
    assert f"fmi2DoStep: {solver} with h = 1: Newton's iteration did not converge" in message
    assert "take a smaller h" in message
    reached = fmu.last_successful_time()
    assert reached in (0.0, 1.0, 2.0) and f"last successful time {reached:g}" in message
    assert np.isfinite(fmu.get("phi", "omega", "E")).all()


@pytest.mark.parametrize("name", ["DoublePendulum", "SpringPendulum", "CartPendulum"])
def test_stormer_verlet_is_refused_where_the_mass_matrix_varies(open_fmu, name):
    fmu = open_fmu(name)
    with pytest.raises(HarnessError) as error:
        fmu.initialize(0.0, solver="stormer_verlet")
    message = str(error.value)
    assert "fmi2SetInteger: variable solver" in message and "= 15 (stormer_verlet)" in message
    assert (f"the mass matrix of {name} depends on" in message
            and f"allowed here: 1 to {len(SOLVERS)} except 15" in message)


@pytest.mark.parametrize("solver", SYMMETRIC)
def test_order_with_damping_and_a_varying_force(open_fmu, solver):
    """Damping d and a force input that varies over the communication step (its derivative set): the
    methods keep their order against a fine rkf45 solution."""
    order = METHOD[solver].order
    start = {"phi": 1.0, "omega": 0.5}

    def final(solver_name: str, **settings) -> np.ndarray:
        fmu = open_fmu("SimplePendulum")
        fmu.initialize(0.0, solver=solver_name, d=0.3, **start, **settings)
        t = 0.0
        for _ in range(10):
            fmu.set(F_x=2.0 * np.sin(t))
            fmu.set_input_derivatives(F_x=2.0 * np.cos(t))
            assert fmu.do_step(t, 0.2) == 0
            t += 0.2
        return np.array(fmu.get("phi", "omega"))

    reference = final("rkf45", tol=1e-13, h=1e-3)
    hs = [0.02, 0.01, 0.005] if order == 2 else [0.1, 0.05, 0.025]
    errors = [float(np.max(np.abs(final(solver, h=h) - reference))) for h in hs]
    assert abs(slope(hs, errors) - order) <= 0.3, errors


@pytest.mark.parametrize("solver", IMPLICIT)
def test_state_round_trip_mid_run(open_fmu, solver):
    """The implicit methods keep nothing between steps but the counters: a saved and restored state
    continues exactly as the uninterrupted run."""
    fmu = open_fmu("DoublePendulum")
    fmu.initialize(0.0, solver=solver, h=0.01, phi1=1.0)
    assert fmu.do_step(0.0, 0.5) == 0
    state = fmu.get_state()
    assert fmu.do_step(0.5, 0.5) == 0
    straight = fmu.get("phi1", "phi2", "omega1", "omega2", "n_iterations", "n_jacobians")
    fmu.set_state(state)
    assert fmu.do_step(0.5, 0.5) == 0
    assert fmu.get("phi1", "phi2", "omega1", "omega2", "n_iterations", "n_jacobians") == straight
    fmu.free_state(state)


def test_instances_of_each_version_agree(fmu_paths):
    """The FMI 3.0 build runs the new methods bit for bit like the FMI 2.0 one."""
    results = []
    for path in (fmu_paths["DoublePendulum"], build_dir() / "fmus" / "fmi3" / "DoublePendulum.fmu"):
        fmu = FmuInstance(path)
        try:
            fmu.initialize(0.0, solver="gauss_legendre4", h=0.01, phi1=1.0)
            assert fmu.do_step(0.0, 1.0) == 0
            results.append(fmu.get("phi1", "phi2", "omega1", "omega2", "n_iterations"))
        finally:
            fmu.free()
    assert results[0] == results[1]
