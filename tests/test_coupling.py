"""What the coupling chart claims: held inputs converge at first order and extrapolated ones at
second, Gauss-Seidel is no worse than Jacobi, iteration converges to one answer whichever the
order, and the monolithic reference itself conserves energy."""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from harness.cli import main
from harness.cosim.system import load_system
from harness.fmi.fmus import PROJECT_ROOT
from harness.objects.thesis.reference import slope
from harness.studies.coupling import CoupledPendulums, read_csv

SCENE = PROJECT_ROOT / "scenes" / "coupled_pendulums.json"


@pytest.fixture(scope="module")
def sweep(fmu_paths, tmp_path_factory):
    out = tmp_path_factory.mktemp("coupling")
    assert main(["chart", "coupling", "--out", str(out), "--repeats", "1", "--stop", "3"]) == 0
    return out, read_csv(out / "coupling.csv")


def series(points, configuration):
    return sorted((p for p in points if p.configuration == configuration), key=lambda p: p.step)


def test_the_files_and_the_columns(sweep):
    out, points = sweep
    with open(out / "coupling.csv") as handle:
        assert next(csv.reader(handle)) == ["algorithm", "extrapolation", "iterate", "step", "error", "rhs_evals",
                                            "do_steps", "seconds"]
    for suffix in ("png", "svg"):
        assert (out / f"coupling.{suffix}").stat().st_size > 10_000
    assert len({p.configuration for p in points}) == 6
    assert all(math.isfinite(p.error) and p.rhs_evals > 0 and p.seconds > 0 for p in points)


@pytest.mark.parametrize("configuration,low,high", [("jacobi, hold", 0.7, 1.3), ("gauss-seidel, hold", 0.7, 1.3),
                                                    ("jacobi, linear", 1.7, 2.4), ("gauss-seidel, linear", 1.7, 2.4),
                                                    ("gauss-seidel, linear, iterated", 1.7, 2.4)])
def test_slopes_are_the_extrapolation_orders(sweep, configuration, low, high):
    mine = series(sweep[1], configuration)[:3]  # the three smallest steps
    assert low <= slope([p.step for p in mine], [p.error for p in mine]) <= high, [p.error for p in mine]


@pytest.mark.parametrize("extrapolation", ["hold", "linear"])
def test_gauss_seidel_is_no_worse_than_jacobi(sweep, extrapolation):
    for gs, jacobi in zip(series(sweep[1], f"gauss-seidel, {extrapolation}"), series(sweep[1], f"jacobi, {extrapolation}")):
        assert gs.error <= jacobi.error * 1.05


def test_iteration_converges_to_one_answer_and_costs_passes(sweep):
    for jacobi, gs, single in zip(series(sweep[1], "jacobi, linear, iterated"),
                                  series(sweep[1], "gauss-seidel, linear, iterated"),
                                  series(sweep[1], "gauss-seidel, linear")):
        assert jacobi.error == pytest.approx(gs.error, rel=0.01)
        assert gs.do_steps > 2 * single.do_steps and gs.rhs_evals > 2 * single.rhs_evals


def test_the_monolithic_reference_conserves_energy(fmu_paths):
    physics = CoupledPendulums.from_system(load_system(SCENE))
    t = np.linspace(0, 10, 2001)
    a, b = physics.reference(t)
    ya, yb = a[:, 1], b[:, 1]
    # speeds from the positions' spectral derivative would be noisy: differentiate the reference's states instead
    from scipy.integrate import solve_ivp
    start = [physics.left["phi"], physics.left["omega"], physics.right["phi"], physics.right["omega"]]
    y = solve_ivp(physics.rhs, (0, 10), start, method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t).y
    L, m, g, k, l0 = physics.left["L"], physics.left["m"], physics.left["g"], physics.spring["k"], physics.spring["l0"]
    stretch = np.hypot(*(b - a).T) - l0
    energy = m * L ** 2 * (y[1] ** 2 + y[3] ** 2) / 2 + m * g * (ya + yb) + k * stretch ** 2 / 2
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * abs(energy[0])
    assert np.ptp(stretch) > 0.01  # the spring does work


def test_a_system_of_another_shape_is_a_one_line_error(fmu_paths, tmp_path, capsys):
    scene = tmp_path / "one.json"
    scene.write_text(json.dumps({"name": "one", "stop": 1.0, "step": 0.01,
                                 "components": {"p": {"fmu": "SimplePendulum"}}, "connections": []}))
    assert main(["chart", "coupling", "--system", str(scene), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "two SimplePendulums whose bobs are joined by one Spring" in err and err.count("\n") == 1


@pytest.mark.parametrize("change, named", [
    ("no forces back", "spring.Fa_x -> left.F_x"),
    ("crossed velocity", "right.v_x -> spring.a_vx"),
    ("linear model", "left.model = 'linear'"),
    ("a third object", "DoublePendulum"),
])
def test_a_scene_the_reference_does_not_describe_is_refused_by_what_differs(fmu_paths, tmp_path, capsys, change,
                                                                             named):
    """The standard scene with one thing changed has another monolithic reference: the chart and the
    coupled planner refuse it, naming the difference, rather than measure against the wrong one."""
    scene = json.loads(SCENE.read_text())
    if change == "no forces back":
        scene["connections"] = [c for c in scene["connections"] if not c[0].startswith("spring.F")]
    elif change == "crossed velocity":
        scene["connections"] = [["right.v_x", "spring.a_vx"] if c == ["left.v_x", "spring.a_vx"] else c
                                for c in scene["connections"]]
    elif change == "linear model":
        scene["components"]["left"]["start"]["model"] = "linear"
    else:
        scene["components"]["extra"] = {"fmu": "DoublePendulum"}
    path = tmp_path / "changed.json"
    path.write_text(json.dumps(scene))
    for command in (["chart", "coupling", "--system", str(path), "--out", str(tmp_path / "out"), "--repeats", "1"],
                    ["plan", str(path), "--tolerance", "0.001", "--out", str(tmp_path / "plan.csv")]):
        assert main(command) == 2, command
        err = capsys.readouterr().err
        assert "the coupling reference knows one scene only" in err and named in err and err.count("\n") == 1, err
    assert CoupledPendulums.from_system(load_system(SCENE)).names == ("left", "right")
