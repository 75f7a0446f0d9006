"""What the coupling chart claims: held inputs converge at first order and extrapolated ones at
second, Gauss-Seidel is no worse than Jacobi, iteration converges to one answer whichever the
order, and the monolithic reference itself conserves energy."""
from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from harness.cosim.algorithm_registry import NAMES as ALGORITHM_NAMES
from harness.cli import main
from harness.cosim.master import MasterOptions, run_system
from harness.cosim.system import load_system
from harness.fmi.fmus import PROJECT_ROOT
from harness.objects.thesis.reference import slope
from harness.studies.coupling import coupling_error, derived_reference, read_csv
from pair_reference import CoupledPair

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
    for gs, jacobi in zip(series(sweep[1], f"gauss-seidel, {extrapolation}"),
                          series(sweep[1], f"jacobi, {extrapolation}")):
        assert gs.error <= jacobi.error * 1.05


def test_iteration_converges_to_one_answer_and_costs_passes(sweep):
    for jacobi, gs, single in zip(series(sweep[1], "jacobi, linear, iterated"),
                                  series(sweep[1], "gauss-seidel, linear, iterated"),
                                  series(sweep[1], "gauss-seidel, linear")):
        assert jacobi.error == pytest.approx(gs.error, rel=0.01)
        assert gs.do_steps > 2 * single.do_steps and gs.rhs_evals > 2 * single.rhs_evals


def test_the_hand_coded_pair_conserves_energy(fmu_paths):
    """The independent reference the derived one is checked against (tests/cosim/test_monolithic.py) is
    itself right: its energy, written out by hand, is constant."""
    physics = CoupledPair.from_system(load_system(SCENE))
    t = np.linspace(0, 10, 2001)
    a, b = physics.reference(t)
    y = physics.states(t)
    L, m, g, k, l0 = physics.left["L"], physics.left["m"], physics.left["g"], physics.spring["k"], physics.spring["l0"]
    stretch = np.hypot(*(b - a).T) - l0
    energy = m * L ** 2 * (y[1] ** 2 + y[3] ** 2) / 2 + m * g * (a[:, 1] + b[:, 1]) + k * stretch ** 2 / 2
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * abs(energy[0])
    assert np.ptp(stretch) > 0.01  # the spring does work


def test_any_spring_scene_has_its_chart(fmu_paths, tmp_path):
    """Three pendulums in a row, through --scene: the same orders as the pair."""
    out = tmp_path / "row"
    assert main(["chart", "coupling", "--scene", str(PROJECT_ROOT / "scenes" / "pendulums_in_a_row.json"), "--out",
                 str(out), "--repeats", "1", "--stop", "2"]) == 0
    points = read_csv(out / "coupling.csv")
    for configuration, low, high in (("gauss-seidel, hold", 0.7, 1.3), ("gauss-seidel, linear", 1.7, 2.5)):
        mine = series(points, configuration)[:3]
        assert low <= slope([p.step for p in mine], [p.error for p in mine]) <= high, (configuration, mine)


@pytest.mark.parametrize("change, named", [
    ("object to object", "connection left.x -> right.F2_x joins two objects directly"),
    ("linear model", "left.model = 'linear'"),
])
def test_a_scene_without_a_derived_reference_is_refused_by_what_differs(fmu_paths, tmp_path, capsys, change, named):
    """The chart and the coupled planner refuse a scene whose monolithic reference cannot be derived,
    naming why, rather than measure against a wrong one."""
    scene = json.loads(SCENE.read_text())
    if change == "object to object":
        scene["connections"].append(["left.x", "right.F2_x"])
    else:
        scene["components"]["left"]["start"]["model"] = "linear"
    path = tmp_path / "changed.json"
    path.write_text(json.dumps(scene))
    for command in (["chart", "coupling", "--scene", str(path), "--out", str(tmp_path / "out"), "--repeats", "1"],
                    ["plan", str(path), "--tolerance", "0.001", "--out", str(tmp_path / "plan.csv")]):
        assert main(command) == 2, command
        err = capsys.readouterr().err
        assert named in err and err.count("\n") == 1, err


def test_the_coupling_sweep_runs_on_dask_as_in_processes(fmu_paths):
    """The same items on a Dask LocalCluster give the same errors and costs (timings aside)."""
    pytest.importorskip("distributed")
    from harness.studies.coupling import coupling_sweep
    system = load_system(PROJECT_ROOT / "scenes" / "pendulums_in_a_row.json")
    kwargs = dict(stop=0.5, steps=(0.02, 0.01), configurations=(("gauss-seidel", "linear", None),), repeats=1)
    on_dask = coupling_sweep(system, scheduler="local", workers=2, **kwargs)
    in_processes = coupling_sweep(system, workers=2, **kwargs)
    assert [(p.step, p.error, p.rhs_evals, p.do_steps) for p in on_dask] == \
        [(p.step, p.error, p.rhs_evals, p.do_steps) for p in in_processes]
    assert all(0 < p.error < 1e-2 for p in on_dask)


@pytest.mark.parametrize("algorithm", ALGORITHM_NAMES)
def test_a_damped_spring_keeps_linear_extrapolation_second_order(fmu_paths, tmp_path, algorithm):
    """A spring with damping hands over the rate of its force, which at a step's end follows the
    slopes its ends' velocities had over the step (their accelerations): Jacobi, which extrapolates
    with that rate, converges at second order as on the undamped pair (it was first order while the
    rate left the slopes out)."""
    scene = json.loads(SCENE.read_text())
    scene["components"]["spring"]["start"]["c"] = 0.5
    path = tmp_path / "damped.json"
    path.write_text(json.dumps(scene))
    steps = (0.02, 0.01, 0.005)
    with load_system(path) as system:
        reference = derived_reference(system, np.arange(0, 76) * 0.04)
        errors = []
        for H in steps:
            result = run_system(system, MasterOptions(stop=3.0, step=H, algorithm=algorithm, extrapolation="linear"))
            every = round(0.04 / H)
            kept = type(result)(result.columns, result.values[::every], result.energy[::every])
            errors.append(coupling_error(kept, *reference))
    assert 1.8 <= slope(list(steps), errors) <= 2.4, errors
