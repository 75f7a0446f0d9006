"""What the stability atlas claims: measured limits within 5% of the prediction in every linear case,
the predictions themselves right (against SPEC's table and closed forms), and the criterion able to
tell a stable run from an unstable one."""
from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from harness.cli import main
from harness.fmi.methods import IMPLICIT
from harness.fmi.fmus import build_dir
from harness.studies.stability import (ATLAS_METHODS, GROWTH_LIMIT, QUICK_DAMPING_RATIOS, PERIODS, Case, Probe,
                                       extrapolated_midpoint, growth, linearized_eigenvalues, method_tables, read_csv,
                                       simple_cases, theory_limit, verlet_matrix)

MODAL_OBJECTS = ("DoublePendulum", "SpringPendulum", "CartPendulum", "Chain3", "Chain5", "ElasticDoublePendulum")


@pytest.fixture(scope="module")
def atlas(fmu_paths, tmp_path_factory):
    """Every object, the simple pendulum on the quick damping rays: undamped, underdamped and overdamped (the
    default's five more rays between them measure the same code, at five minutes of the suite)."""
    out = tmp_path_factory.mktemp("stability")
    assert main(["chart", "stability", "--quick", "--out", str(out)]) == 0
    return out, read_csv(out / "stability.csv")


def test_the_files_and_the_columns(atlas):
    out, limits = atlas
    with open(out / "stability.csv") as handle:
        assert next(csv.reader(handle))[:5] == ["object", "method", "damping", "measured_limit", "theory_limit"]
    for stem in ("stability-regions", "stability-limits"):
        for suffix in ("png", "svg"):
            assert (out / f"{stem}.{suffix}").stat().st_size > 10_000
    cases = {(x.object, x.damping, x.release) for x in limits}
    assert ("SimplePendulum", 0.0, 0.01) in cases and ("SimplePendulum", 0.0, 3.0) in cases
    omega0 = math.sqrt(9.81)
    assert any(x.object == "SimplePendulum" and x.damping == pytest.approx(20 * omega0) for x in limits)
    # Every object with a stable, regular rest state; not the spherical pendulum (its mass matrix is
    # singular at rest) nor Kapitza's (driven).
    for name in MODAL_OBJECTS:  # stormer_verlet only where the mass matrix is constant
        assert {x.method for x in limits if x.object == name} == set(ATLAS_METHODS) - {"stormer_verlet"}
    assert not {x.object for x in limits} & {"SphericalPendulum", "KapitzaPendulum"}


def test_measured_limits_agree_with_the_prediction_in_the_linear_cases(atlas):
    linear = [x for x in atlas[1] if x.release < 1]
    assert len(linear) == len(QUICK_DAMPING_RATIOS) * len(ATLAS_METHODS) + len(MODAL_OBJECTS) * (len(ATLAS_METHODS) - 1)
    for x in linear:
        if math.isinf(x.theory_limit):  # A-stable: stable at any step the Newton iteration converges at
            assert x.method in IMPLICIT and x.measured_limit >= 100, x
        elif x.method == "stormer_verlet" and x.damping > 2 * math.sqrt(9.81):
            # overdamped: the mode that grows first is the step's parasitic one (eigenvalue near -1),
            # which a release from rest barely excites; the worst-case prediction is then a lower bound
            assert x.theory_limit * 0.95 <= x.measured_limit <= x.theory_limit * 1.15, x
        else:
            assert x.measured_limit == pytest.approx(x.theory_limit, rel=0.05), (x.object, x.method, x.damping)


def test_nonlinear_limits_are_measured_without_a_prediction(atlas):
    nonlinear = [x for x in atlas[1] if x.release == 3.0]
    assert len(nonlinear) == len(ATLAS_METHODS)
    assert all(math.isnan(x.theory_limit) and x.measured_limit > 0 for x in nonlinear)


def test_multi_body_limits_are_the_simple_pendulums_on_their_fastest_mode(atlas):
    """Released in its fastest normal mode, each object has the limit of the undamped linear
    oscillator in h*omega_max: the same predicted value as the simple pendulum's."""
    undamped = {x.method: x for x in atlas[1] if x.object == "SimplePendulum" and x.damping == 0 and x.release < 1}
    for x in atlas[1]:
        if x.object != "SimplePendulum":
            assert x.theory_limit == pytest.approx(undamped[x.method].theory_limit, rel=1e-9)


def hand_derived_squares(kind: str, p: dict[str, float]) -> list[float]:
    """omega^2 of the thesis pendulums about rest, linearized by hand (not from the object files)."""
    if kind == "SimplePendulum":
        return [p["g"] / p["L"]]
    if kind == "SpringPendulum":  # hanging at rest the swing and the spring decouple
        stretch = p["m"] * p["g"] / p["D"]
        return [p["g"] / (p["l0"] + stretch), p["D"] / p["m"]]
    mass = np.array([[p["m1"] * p["s1"] ** 2 + p["J1"] + p["m2"] * p["l1"] ** 2, p["m2"] * p["l1"] * p["s2"]],
                     [p["m2"] * p["l1"] * p["s2"], p["m2"] * p["s2"] ** 2 + p["J2"]]])
    stiffness = np.diag([(p["m1"] * p["s1"] + p["m2"] * p["l1"]) * p["g"], p["m2"] * p["s2"] * p["g"]])
    return sorted(np.linalg.eigvals(np.linalg.solve(mass, stiffness)).real)


@pytest.mark.parametrize("kind", ["SimplePendulum", "DoublePendulum", "SpringPendulum"])
def test_normal_modes_from_the_energies_match_the_hand_linearization(kind):
    rng = np.random.default_rng(3)
    names = {"SimplePendulum": ("g", "L"), "SpringPendulum": ("g", "m", "D", "l0"),
             "DoublePendulum": ("g", "m1", "m2", "J1", "J2", "s1", "s2", "l1")}[kind]
    for _ in range(5):
        p = {name: rng.uniform(0.3, 3.0) for name in names}
        d = rng.uniform(0.0, 0.5)
        def order(z: complex) -> tuple:
            return round(abs(z), 9), z.imag
        got = sorted(linearized_eigenvalues(kind, {**p, "d": d}), key=order)
        expected = sorted([(-d + s * complex(d * d - 4 * w2) ** 0.5) / 2 for w2 in hand_derived_squares(kind, p)
                           for s in (1, -1)], key=order)
        assert np.allclose(got, expected, rtol=1e-12), (got, expected)


# The predictions, checked independently of the FMUs.
SPEC_REAL_AXIS = {"euler": 2, "midpoint": 2, "heun": 2, "rk3": 2.513, "rk4": 2.785, "nystrom5": 3.22,
                  "ab2": 1, "ab3": 0.545, "ab4": 0.300, "ab5": 0.163, "ab6": 0.088}
SPEC_IMAGINARY_AXIS = {"rk3": math.sqrt(3), "rk4": 2 * math.sqrt(2), "ab3": 0.72, "ab4": 0.43}


def boundary(method: str, direction: complex) -> float:
    """Largest r with growth(r * direction) <= 1 (+ rounding), from r = 0 outward."""
    table = method_tables()[method]
    r = 1e-3
    while growth(table, (r * 1.001) * direction) <= 1 + 1e-12 and r < 10:
        r *= 1.001
    return r


@pytest.mark.parametrize("columns", [1, 2, 3, 4, 8])
def test_the_extrapolated_midpoint_polynomial_is_the_exponential_to_order_2k(columns):
    """gbs's R(z) at column k, read off as a polynomial by its values on the unit circle (a discrete
    Fourier transform): degree 2k, its coefficients 1/m! up to z^(2k), as a method of order 2k needs."""
    points = 64
    z = np.exp(2j * np.pi * np.arange(points) / points)
    coefficients = np.fft.fft(extrapolated_midpoint(z, columns)) / points
    expected = [1 / math.factorial(m) for m in range(2 * columns + 1)]
    assert np.allclose(coefficients[:2 * columns + 1], expected, rtol=0, atol=1e-13)
    assert np.max(np.abs(coefficients[2 * columns + 1:])) < 1e-13  # nothing above z^(2k)


@pytest.mark.parametrize("method", SPEC_REAL_AXIS)
def test_real_axis_boundaries_are_the_contracts(method):
    assert boundary(method, -1) == pytest.approx(SPEC_REAL_AXIS[method], rel=0.01)


@pytest.mark.parametrize("method", IMPLICIT)
def test_the_implicit_methods_are_a_stable_and_keep_the_oscillators_energy(method):
    """R(z) of the Gauss methods and the trapezoid rule: |R| <= 1 on the whole left half-plane (the scan
    stops at its cap, 10), |R(iy)| = 1 on the imaginary axis (no damping added, none removed), and the Pade forms
    (1 + z/2) / (1 - z/2) and (1 + z/2 + z^2/12) / (1 - z/2 + z^2/12) at sample points."""
    table = method_tables()[method]
    assert boundary(method, -1) > 9.9 and boundary(method, 1j) > 9.9 and boundary(method, -1 + 1j) > 9.9
    for y in (0.1, 1.0, 5.0, 50.0):
        assert growth(table, 1j * y) == pytest.approx(1.0, abs=1e-12)
    pade = {"implicit_midpoint": lambda z: (1 + z / 2) / (1 - z / 2), "trapezoid": lambda z: (1 + z / 2) / (1 - z / 2),
            "gauss_legendre4": lambda z: (1 + z / 2 + z * z / 12) / (1 - z / 2 + z * z / 12)}[method]
    for z in (-0.3 + 2j, -4 + 0.5j, 1.5 + 1j):
        assert growth(table, z) == pytest.approx(abs(pade(z)), rel=1e-12)


def test_stormer_verlet_is_stable_below_h_omega_2_on_the_oscillator():
    """The leapfrog condition h omega < 2 (undamped); within it the step matrix has determinant 1 and
    eigenvalues on the unit circle, beyond it one outside."""
    for h_omega in (0.5, 1.0, 1.9, 1.99):
        assert growth(method_tables()["stormer_verlet"], 1j * h_omega) == pytest.approx(1.0, abs=1e-12)
        assert np.linalg.det(verlet_matrix(h_omega ** 2, 0.0)) == pytest.approx(1.0, abs=1e-12)
    assert growth(method_tables()["stormer_verlet"], 2.01j) > 1.1
    assert boundary("stormer_verlet", 1j) == pytest.approx(2.0, rel=0.01)


@pytest.mark.parametrize("method", sorted(SPEC_IMAGINARY_AXIS))
def test_imaginary_axis_boundaries_are_the_contracts(method):
    assert boundary(method, 1j) == pytest.approx(SPEC_IMAGINARY_AXIS[method], rel=0.01)


def test_window_limits_have_closed_forms_for_euler_and_midpoint():
    """|R(iy)|^2 = 1 + y^2 (euler) and 1 + y^4/4 (midpoint); N = 200 pi / y steps; 1.5 x energy:
    N ln(1 + y^2) = ln 1.5 and N ln(1 + y^4/4) = ln 1.5."""
    from scipy.optimize import brentq
    undamped = Case("SimplePendulum", 0.0, 0.01, 1.0, eigenvalues=(1j, -1j))
    steps = lambda y: PERIODS * 2 * math.pi / y  # noqa: E731
    euler = brentq(lambda y: steps(y) * math.log1p(y * y) - math.log(GROWTH_LIMIT), 1e-6, 1)
    midpoint = brentq(lambda y: steps(y) * math.log1p(y ** 4 / 4) - math.log(GROWTH_LIMIT), 1e-3, 1)
    tables = method_tables()
    assert theory_limit(tables["euler"], undamped) == pytest.approx(euler, rel=1e-6)
    assert theory_limit(tables["midpoint"], undamped) == pytest.approx(midpoint, rel=1e-6)


def test_the_criterion_separates_stable_from_unstable(fmu_paths):
    """rk4 on the undamped pendulum: 10% below the prediction the energy stays, 10% above it grows."""
    case = simple_cases(build_dir() / "fmus" / "SimplePendulum.fmu", ratios=(0.0,))[0]
    limit = theory_limit(method_tables()["rk4"], case)
    probe = Probe(str(fmu_paths["SimplePendulum"]), case, "rk4")
    try:
        assert probe.stable(round(case.window * case.omega / (0.9 * limit)))
        assert not probe.stable(round(case.window * case.omega / (1.1 * limit)))
    finally:
        probe.close()


def test_adams_bashforth_growth_is_the_largest_root():
    """ab2 at z: roots of zeta^2 - (1 + 3z/2) zeta + z/2."""
    z = 0.3 + 0.4j
    roots = np.roots([1, -(1 + 1.5 * z), 0.5 * z])
    assert growth(method_tables()["ab2"], z) == pytest.approx(max(abs(roots)), rel=1e-12)


@pytest.mark.parametrize("k", range(2, 7))
def test_the_predictor_corrector_theory_is_the_recursion_run(k):
    """abm<k>'s growth from its characteristic polynomial equals the growth per step of its PECE
    recursion run on y' = lambda y (h = 1): predict with ab<k>, evaluate, correct, evaluate."""
    table = method_tables()[f"abm{k}"]
    beta, moulton = table["beta"], table["moulton"]
    rng = np.random.default_rng(k)
    for z in (-0.2, -0.9, -1.6, 0.4j, 1.1j, -0.6 + 0.7j, -1.2 + 0.3j):
        f = list(z * rng.normal(size=k))  # f(k), f(k-1), ...: the history of z y
        y, log_size, logs = 1.0 + 0j, 0.0, []
        for n in range(4000):
            predicted = y + sum(b * fj for b, fj in zip(beta, f))
            y = y + moulton[0] * z * predicted + sum(m * fj for m, fj in zip(moulton[1:], f))
            f = [z * y] + f[:-1]
            scale = max(abs(y), *map(abs, f))  # kept near 1: the logarithm carries the size
            y, f, log_size = y / scale, [fj / scale for fj in f], log_size + math.log(scale)
            logs.append(log_size)
        rate = math.exp((logs[-1] - logs[-1001]) / 1000)
        assert rate == pytest.approx(growth(table, z), rel=2e-3), z


def test_the_growth_as_arrays_is_the_growth_point_by_point():
    """The charts' regions and the predicted limits' scan take the growth as arrays; it is the scalar
    growth at every point (pairs of roots for Stormer-Verlet, an underdamped and an overdamped pair)."""
    from harness.studies.stability import atlas_tables, growth_on_grid, largest_growth, largest_growth_on_grid
    rng = np.random.default_rng(5)
    z = rng.uniform(-3, 1, 40) + 1j * rng.uniform(-3, 3, 40)
    for name, table in atlas_tables().items():
        if table.get("partitioned"):
            pairs = np.array([[0.7j - 0.1, -0.7j - 0.1], [-0.2, -1.9], [1.2j, -1.2j]])
            expected = [largest_growth(table, list(pair)) for pair in pairs]
            assert np.allclose(largest_growth_on_grid(table, pairs), expected, rtol=1e-12, atol=0), name
            with pytest.raises(ValueError):
                largest_growth_on_grid(table, pairs[:, :1])
            continue
        expected = [growth(table, complex(w)) for w in z]
        assert np.allclose(growth_on_grid(table, z), expected, rtol=1e-12, atol=0), name
        assert largest_growth_on_grid(table, z.reshape(8, 5))[3] == pytest.approx(max(expected[15:20]), rel=1e-12)
