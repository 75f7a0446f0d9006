"""The forces the angle form hides: the simple pendulum's rod tension and the double pendulum's link
tensions (outputs of their object files, from Newton's law along each rod) against Lagrange's equations of
the first kind, where the rods are constraints and their forces the multipliers: the simple pendulum against
the CartesianPendulum FMU's rod force, the double pendulum with point masses against a Cartesian double
pendulum written here and solved by the numeric route (no symbolic derivation, no generated code). A rigid
link's tension is checked against Newton's law for its centre of gravity with the acceleration taken by
finite differences of the FMU's recorded motion."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu

from harness.fmi.fmu_instance import FmuInstance
from harness.fmi.methods import SOLVERS
from harness.objects.numeric_route import NumericLagrangian
from harness.objects.object_file import ObjectFileError, read_object_file

G = 9.81

CARTESIAN_DOUBLE = """
identifier = "CartesianDoublePendulum"
[parameters]
g = { start = 9.81 }
m1 = { start = 1.0 }
m2 = { start = 1.0 }
l1 = { start = 1.0 }
l2 = { start = 1.0 }
[coordinates]
x1 = { velocity = "vx1" }
y1 = { velocity = "vy1" }
x2 = { velocity = "vx2" }
y2 = { velocity = "vy2" }
[energy]
T = "m1/2*(vx1**2 + vy1**2) + m2/2*(vx2**2 + vy2**2)"
U = "m1*g*y1 + m2*g*y2"
[points]
one = { x = "x1", y = "y1" }
tip = { x = "x2", y = "y2" }
[forces]
F = { point = "tip" }
[constraints]
rod1 = { gap = "l1 - sqrt(x1**2 + y1**2)", kind = "bilateral" }
rod2 = { gap = "l2 - sqrt((x2 - x1)**2 + (y2 - y1)**2)", kind = "bilateral" }
"""


def test_the_simple_pendulums_rod_tension_is_the_cartesian_pendulums_rod_force(fmu_paths):
    rng = np.random.default_rng(7)
    with FmuInstance(fmu_paths["SimplePendulum"]) as angle, FmuInstance(fmu_paths["CartesianPendulum"]) as rod:
        for _ in range(12):
            L, m, phi, omega = rng.uniform(0.3, 2.0), rng.uniform(0.2, 3.0), rng.uniform(-3, 3), rng.uniform(-4, 4)
            F, F2 = rng.uniform(-2, 2, 2), rng.uniform(-2, 2, 2)
            d = rng.uniform(0.0, 0.5)  # a torque in the angle form, along the velocity in Cartesian form:
                                       # no radial part
            angle.reset()
            angle.initialize(L=L, m=m, d=d, phi=phi, omega=omega, F_x=F[0], F_y=F[1], F2_x=F2[0], F2_y=F2[1])
            rod.reset()
            rod.initialize(L=L, m=m, d=d, x=L * math.sin(phi), y=-L * math.cos(phi), vx=L * omega * math.cos(phi),
                           vy=L * omega * math.sin(phi), F_x=F[0] + F2[0], F_y=F[1] + F2[1])
            tension, force = angle.get("rod_tension")[0], rod.get("rod_force")[0]
            assert tension == pytest.approx(force, rel=1e-10, abs=1e-10)
            # and the closed form the thesis pendulum's tension has without forces
            if abs(F).max() == 0:
                assert tension == pytest.approx(m * (G * math.cos(phi) + L * omega ** 2), rel=1e-12)


def test_the_double_pendulums_link_tensions_are_the_multipliers_of_its_rods(fmu_paths):
    """Point masses at the links' ends (J = 0, s = l): each link is a rod, and its tension is the rod's
    Lagrange multiplier, at random states, parameters, tip forces and damping."""
    cartesian = NumericLagrangian(read_object_file("CartesianDoublePendulum.toml", CARTESIAN_DOUBLE))
    rng = np.random.default_rng(11)
    with FmuInstance(fmu_paths["DoublePendulum"]) as fmu:
        for _ in range(8):
            m1, m2, l1, l2 = rng.uniform(0.3, 2.0, 4)
            phi1, phi2, omega1, omega2 = rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-3, 3)
            Fx, Fy = rng.uniform(-2, 2, 2)
            d = rng.uniform(0.0, 0.5)  # a drag -d v on each mass in both forms
            fmu.reset()
            fmu.initialize(m1=m1, m2=m2, l1=l1, l2=l2, J1=0.0, J2=0.0, s1=l1, s2=l2, phi1=phi1, phi2=phi2,
                           omega1=omega1, omega2=omega2, F_x=Fx, F_y=Fy, d=d)
            tensions = fmu.get("link1_tension", "link2_tension")
            x1, y1 = l1 * math.sin(phi1), -l1 * math.cos(phi1)
            vx1, vy1 = l1 * omega1 * math.cos(phi1), l1 * omega1 * math.sin(phi1)
            x2, y2 = x1 + l2 * math.sin(phi2), y1 - l2 * math.cos(phi2)
            vx2, vy2 = vx1 + l2 * omega2 * math.cos(phi2), vy1 + l2 * omega2 * math.sin(phi2)
            multipliers = cartesian.forces({"g": G, "m1": m1, "m2": m2, "l1": l1, "l2": l2, "x1": x1, "y1": y1,
                                            "x2": x2, "y2": y2, "vx1": vx1, "vy1": vy1, "vx2": vx2, "vy2": vy2,
                                            "F_x": Fx, "F_y": Fy, "d": d})
            assert tensions == pytest.approx(list(multipliers), rel=1e-9, abs=1e-9)


def test_a_rigid_links_tension_is_newtons_law_for_its_centre_of_gravity(fmu_paths):
    """Link 2 with inertia (the defaults: J2 = m l^2 / 12, s2 = l / 2): its centre of gravity moves under
    gravity, the joint's force P and nothing else, so P = m2 (a - g) and the tension is -P along the link.
    The acceleration comes from the recorded centre by central differences (4th order, 1e-3 s)."""
    h, stop = 1e-3, 1.0
    result = simulate_fmu(fmu_paths["DoublePendulum"], stop_time=stop, output_interval=h,
                          start_values={"solver": SOLVERS.index("gbs") + 1, "h": 0.01, "tol": 1e-13},
                          output=["x1", "y1", "x2", "y2", "phi2", "link2_tension"])
    s2, l2, m2 = 0.5, 1.0, 1.0
    centre = np.stack([result["x1"] + s2 / l2 * (result["x2"] - result["x1"]),
                       result["y1"] + s2 / l2 * (result["y2"] - result["y1"])])
    acceleration = (-centre[:, 4:] + 16 * centre[:, 3:-1] - 30 * centre[:, 2:-2] + 16 * centre[:, 1:-3]
                    - centre[:, :-4]) / (12 * h * h)
    phi2 = result["phi2"][2:-2]
    along = np.stack([np.sin(phi2), -np.cos(phi2)])
    joint_force = m2 * (acceleration - np.array([[0.0], [-G]]))
    tension = -(joint_force * along).sum(axis=0)
    assert np.max(np.abs(tension - result["link2_tension"][2:-2])) < 1e-5


# ---------------------------------------------------------------- what an outputs table may not say

SIMPLE = (Path(__file__).resolve().parents[2] / "modelDescription" / "SimplePendulum.toml").read_text()


@pytest.mark.parametrize("line, message", [
    ('rod_tension = { value = "der(phi)" }', "der(phi): der() takes one velocity (omega)"),
    ('rod_tension = { value = "der(omega, omega)" }', "der() takes one velocity"),
    ('rod_tension = { unit = "N" }', "outputs.rod_tension.value: missing"),
    ('rod_tension = { value = "m*g", colour = "red" }', "outputs.rod_tension.colour: unknown key"),
    ('x = { value = "m*g" }', "outputs.x: 'x' is already used by points.bob.names.x"),
    ('rod_tension = { value = "m*g*q" }', "unknown symbol 'q'"),
])
def test_an_output_that_cannot_be_made_is_named(line, message):
    text = SIMPLE[:SIMPLE.index("[outputs]")] + "[outputs]\n" + line + "\n"
    with pytest.raises(ObjectFileError) as caught:
        read_object_file("SimplePendulum.toml", text)
    assert message in str(caught.value) and "\n" not in str(caught.value)


def test_a_refused_object_file_leaves_no_output_folder(tmp_path):
    """Accelerations in the outputs of an object with constraints are refused by name, exit code 2, and the
    --out folder the command was asked to make is not made."""
    source = tmp_path / "Swing.toml"
    text = SIMPLE.replace('rod_tension = { value = "', 'rod_tension = { value = "der(omega) + ')
    source.write_text(text + '\n[constraints]\nwall = { gap = "phi + 1", unit = "rad" }\n')
    out = tmp_path / "new" / "fmus"
    result = subprocess.run([sys.executable, "-m", "harness", "derive", str(source), "--out", str(out)],
                            capture_output=True, text=True, cwd=Path(__file__).resolve().parents[2])
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "offers no accelerations to its outputs" in result.stderr
    assert not (tmp_path / "new").exists()
