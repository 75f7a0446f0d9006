"""Every tableau the FMUs are built with satisfies the Runge-Kutta order conditions of its order
(and fails one of the next order); every Adams-Bashforth set is exact on polynomials of its degree."""
from __future__ import annotations

import functools
import json
import subprocess
import xml.etree.ElementTree as ET
from fractions import Fraction

import numpy as np
import pytest

from harness.fmi.fmus import PROJECT_ROOT, build_dir, build_fmus

EXPECTED_ORDER = {"euler": 1, "midpoint": 2, "heun": 2, "rk3": 3, "rk4": 4, "nystrom5": 5, "rkf45": 4}
IMPLICIT_ORDER = {"implicit_midpoint": 2, "gauss_legendre4": 4}


@pytest.fixture(scope="module")
def tables() -> dict:
    build_fmus()
    output = subprocess.run([str(build_dir() / "bin" / "integrator_tables")], check=True, capture_output=True,
                            text=True).stdout
    return json.loads(output)


@functools.lru_cache(maxsize=None)
def rooted_trees(order: int) -> tuple:
    """All rooted trees with `order` nodes; a tree is the sorted tuple of its subtrees."""
    if order == 1:
        return ((),)
    result = set()

    def forests(remaining: int, smallest: tuple) -> list:
        if remaining == 0:
            return [()]
        found = []
        for first_order in range(1, remaining + 1):
            for subtree in rooted_trees(first_order):
                if (first_order, subtree) < smallest:
                    continue
                for rest in forests(remaining - first_order, (first_order, subtree)):
                    found.append((subtree,) + rest)
        return found

    for forest in forests(order - 1, (0, ())):
        result.add(tuple(sorted(forest, key=repr)))
    return tuple(sorted(result, key=repr))


def tree_order(tree: tuple) -> int:
    return 1 + sum(tree_order(child) for child in tree)


def density(tree: tuple) -> int:
    value = tree_order(tree)
    for child in tree:
        value *= density(child)
    return value


def stage_weights(tree: tuple, a: np.ndarray) -> np.ndarray:
    weights = np.ones(a.shape[0])
    for child in tree:
        weights = weights * (a @ stage_weights(child, a))
    return weights


def satisfied_order(a: np.ndarray, b: np.ndarray, limit: int = 7) -> int:
    """Largest p such that b . Phi(t) = 1/gamma(t) for every tree t with at most p nodes."""
    for order in range(1, limit + 1):
        for tree in rooted_trees(order):
            if abs(b @ stage_weights(tree, a) - 1.0 / density(tree)) > 1e-12:
                return order - 1
    return limit


def test_tree_counts():
    # 1, 1, 2, 4, 9, 20 rooted trees of orders 1..6 (OEIS A000081): the generator is complete.
    assert [len(rooted_trees(n)) for n in range(1, 7)] == [1, 1, 2, 4, 9, 20]


def test_solver_order_matches_the_xml_enumeration(tables):
    root = ET.parse(PROJECT_ROOT / "build" / "generated" / "SimplePendulum" / "modelDescription.xml").getroot()
    items = [item.get("name") for item in root.iter("Item") if item.get("name") in tables]
    assert items == list(tables) == ["euler", "midpoint", "heun", "rk3", "rk4", "rkf45", "nystrom5",
                                     "ab2", "ab3", "ab4", "ab5", "ab6",
                                     "implicit_midpoint", "gauss_legendre4", "stormer_verlet",
                                     "abm2", "abm3", "abm4", "abm5", "abm6", "trapezoid", "taylor", "gbs"]


@pytest.mark.parametrize("name", list(EXPECTED_ORDER))
def test_runge_kutta_order_conditions(tables, name):
    t = tables[name]
    a, b, c = np.array(t["a"]), np.array(t["b"]), np.array(t["c"])
    assert np.allclose(a.sum(axis=1), c, atol=1e-15), "c_i must be the row sums of A"
    assert np.allclose(np.triu(a), 0.0), "explicit methods have a strictly lower-triangular A"
    assert t["order"] == EXPECTED_ORDER[name]
    assert satisfied_order(a, b) == EXPECTED_ORDER[name]


@pytest.mark.parametrize("name", list(IMPLICIT_ORDER))
def test_implicit_methods_order_symmetry_and_update(tables, name):
    """The Gauss-Legendre tableaux: order conditions of their order (and not the next), symmetric
    (c_i + c_(s+1-i) = 1 and a_ij + a_(s+1-i)(s+1-j) = b_j, so that the adjoint method is the method
    itself), and the update weights d = b^T A^-1 that spare the evaluation after the Newton solve."""
    t = tables[name]
    a, b, c, d = np.array(t["a"]), np.array(t["b"]), np.array(t["c"]), np.array(t["d"])
    assert t["implicit"] and t["order"] == IMPLICIT_ORDER[name]
    assert np.allclose(a.sum(axis=1), c, atol=1e-15)
    assert satisfied_order(a, b) == IMPLICIT_ORDER[name]
    assert np.allclose(c + c[::-1], 1.0, atol=1e-15)
    assert np.allclose(a + a[::-1, ::-1], np.broadcast_to(b, a.shape), atol=1e-15)
    assert np.allclose(d, b @ np.linalg.inv(a), atol=1e-14)
    # Collocation at the Gauss points: the c_i are the roots of the shifted Legendre polynomial.
    legendre = np.polynomial.legendre.Legendre.basis(len(c), domain=[0, 1])
    assert np.allclose(legendre(c), 0.0, atol=1e-14)


def test_the_trapezoid_rule_is_thesis_4_9(tables):
    """x1 = x0 + h/2 (f(x0) + f(x1)): a first stage at the step's start with a zero row of A (explicit,
    evaluated once), a last stage at its end with the row b (stiffly accurate: x1 = x0 + Z_2, the
    update d = (0, 1), since A is singular), symmetric, order 2 and not 3, and A-stable:
    R(z) = (1 + z/2) / (1 - z/2) on the imaginary axis has modulus 1."""
    t = tables["trapezoid"]
    a, b, c, d = np.array(t["a"]), np.array(t["b"]), np.array(t["c"]), np.array(t["d"])
    assert t["implicit"] and t["order"] == 2
    assert list(c) == [0.0, 1.0] and list(a[0]) == [0.0, 0.0] and list(a[1]) == list(b) == [0.5, 0.5]
    assert list(d) == [0.0, 1.0]
    assert satisfied_order(a, b) == 2
    assert np.allclose(a + a[::-1, ::-1], np.broadcast_to(b, a.shape), atol=1e-15)
    for z in (-1e3, -1.0, -1e-3, 2j, 50j):
        stability = 1 + z * b @ np.linalg.solve(np.eye(2) - z * a, np.ones(2))
        assert stability == pytest.approx((1 + z / 2) / (1 - z / 2), rel=1e-14)
        assert abs(stability) <= 1 + 1e-14


def test_explicit_tableaux_say_so(tables):
    explicit = [name for name, t in tables.items() if "a" in t and not t["implicit"]]
    assert sorted(explicit) == sorted(EXPECTED_ORDER)


def test_fehlberg_partner_is_fifth_order(tables):
    t = tables["rkf45"]
    a, b, e = np.array(t["a"]), np.array(t["b"]), np.array(t["e"])
    assert satisfied_order(a, b + e) == 5


def test_thesis_misprints_would_fail():
    """The printed Kutta-Nystrom coefficients (a21 = 1/4, a52 = -90/81, a62 = -36/75) are not order 5."""
    a = np.array([[0, 0, 0, 0, 0, 0], [1 / 4, 0, 0, 0, 0, 0], [4 / 25, 6 / 25, 0, 0, 0, 0],
                  [1 / 4, -3, 15 / 4, 0, 0, 0], [2 / 27, -90 / 81, -50 / 81, 8 / 81, 0, 0],
                  [2 / 25, -36 / 75, 2 / 15, 8 / 75, 0, 0]])
    b = np.array([23, 0, 125, 0, -81, 125]) / 192
    assert satisfied_order(a, b) < 5


@pytest.mark.parametrize("name,steps", [(f"{kind}{k}", k) for kind in ("ab", "abm") for k in range(2, 7)])
def test_adams_bashforth_exact_on_polynomials(tables, name, steps):
    ab = tables[name]
    beta = [Fraction(x).limit_denominator(2000) for x in ab["beta"]]
    assert all(abs(float(f) - x) < 1e-15 for f, x in zip(beta, ab["beta"]))
    # int_0^1 s^(q-1) ds = 1/q = sum_j beta_j (-j)^(q-1): exact for degree < steps, not for degree = steps.
    moments = [sum(bj * Fraction(-j) ** (q - 1) for j, bj in enumerate(beta)) for q in range(1, steps + 2)]
    assert moments[:steps] == [Fraction(1, q) for q in range(1, steps + 1)]
    assert moments[steps] != Fraction(1, steps + 1)
    assert ab["steps"] == steps
    # The start must match the order: a Runge-Kutta method of order >= steps - 1.
    assert EXPECTED_ORDER[ab["starter"]] >= steps - 1


@pytest.mark.parametrize("steps", range(2, 7))
def test_adams_moulton_correctors_are_exact_on_polynomials(tables, steps):
    """The corrector of abm<k>: int_0^1 p(s) ds = m_0 p(1) + sum_j m_(j+1) p(-j), exact for degree < k
    (order k), not for degree k; its predictor is ab<k>'s."""
    abm = tables[f"abm{steps}"]
    m = [Fraction(x).limit_denominator(2000) for x in abm["moulton"]]
    assert all(abs(float(f) - x) < 1e-15 for f, x in zip(m, abm["moulton"]))
    nodes = [1] + [-j for j in range(steps - 1)]
    moments = [sum(mj * Fraction(node) ** (q - 1) for mj, node in zip(m, nodes)) for q in range(1, steps + 2)]
    assert moments[:steps] == [Fraction(1, q) for q in range(1, steps + 1)]
    assert moments[steps] != Fraction(1, steps + 1)
    assert abm["beta"] == tables[f"ab{steps}"]["beta"]
    # The start at the method's own order where one exists (nystrom5 at most): the PECE error constant is
    # small, and a start one order lower would dominate it over a short run.
    assert EXPECTED_ORDER[abm["starter"]] >= min(steps, 5)
