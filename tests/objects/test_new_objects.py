"""The objects beyond the thesis, made from their object files: what each one's physics must show.
(The checks every object gets alike are in test_objects.py and the conformance suites.)"""
from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from harness.fmi.fmus import PROJECT_ROOT
from harness.fmi.simulation import simulate

SCENES = ["cart_pendulum", "chain3", "chain5", "spherical_pendulum", "elastic_double_pendulum", "kapitza_pendulum"]


@pytest.mark.parametrize("scene", SCENES)
def test_each_scene_runs_and_conserves_its_energy(tmp_path, fmu_paths, scene):
    """Each object's scene runs through the master; without damping or drive the energy stays put."""
    path = PROJECT_ROOT / "scenes" / f"{scene}.json"
    out = tmp_path / "run.csv"
    result = subprocess.run([sys.executable, "-m", "harness", "run", str(path), "--stop", "2", "--step", "0.01",
                             "--out", str(out), "--quiet"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    data = np.genfromtxt(out, delimiter=",", names=True)
    assert len(data) == 201
    (component,) = json.loads(path.read_text())["components"]
    energy = data[f"{component}E"]
    if scene != "kapitza_pendulum":  # the drive pumps energy in and out
        assert np.max(np.abs(energy - energy[0])) < 1e-6 * max(1.0, abs(energy[0])), scene


def test_cart_pendulum_keeps_its_horizontal_momentum(fmu_paths):
    """No horizontal force: (M + m) v + m l omega cos(phi) is conserved."""
    r = simulate(fmu_paths["CartPendulum"], 5.0, 0.01, start_values={"h": 0.002})
    M, m, length = 2.0, 0.5, 0.8
    momentum = (M + m) * np.asarray(r["v"]) + m * length * np.asarray(r["omega"]) * np.cos(np.asarray(r["phi"]))
    assert np.max(np.abs(momentum - momentum[0])) < 1e-9


def test_spherical_pendulum_keeps_its_angular_momentum_and_stops_at_the_pole(fmu_paths):
    r = simulate(fmu_paths["SphericalPendulum"], 5.0, 0.01, start_values={"h": 0.001})
    lz = np.sin(np.asarray(r["theta"])) ** 2 * np.asarray(r["psi_dot"])
    assert np.max(np.abs(lz - lz[0])) < 1e-9 * abs(lz[0])
    assert np.min(r["theta"]) > 0.1  # the centrifugal barrier keeps it off the pole
    # A plane swing (no spin) passes through the pole theta = 0, where psi is undefined: fmi2Discard.
    plane = simulate(fmu_paths["SphericalPendulum"], 5.0, 0.01, start_values={"h": 0.001, "psi_dot": 0.0})
    assert plane.discarded_at is not None and plane.discarded_at < 1.0
    assert "non-finite or singular" in plane.messages[-1]


def upright_deviation(fmu, Omega: float) -> float:
    r = simulate(fmu, 3.0, 0.01, start_values={"Omega": Omega, "h": 2e-5 * 314.1592653589793 / Omega})
    return float(np.max(np.abs(np.asarray(r["phi"]) - math.pi)))


def test_kapitza_pendulum_stays_upright_above_the_threshold_and_falls_below(fmu_paths):
    """Stable upright for (A Omega)^2 > 2 g L: A = 0.02 m, L = 0.2 m puts the threshold at Omega = 99 rad/s."""
    threshold = math.sqrt(2 * 9.81 * 0.2) / 0.02
    assert upright_deviation(fmu_paths["KapitzaPendulum"], 2.0 * threshold) < 0.2
    assert upright_deviation(fmu_paths["KapitzaPendulum"], 0.5 * threshold) > 1.5


def test_linear_models_match_the_nonlinear_ones_at_small_amplitude(fmu_paths):
    """model = linear (normal modes of the quadratic T and U about rest) against the full equations."""
    cases = {"CartPendulum": {"phi": 0.01}, "Chain3": {"phi1": 0.01}, "ElasticDoublePendulum": {"phi1": 0.01,
                                                                                              "phi2": 0.005}}
    for name, start in cases.items():
        if name == "ElasticDoublePendulum":
            start = dict(start, e1=2 * 9.81 / 100 + 0.001, e2=9.81 / 100)
        full = simulate(fmu_paths[name], 3.0, 0.01, start_values={**start, "h": 0.001})
        linear = simulate(fmu_paths[name], 3.0, 0.01, start_values={**start, "model": "linear"})
        for column in full.columns:
            if column.startswith(("phi", "x", "e")):
                scale = max(1e-3, float(np.max(np.abs(full[column]))))
                assert np.max(np.abs(np.asarray(full[column]) - np.asarray(linear[column]))) < 0.05 * scale, \
                    (name, column)


@pytest.mark.parametrize("scene", SCENES)
def test_every_object_can_be_planned_and_the_plan_holds(fmu_paths, scene):
    """The planner knows any object from its file: linear model or not, driven or not. The verified
    error (against an FMU nystrom5 reference with a step-halving estimate) meets the tolerance, and
    the plan is re-checked here against an independent run: rkf45 at a tight tolerance."""
    assert_the_plan_holds(scene)


def assert_the_plan_holds(scene: str) -> None:
    """The scene's plan at 1 mm over 1 s, verified by the planner and re-checked against rkf45 at 1e-12."""
    from harness.cosim.system import load_system
    from harness.studies.planner import plan_scene
    system = load_system(PROJECT_ROOT / "scenes" / f"{scene}.json")
    (plan,) = plan_scene(system, 1e-3, duration=1.0)
    assert plan.verified_error <= 1e-3
    (component,) = system.components
    planned = simulate(component.fmu, 1.0, 0.01, start_values={**component.start, **plan.settings})
    tight = simulate(component.fmu, 1.0, 0.01, start_values={**component.start, "solver": "rkf45", "tol": 1e-12})
    for x, y in system.traces[component.name]:
        distance = np.hypot(np.asarray(planned[x]) - np.asarray(tight[x]),
                            np.asarray(planned[y]) - np.asarray(tight[y]))
        assert np.max(distance) <= 1e-3, (x, y)
