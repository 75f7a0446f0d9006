"""The Taylor method's code generation (harness.objects.taylor_code): the products of sines and cosines it
contracts keep their value, the contraction pays where it is taken, and the generated recurrences give the
Taylor coefficients of an independent computation (SymPy's series of the same equations)."""
from __future__ import annotations

import random

import numpy as np
import pytest
import sympy as sp

from harness.objects.registry import constrained_names, object_names
from harness.objects.taylor_code import contract_trigonometry, taylor_code

FREE = [name for name in object_names() if name not in constrained_names()]


def test_the_difference_of_two_angles_comes_back():
    a, b, c = sp.symbols("a b c", real=True)
    m = sp.Symbol("m", positive=True)
    expanded = m * (sp.cos(a) * sp.cos(b) + sp.sin(a) * sp.sin(b))
    assert contract_trigonometry(expanded, {a, b}, {a, b}) == m * sp.cos(a - b)
    # a lone product has no partner to cancel with: it becomes two terms, and the generator keeps the product
    lone = contract_trigonometry(sp.sin(a) * sp.cos(b), {a, b}, {a, b})
    assert sp.simplify(lone - sp.sin(a) * sp.cos(b)) == 0
    # three angles, a square, and a factor that is no angle's
    three = sp.sin(a) * sp.cos(b) * sp.cos(c) ** 2 * m * sp.exp(c)
    assert sp.simplify(contract_trigonometry(three, {a, b, c}, {a, b, c}) - three) == 0


@pytest.mark.parametrize("name", FREE)
def test_contraction_keeps_every_equation(derivation, name):
    """Every entry of M and f of every object without contacts: the contracted expression equals the derived
    one at random points (all symbols drawn)."""
    derived = derivation(name)
    spec = derived.spec
    angles = set(spec.q) | {spec.time}
    states = angles | set(spec.v) | set(derived.inputs)
    rng = random.Random(7)
    for expr in list(derived.M) + list(derived.f) + list(derived.Q):
        contracted = contract_trigonometry(expr, angles, states)
        symbols = sorted(expr.free_symbols | contracted.free_symbols, key=str)
        for _ in range(5):
            point = {s: rng.uniform(0.2, 1.7) for s in symbols}
            exact, value = float(expr.subs(point)), float(contracted.subs(point))
            assert value == pytest.approx(exact, rel=1e-12, abs=1e-12 * (1 + abs(exact))), (name, expr)


def test_the_double_pendulum_takes_fewer_convolutions(derivation):
    """The double pendulum's mass matrix and forcing hold cos(phi1 - phi2) and sin(phi1 - phi2) expanded
    into four products of sines and cosines of the angles: contracted, the recurrences need fewer inner sums
    per order (the generator takes whichever variant has fewer)."""
    derived = derivation("DoublePendulum")
    spec = derived.spec
    angles = set(spec.q)
    states = angles | set(spec.v) | set(derived.inputs)
    variables = {s: f"x[{j}]" for j, s in enumerate(spec.q + spec.v)}
    upper = {(i, j): derived.M[i, j] for i in range(2) for j in range(i + 1)}

    def cost(variant):
        return taylor_code(2, {key: variant(e) for key, e in upper.items()}, False, [variant(e) for e in derived.f],
                           [], variables).cost
    as_derived, contracted = cost(lambda e: e), cost(lambda e: contract_trigonometry(e, angles, states))
    assert contracted < as_derived - 1, (contracted, as_derived)


def _series_by_sympy(derived, order: int, start: dict) -> list[list[float]]:
    """Taylor coefficients 0 ... order of q and v at t = 0 by repeated differentiation along the motion."""
    spec = derived.spec
    n = derived.n
    values = {spec.symbols[p.name]: p.start for p in spec.parameters if p.name in spec.symbols}
    a = derived.M.subs(values).LUsolve(derived.f.subs(values))
    damping = values.get(spec.symbols["d"], 0.0)
    rates = list(spec.v) + [a[j] - damping * spec.v[j] for j in range(n)]
    variables = list(spec.q) + list(spec.v)
    current = list(variables)
    coefficients = [[float(e.subs(start))] for e in current]
    factorial = 1.0
    for k in range(1, order + 1):
        # d/dt of each expression along x' = rates(x, t)
        current = [sp.diff(e, spec.time) + sum(sp.diff(e, x) * r for x, r in zip(variables, rates)) for e in current]
        factorial *= k
        for i, e in enumerate(current):
            coefficients[i].append(float(e.subs(start).subs(spec.time, 0.0).evalf()) / factorial)
    return coefficients


@pytest.mark.parametrize("name", ["SimplePendulum", "CartPendulum", "SpringPendulum", "KapitzaPendulum"])
def test_the_fmu_coefficients_are_sympys(open_fmu, derivation, name):
    """One Taylor step of order 6 from the default start, at a step of 0.1 s, against the sum of SymPy's own
    series of the same equations (coefficients by differentiating along the motion): equal to rounding, so
    every recurrence the generator wrote (sines and cosines, products, quotients, the mass matrix's solve)
    gives its coefficients."""
    derived = derivation(name)
    spec = derived.spec
    start = {s: c.start for s, c in zip(spec.q, spec.coordinates)}
    start.update({s: c.velocity_start for s, c in zip(spec.v, spec.coordinates)})
    order, h = 6, 0.1
    coefficients = _series_by_sympy(derived, order, start)
    expected = [sum(c * h ** k for k, c in enumerate(row)) for row in coefficients]
    fmu = open_fmu(name)
    fmu.initialize(solver="taylor", taylor_order=order, tol=0.0, h=h)
    assert fmu.do_step(0.0, h) == 0
    names = [c.name for c in spec.coordinates] + [c.velocity for c in spec.coordinates]
    got = fmu.get(*names)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-13)
