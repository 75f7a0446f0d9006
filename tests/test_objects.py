"""Objects from their energies: bad object files, the generated equations against an independent
numeric route, and `harness derive` end to end. Nothing here is specific to one object: every
object file in the registry is checked the same way."""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description

from harness.fmu_instance import FmuInstance
from harness.objects.derivation import derive
from harness.objects.numeric_route import NumericLagrangian
from harness.objects.object_file import ObjectFileError, read_object_file
from harness.objects.registry import object_files, object_names

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
    before = set(Path(tempfile.gettempdir()).glob("derive-*"))
    result = subprocess.run([sys.executable, "-m", "harness", "derive", str(path), "--out", str(tmp_path / "out")],
                            capture_output=True, text=True)
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.count("\n") == 1 and "energy.U: unknown symbol 'psi'" in result.stderr, result.stderr
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
    assert set(Path(tempfile.gettempdir()).glob("derive-*")) == before


def test_derive_builds_a_valid_fmu_that_moves_as_the_numeric_route_says(tmp_path):
    from fmpy.validation import validate_fmu
    path = write(tmp_path, CART_PENDULUM)
    result = subprocess.run([sys.executable, "-m", "harness", "derive", str(path), "--out", str(tmp_path)],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    fmu = tmp_path / "CartPendulumTest.fmu"
    assert validate_fmu(str(fmu)) == []
    md = read_model_description(str(fmu))
    names = {v.name for v in md.modelVariables}
    assert {"x", "phi", "v", "omega", "push_x", "push_y", "cart_x", "bob_v_y", "E_kin", "E", "model",
            "n_rhs"} <= names
    check_against_numeric_route(fmu, path, samples=4)


def check_against_numeric_route(fmu: Path, object_file: Path, samples: int, seed: int = 7) -> float:
    """Largest relative deviation of the FMU's accelerations (Model Exchange) from the numeric route."""
    spec = read_object_file(object_file)
    route = NumericLagrangian(spec)
    rng = np.random.default_rng(seed)
    worst = 0.0
    instance = FmuInstance(fmu, kind="ME")
    try:
        defaults = {p.name: p.start for p in spec.parameters}
        instance.initialize()
        assert instance.call("fmi2EnterContinuousTimeMode") == 0
        n = len(spec.coordinates)
        inputs = [name for force in spec.forces for name in force.inputs.values()]
        for _ in range(samples):
            values = dict(defaults)
            for c in spec.coordinates:
                values[c.name] = c.start + rng.uniform(-0.3, 0.3)
                values[c.velocity] = c.velocity_start + rng.uniform(-1.0, 1.0)
            values.update({name: rng.uniform(-2.0, 2.0) for name in inputs})
            states = [values[c.name] for c in spec.coordinates] + [values[c.velocity] for c in spec.coordinates]
            assert instance.call("fmi2SetContinuousStates", (ctypes_array(states)), 2 * n) == 0
            if inputs:
                assert instance.set(**{name: values[name] for name in inputs}) == 0
            derivatives = (ctypes_array([0.0] * 2 * n))
            assert instance.call("fmi2GetDerivatives", derivatives, 2 * n) == 0
            got = np.array(derivatives[n:])
            expected = route.accelerations(values)
            assert np.allclose(derivatives[:n], states[n:], rtol=0, atol=0)
            deviation = np.max(np.abs(got - expected)) / max(1.0, np.max(np.abs(expected)))
            worst = max(worst, deviation)
            T, U = route.energies(values)
            E_kin, E_pot = instance.get("E_kin", "E_pot")
            assert E_kin == pytest.approx(T, rel=1e-12, abs=1e-12) and E_pot == pytest.approx(U, rel=1e-12, abs=1e-12)
    finally:
        instance.free()
    assert worst < 1e-9, worst
    return worst


def ctypes_array(values):
    import ctypes
    return (ctypes.c_double * len(values))(*values)


@pytest.mark.parametrize("name", object_names())
def test_every_object_agrees_with_the_numeric_route(fmu_paths, name):
    check_against_numeric_route(fmu_paths[name], dict(zip(object_names(), object_files()))[name], samples=5)
