"""Numerics through the FMUs: convergence orders against the exact simple pendulum, rkf45 against
its tolerance, energy conservation to each method's order."""
from __future__ import annotations

import numpy as np
import pytest

from harness.fmi.methods import METHOD
from harness.fmi.simulation import simulate
from harness.objects.thesis.reference import exact_simple_pendulum, slope

ORDERS = {"euler": 1, "midpoint": 2, "heun": 2, "rk3": 3, "rk4": 4, "nystrom5": 5,
          "ab2": 2, "ab3": 3, "ab4": 4, "ab5": 5, "ab6": 6, "implicit_midpoint": 2, "gauss_legendre4": 4,
          "stormer_verlet": 2, "abm2": 2, "abm3": 3, "abm4": 4, "abm5": 5, "abm6": 6, "trapezoid": 2}
# Steps where each method is in its asymptotic range on the pendulum (errors 1e-2 ... 1e-11).
FINE, MEDIUM, COARSE = [0.02, 0.01, 0.005, 0.0025], [0.04, 0.02, 0.01, 0.005], [0.08, 0.04, 0.02, 0.01]
STEPS = {"euler": [2e-3, 1e-3, 5e-4, 2.5e-4], "midpoint": FINE, "heun": FINE, "rk3": MEDIUM, "rk4": COARSE,
         "nystrom5": [0.1, 0.05, 0.025, 0.0125], "ab2": FINE, "ab3": FINE, "ab4": MEDIUM, "ab5": MEDIUM,
         "ab6": MEDIUM, "implicit_midpoint": FINE, "gauss_legendre4": COARSE, "stormer_verlet": FINE,
         "abm2": FINE, "abm3": FINE, "abm4": MEDIUM, "abm5": MEDIUM, "abm6": MEDIUM, "trapezoid": FINE}
T = 2.0  # about one period at phi0 = 0.5
PHI0 = 0.5


def state_error(instance, t: float) -> float:
    phi, omega = instance.get("phi", "omega")
    phi_exact, omega_exact = exact_simple_pendulum(PHI0, t)
    return max(abs(phi - phi_exact), abs(omega - omega_exact) / np.sqrt(9.81))


@pytest.mark.parametrize("solver", list(ORDERS))
def test_fixed_step_methods_converge_at_their_order(open_fmu, solver):
    order, hs = ORDERS[solver], STEPS[solver]
    errors = []
    for h in hs:
        fmu = open_fmu("SimplePendulum")
        fmu.initialize(solver=solver, h=h, phi=PHI0)
        assert fmu.do_step(0.0, T) == 0
        errors.append(state_error(fmu, T))
        fmu.free()
    measured = slope(hs, errors)
    assert abs(measured - order) <= 0.3, f"{solver}: measured order {measured:.2f}, errors {errors}"


def test_many_communication_steps_match_one_long_step(open_fmu):
    """Adams-Bashforth keeps its history across fmi2DoStep calls: 200 calls of 0.01 s give the
    same answer as one call of 2 s, up to rounding of the substep times."""
    results = []
    for calls in (1, 200):
        fmu = open_fmu("SimplePendulum")
        fmu.initialize(solver="ab4", h=0.01)
        H = T / calls
        for i in range(calls):
            assert fmu.do_step(i * H, H) == 0
        results.append(fmu.get("phi", "omega", "n_rhs", "n_steps"))
    (phi1, omega1, rhs1, steps1), (phi2, omega2, rhs2, steps2) = results
    assert abs(phi1 - phi2) < 1e-12 and abs(omega1 - omega2) < 1e-12
    assert rhs1 == rhs2 == 200 + 3 * 3  # one evaluation per step, plus 3 extra in each of the 3 RK4 start steps
    assert steps1 == steps2 == 200


@pytest.mark.parametrize("phi0", [0.5, 2.5])
def test_rkf45_meets_its_tolerance(fmu_paths, unzipped, phi0):
    """Every accepted step keeps its local error estimate within tol (1 + |y|); the global error is
    then bounded by the sum of the local tolerances, n_steps tol (1 + max|y|), up to a small growth
    factor, and falls with tol."""
    tolerances = [1e-4, 1e-6, 1e-8, 1e-10]
    errors = []
    for tol in tolerances:
        r = simulate(fmu_paths["SimplePendulum"], 10.0, 1.0, start_values={"solver": "rkf45", "tol": tol, "phi": phi0},
                     unzipdir=unzipped["SimplePendulum"])
        phi_exact, omega_exact = exact_simple_pendulum(phi0, r.time)
        error = float(np.max(np.maximum(abs(r["phi"] - phi_exact), abs(r["omega"] - omega_exact))))
        bound = r["n_steps"][-1] * tol * (1 + np.max(np.abs(r["omega"])))
        assert error <= 5 * bound, f"tol {tol}: error {error:.3g} above 5 x {bound:.3g}"
        errors.append(error)
    assert all(a > b for a, b in zip(errors, errors[1:]))
    assert 0.6 <= slope(tolerances, errors) <= 1.3  # theory: tol^(4/5)


def test_rkf45_rejects_and_recovers(open_fmu):
    """A large initial step is rejected, not accepted with a large error."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="rkf45", tol=1e-8, h=0.5, phi=2.0)
    assert fmu.do_step(0.0, 1.0) == 0
    n_rejected, n_steps = fmu.get("n_rejected", "n_steps")
    assert n_rejected >= 1 and n_steps > 10
    # Five new stages per attempt; the first stage is evaluated once per accepted point and
    # reused when a step from there is retried.
    assert fmu.get("n_rhs")[0] == 5 * (n_steps + n_rejected) + n_steps


ENERGY_STEPS = {1: [2e-4, 1e-4, 5e-5], 2: [2e-3, 1e-3, 5e-4], 3: [4e-3, 2e-3, 1e-3], 4: [8e-3, 4e-3, 2e-3],
                5: [0.01, 0.005, 0.0025], 6: [0.004, 0.002, 0.001]}


@pytest.mark.parametrize("name", ["DoublePendulum", "SpringPendulum"])
@pytest.mark.parametrize("solver", [s for s in ORDERS if not METHOD[s].needs_constant_mass])
def test_energy_is_conserved_to_the_method_order(fmu_paths, unzipped, name, solver):
    """Without damping or force the energy drift over 2 s shrinks at least like h^p."""
    order = ORDERS[solver]
    hs = ENERGY_STEPS[order]
    drifts = []
    for h in hs:
        r = simulate(fmu_paths[name], 2.0, 0.1, start_values={"solver": solver, "h": h}, unzipdir=unzipped[name])
        drifts.append(float(np.max(np.abs(r["E"] - r["E"][0]))))
    assert drifts[-1] < 0.05
    measured = slope(hs, drifts)
    assert measured >= order - 0.3, f"{name} {solver}: energy error order {measured:.2f}, drifts {drifts}"
