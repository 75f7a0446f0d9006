"""Objects from their energies: bad object files, the generated equations against an independent
numeric route, and `harness derive` end to end. Nothing here is specific to one object: every
object file in the registry is checked the same way."""
from __future__ import annotations

import math

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description

from harness.fmi.methods import SOLVERS
from harness.objects.derivation import derive
from harness.objects.build import derive_fmu
from harness.objects.proof import numeric_route_agreement, object_file_in, observed_order, prove
from harness.objects.object_file import ObjectFileError, read_object_file
from harness.objects.registry import object_file, object_names

CART_PENDULUM = '''
identifier = "CartPendulumTest"
description = "A pendulum hanging from a cart on a rail"
[parameters]
M = { start = 2.0, unit = "kg", min = 1e-9 }
m = { start = 0.5, unit = "kg", min = 1e-9 }
l = { start = 0.8, unit = "m", min = 1e-9 }
g = { start = 9.81, unit = "m/s2", min = 0.0 }
[coordinates]
x = { start = 0.0, unit = "m", velocity = "v" }
phi = { start = 0.5, unit = "rad", velocity = "omega" }
[energy]
T = "M/2*v**2 + m/2*((v + l*omega*cos(phi))**2 + (l*omega*sin(phi))**2)"
U = "-m*g*l*cos(phi)"
[points]
cart = { x = "x", y = "0" }
bob = { x = "x + l*sin(phi)", y = "-l*cos(phi)" }
[forces]
push = { point = "cart" }
'''


def write(tmp_path: Path, text: str, name: str = "CartPendulumTest.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("old,new,key,problem", [
    ('U = "-m*g*l*cos(phi)"', 'U = "-m*g*l*cos(psi)"', "energy.U", "unknown symbol 'psi'"),
    (', velocity = "omega" }', ' }', "coordinates.phi.velocity", "missing"),
    ('T = "M/2*v**2', 'T = "M/2*v**4', "energy.T", "not quadratic in the velocities"),
    ('T = "M/2*v**2', 'T = "-M/2*v**2 - 10*', "energy.T", "not positive in the velocities"),
    ('l = { start = 0.8', 'omega = { start = 0.8', "coordinates.phi.velocity", "'omega' is already used"),
    ('m = { start = 0.5', 'm = { start = "heavy"', "parameters.m.start", "must be a finite number"),
    ('U = "-m*g*l*cos(phi)"', 'U = "-m*g*l*cos(phi)^2"', "energy.U", "write powers as **"),
    ('U = "-m*g*l*cos(phi)"', 'U = "-m*g*omega"', "energy.U", "'omega' may not appear here"),
    ('U = "-m*g*l*cos(phi)"', 'U = "__import__(1)"', "energy.U", "'__' is not allowed"),
    ('push = { point = "cart" }', 'push = { point = "wheel" }', "forces.push.point", "'wheel' is not one of"),
    ('cart = { x = "x", y = "0" }', 'cart = { x = "x", y = "0", names = { x = "E" } }', "points.cart.names.x",
     "every object already has"),
    ('[parameters]', 'require = ["0"]\n[parameters]', "require[0]", "depends on no parameter or coordinate"),
    ('U = "-m*g*l*cos(phi)"', 'U = "' + "sin(" * 150 + "phi" + ")" * 150 + '"', "energy.U",
     "parentheses nested 150 deep (at most 100)"),
    ('U = "-m*g*l*cos(phi)"', 'U = "' + "(" * 250 + "phi" + ")" * 250 + '"', "energy.U",
     "parentheses nested 250 deep (at most 100)"),
])
def test_a_bad_object_file_gets_one_line_naming_file_key_and_problem(tmp_path, old, new, key, problem):
    assert old in CART_PENDULUM
    path = write(tmp_path, CART_PENDULUM.replace(old, new, 1))
    with pytest.raises(ObjectFileError) as error:
        derive(read_object_file(path))
    message = str(error.value)
    assert "\n" not in message and message.startswith(f"{path}: {key}: ") and problem in message, message


def test_derive_refuses_a_bad_file_with_exit_code_2_and_leaves_nothing(tmp_path):
    path = write(tmp_path, CART_PENDULUM.replace('U = "-m*g*l*cos(phi)"', 'U = "-m*g*l*cos(psi)"'))
    scratch = tmp_path / "scratch"  # the command's temporary folder: other runs use the system's
    scratch.mkdir()
    result = subprocess.run([sys.executable, "-m", "harness", "derive", str(path), "--out", str(tmp_path / "out")],
                            capture_output=True, text=True, env={**os.environ, "TMPDIR": str(scratch)})
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.count("\n") == 1 and "energy.U: unknown symbol 'psi'" in result.stderr, result.stderr
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
    assert list(scratch.iterdir()) == []


@pytest.fixture(scope="module")
def derived_cart(tmp_path_factory) -> tuple[subprocess.CompletedProcess, Path]:
    """`harness derive` of CART_PENDULUM, run once (half a minute): (the command's result, its folder)."""
    folder = tmp_path_factory.mktemp("derived-cart")
    path = write(folder, CART_PENDULUM)
    result = subprocess.run([sys.executable, "-m", "harness", "derive", str(path), "--out", str(folder)],
                            capture_output=True, text=True)
    return result, folder


def test_derive_builds_a_valid_fmu_that_moves_as_the_numeric_route_says(derived_cart):
    from fmpy.validation import validate_fmu
    result, tmp_path = derived_cart
    assert result.returncode == 0, result.stderr
    fmu = tmp_path / "CartPendulumTest.fmu"
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    names = {v.name for v in md.modelVariables}
    assert {"x", "phi", "v", "omega", "push_x", "push_y", "cart_x", "bob_v_y", "E_kin", "E", "model",
            "n_rhs"} <= names
    proof = numeric_route_agreement(fmu, object_file_in(fmu), samples=4)
    assert proof.passed, proof.detail
    # the FMI 3.0 FMU beside it: valid, and the same numbers bit for bit
    import fmpy
    fmi3 = tmp_path / "fmi3" / "CartPendulumTest.fmu"
    assert validate_fmu(str(fmi3)) == [] and read_model_description(str(fmi3)).fmiVersion == "3.0"
    runs = [fmpy.simulate_fmu(str(path), stop_time=2.0, output_interval=0.1, start_values={"push_x": 0.5})
            for path in (fmu, fmi3)]
    assert all(np.array_equal(runs[0][name], runs[1][name]) for name in ("x", "phi", "bob_x", "E"))


@pytest.mark.parametrize("name", object_names())
def test_every_object_proves_itself(fmu_paths, name):
    """The proof `harness validate` runs for any FMU made from an object file: numeric route, every
    fixed-step method (and taylor and gbs with their fixed step) at its order (states and energy), rkf45
    and gbs within their tolerance, Model Exchange with CVode."""
    spec = object_file_in(fmu_paths[name])
    assert spec is not None and spec.identifier == name
    failed = [f"{p.name}: {p.detail}" for p in prove(fmu_paths[name], spec) if not p.passed]
    assert not failed, failed


def test_the_proof_finds_an_fmu_that_does_not_follow_its_object_file(derived_cart, tmp_path):
    """An FMU derived from one potential but carrying a file with another (gravity 1 % stronger)."""
    result, folder = derived_cart
    assert result.returncode == 0, result.stderr
    fmu = folder / "CartPendulumTest.fmu"
    changed = read_object_file(write(tmp_path, CART_PENDULUM.replace("-m*g*l*cos(phi)", "-1.01*m*g*l*cos(phi)"),
                                     "changed.toml"))
    proof = numeric_route_agreement(fmu, changed, samples=3)
    assert not proof.passed and "largest relative deviation of the accelerations" in proof.detail, proof.detail
    deviation = float(proof.detail.split("accelerations ")[1].split(",")[0])
    assert 1e-4 < deviation < 1e-1


def test_a_failing_model_exchange_proof_says_so_and_leaves_no_files(fmu_paths, monkeypatch):
    """fmpy's simulate_fmu leaves the FMU it extracted behind where the run raises: the proof extracts it
    itself and removes it either way."""
    import tempfile
    import fmpy
    from harness.objects.proof import model_exchange_with_cvode

    def failing(filename, **settings):  # as fmpy's does: an archive is extracted, and the folder stays on an error
        if not os.path.isdir(filename):
            fmpy.extract(filename)
        raise Exception("fmi2NewDiscreteStates failed with status 3 (error).\nsecond line")
    monkeypatch.setattr(fmpy, "simulate_fmu", failing)
    before = set(os.listdir(tempfile.gettempdir()))
    proof = model_exchange_with_cvode(fmu_paths["SimplePendulum"], read_object_file(object_file("SimplePendulum")))
    assert not proof.passed and proof.detail == ("fmpy's CVode failed: fmi2NewDiscreteStates failed with "
                                                 "status 3 (error).")
    assert set(os.listdir(tempfile.gettempdir())) == before


def test_the_order_check_tells_a_wrong_order_from_a_right_one():
    steps = [0.1 / 2 ** k for k in range(6)]
    fourth = [3.0 * h ** 4 for h in steps]
    assert observed_order(steps, fourth, 4, at_least=False)[0]
    assert not observed_order(steps, fourth, 5, at_least=False)[0]
    assert not observed_order(steps, fourth, 3, at_least=False)[0]
    assert observed_order(steps, fourth, 3, at_least=True)[0]   # energy may fall faster than the order
    exact = observed_order(steps, [1e-14] * 6, 4, at_least=False)  # exact to rounding: nothing wrong
    assert exact[0] and "exact to rounding" in exact[1]
    assert not observed_order(steps, [1e-14, math.nan, 1e-14, 1e-14, 1e-14, 1e-14], 4, at_least=False)[0]
    assert not observed_order(steps, [0.5, 1e-13, 1e-14, 1e-14, 1e-14, 1e-14], 4, at_least=False)[0]
    slow = [0.05 * s ** 5.61 for s in steps]  # a pre-asymptotic energy slope just under the order
    assert observed_order(steps, slow, 6, at_least=True)[0]
    assert not observed_order(steps, [0.05 * s ** 5.0 for s in steps], 6, at_least=True)[0]


def test_a_kink_in_a_point_expression_generates_c():
    """Abs in a point: the output derivatives differentiate it twice, and the impulse that gives
    (DiracDelta, zero wherever the expression is defined) is written as 0.0, not refused by the printer."""
    import sympy as sp

    from harness.objects.c_code import c_expr, generate_c
    text = object_file("SimplePendulum").read_text()
    text = text.replace('x = "anchor_x + L*sin(phi)"', 'x = "anchor_x + Abs(L*sin(phi))"')
    assert "Abs(" in text
    code = generate_c(derive(read_object_file("kinked.toml", text)))
    assert "DiracDelta" not in code.source and "fabs(" in code.source
    assert c_expr(sp.DiracDelta(sp.Symbol("x"))) == "0.0"


def test_a_derived_slow_pendulum_proves_itself_and_plans_from_its_own_file(tmp_path):
    """The project's pendulum with one number changed (L = 10 m) under a new name: every check of the
    proof passes (methods exact to rounding at this pace pass, pre-asymptotic energy slopes within
    0.5 of the order pass), and the planner linearizes the energies the FMU carries: omega^2 = g/L."""
    from harness.cosim.structure import Component
    from harness.studies.planner import object_eigenvalues
    text = object_file("SimplePendulum").read_text().replace('identifier = "SimplePendulum"',
                                                             'identifier = "LongPendulum"')
    text = text.replace('L = { start = 1.0,', 'L = { start = 10.0,')
    fmu = derive_fmu(write(tmp_path, text, "LongPendulum.toml"), tmp_path / "out").path
    failed = [f"{p.name}: {p.detail}" for p in prove(fmu, object_file_in(fmu)) if not p.passed]
    assert not failed, failed
    eigenvalues = object_eigenvalues("LongPendulum", Component("p", fmu))
    assert eigenvalues is not None
    assert max(abs(lam) for lam in eigenvalues) == pytest.approx(math.sqrt(9.81 / 10.0), rel=1e-9)


RIPPLED_WIRE = '''
identifier = "RippledWire"
description = "A bead on a wire with a potential rippled at 1000 waves per radian"
[parameters]
k = { start = 2.0, unit = "J", min = 0.0 }
m = { start = 0.5, unit = "kg", min = 1e-9 }
[coordinates]
x = { start = 0.0, unit = "m", velocity = "v" }
[energy]
T = "m/2*v**2"
U = "k*cos(1000*x)"
[points]
bead = { x = "x", y = "0" }
'''


def test_a_high_multiple_angle_derives_at_once_and_oscillates_at_its_frequency(tmp_path):
    """cos(1000*x) stays whole (its expansion in cos(x) is a polynomial of degree 1000), and the
    derivation reports its stages (the command line names a stage that takes over 2 s). About the
    minimum x0 = pi/1000 the bead's small oscillation is x0 + a cos(w t) with w = 1000 sqrt(k/m) = 2000 rad/s."""
    import fmpy
    path = write(tmp_path, RIPPLED_WIRE, "RippledWire.toml")
    stages: list[str] = []
    derive_fmu(path, tmp_path, stages.append)
    assert [stage.split(" (")[0] for stage in stages] == [
        "deriving Lagrange's equations", "generating the C code", "simplifying the equations for the documentation",
        "compiling"]
    x0, amplitude, w = math.pi / 1000, 1e-6, 2000.0
    rows = fmpy.simulate_fmu(str(tmp_path / "RippledWire.fmu"), stop_time=0.01, output_interval=1e-4,
                             start_values={"x": x0 + amplitude, "solver": SOLVERS.index("rk4") + 1, "h": 1e-5},
                             output=["x"])
    expected = x0 + amplitude * np.cos(w * rows["time"])
    assert np.max(np.abs(rows["x"] - expected)) < 1e-3 * amplitude


def test_display_simplification_is_cut_off_by_its_clock_and_zero_tests_evaluate():
    import sympy as sp

    from harness.objects.derivation import readable, vanishes
    x, y = sp.symbols("x y")
    slow = sp.expand((sp.sin(x) + sp.cos(y) + sp.sin(x + y)) ** 8, trig=True)  # simplify needs 13 s
    assert readable([slow, sp.sin(x) ** 2 + sp.cos(x) ** 2], seconds=0.3) == [slow, sp.sin(x) ** 2 + sp.cos(x) ** 2]
    assert readable([sp.sin(x) ** 2 + sp.cos(x) ** 2, slow], seconds=2) == [1, slow]
    spec = read_object_file("rippled.toml", RIPPLED_WIRE)
    assert vanishes(sp.sin(x + y) - sp.sin(x) * sp.cos(y) - sp.cos(x) * sp.sin(y), spec)
    assert vanishes((sp.sin(x) ** 2 + sp.cos(x) ** 2 - 1) * slow, spec)
    assert not vanishes(sp.sin(x) - x, spec)          # zero at x = 0 only
    assert not vanishes(sp.sqrt(x - 10), spec)        # cannot be evaluated as a real number


def test_a_derivation_that_expands_without_end_stops_at_its_time_limit(tmp_path, monkeypatch):
    """A 36th power of a sum expands into tens of thousands of terms: generation stops at its clock
    (300 s; 2 s here) with one line naming the file, and leaves an enclosing clock as it was."""
    import signal

    import harness.objects.generate as generate_module
    from harness.objects.generate import generate
    monkeypatch.setattr(generate_module, "GENERATION_SECONDS", 2.0)
    text = object_file("SimplePendulum").read_text().replace('U = "-m*g*L*cos(phi)"', 'U = "m*g*L*(phi+L+m+g)**36"')
    path = write(tmp_path, text, "SimplePendulum.toml")
    outer, handler = signal.getitimer(signal.ITIMER_REAL)[0], signal.getsignal(signal.SIGALRM)  # pytest-timeout's
    with pytest.raises(ObjectFileError) as refused:
        generate(path, tmp_path / "out")
    assert "deriving and generating the equations took over 2 s" in str(refused.value)
    assert str(refused.value).count("\n") == 0 and str(path) in str(refused.value)
    left = signal.getitimer(signal.ITIMER_REAL)[0]  # an enclosing clock goes on, none is left of ours
    assert (left == 0) if outer == 0 else (outer - 30 < left < outer)
    assert signal.getsignal(signal.SIGALRM) is handler
