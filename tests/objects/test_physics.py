"""The right-hand sides, positions and energies of all three pendulums against an independent
SymPy Euler-Lagrange derivation from T and U (harness.objects.thesis.lagrange), at random states, parameters and
forces, read through Model Exchange; and the scipy peers' hand-coded equations against the same derivation (here,
so that one test process derives the double pendulum once: it takes half a minute)."""
from __future__ import annotations

import ctypes
import math

import numpy as np
import pytest
import sympy as sp

from harness.objects.thesis.equations import STATES, Pendulum
from harness.objects.thesis.lagrange import MODELS, derived_model, g, random_point

@pytest.mark.parametrize("name", list(MODELS))
def test_right_hand_side_positions_and_energies_match_lagrange(open_fmu, name):
    names, reference, positions, q, qd = derived_model(name)
    rng = np.random.default_rng(20261121 + len(name))
    fmu = open_fmu(name, kind="ME")
    n = 2 * len(q)
    derivatives = (ctypes.c_double * n)()
    for _ in range(25):
        point = random_point(name, rng)
        assert fmu.call("fmi2Reset") == 0
        fmu.initialize(**point)
        assert fmu.call("fmi2GetDerivatives", derivatives, n) == 0
        expected = reference(*[point[k] for k in names])
        k = len(q)
        got_acc, exp_acc = np.array(derivatives[k:]), np.array(expected[:k])
        assert np.allclose(derivatives[:k], [point[s] for s in qd], rtol=0, atol=0)
        assert np.allclose(got_acc, exp_acc, rtol=1e-11, atol=1e-11 * (1 + np.max(np.abs(exp_acc)))), point
        E_kin, E_pot, *coordinates = fmu.get("E_kin", "E_pot", *positions)
        assert math.isclose(E_kin, expected[k], rel_tol=1e-12, abs_tol=1e-12)
        assert math.isclose(E_pot, expected[k + 1], rel_tol=1e-12, abs_tol=1e-11)
        assert np.allclose(coordinates, expected[k + 2:], rtol=1e-13, atol=1e-13)


def test_thesis_misprint_in_5_35_would_be_caught():
    """The printed b2 of (5.35) uses phi2-dot squared and sin(phi1): it differs from the Lagrange
    result, which the corrected b2 matches."""
    m1, m2, s2, l1, phi1, phi2, w1, w2 = sp.symbols("m1 m2 s2 l1 phi1 phi2 w1 w2")
    printed = (m2 / m1) * (s2 / l1) * w2 ** 2 * sp.sin(phi1 - phi2) - (m2 / m1) * (s2 / l1) * (g / l1) * sp.sin(phi1)
    corrected = (m2 / m1) * (s2 / l1) * w1 ** 2 * sp.sin(phi1 - phi2) - (m2 / m1) * (s2 / l1) * (g / l1) * sp.sin(phi2)
    # The corrected b2 is the Lagrange right-hand side of link 2, (m2 s2 l1 w1^2 sin D - m2 s2 g sin phi2),
    # scaled by 1 / (m1 l1^2).
    lagrange_rhs2 = m2 * s2 * l1 * w1 ** 2 * sp.sin(phi1 - phi2) - m2 * s2 * g * sp.sin(phi2)
    assert sp.simplify(corrected - lagrange_rhs2 / (m1 * l1 ** 2)) == 0
    assert sp.simplify(printed - lagrange_rhs2 / (m1 * l1 ** 2)) != 0


@pytest.mark.parametrize("name", list(MODELS))
def test_the_hand_coded_equations_match_the_sympy_derivation(name):
    names, function, positions, q, qd = derived_model(name)
    rng = np.random.default_rng(7)
    for _ in range(40):
        values = random_point(name, rng)
        values.update(F_x=0.0, F_y=0.0)
        pendulum = Pendulum(name, values, [values[s] for s in STATES[name]])
        expected = function(*[values[n] for n in names])
        got = pendulum.rhs(0.0, pendulum.start)
        n = len(q)
        assert np.allclose(got[n:], expected[:n], rtol=1e-11, atol=1e-11)
        tip = pendulum.outer_mass(np.array([pendulum.start]))[0]
        assert np.allclose(tip, expected[-2:], rtol=1e-12, atol=1e-12)
