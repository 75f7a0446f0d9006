"""The planner over a set of scenes (small and large swings, damping, short and long durations,
coupled objects): the verified error is always within the tolerance, the prediction is honest, the
plan never costs more than the default where the default meets the tolerance, and no plan steps
beyond a stability limit."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from harness.cli import main
from harness.cosim.system import load_system
from harness.fmi.fmus import PROJECT_ROOT
from harness.fmi.methods import plan_order, plan_solver
from harness.objects.thesis.reference import exact_simple_pendulum
from harness.studies.planner import plan_scene
from harness.studies.stability import linearized_eigenvalues, plan_tables, stable_over

SCENES = {
    "small swing, long": ({"p": {"fmu": "SimplePendulum", "start": {"phi": 0.05}}}, 20.0, 1e-3),
    "large swing": ({"p": {"fmu": "SimplePendulum", "start": {"phi": 3.0}}}, 10.0, 1e-3),
    "damped": ({"p": {"fmu": "SimplePendulum", "start": {"phi": 0.8, "d": 0.5}}}, 10.0, 1e-4),
    "spring, short": ({"s": {"fmu": "SpringPendulum", "start": {}}}, 2.0, 1e-4),
    "double, small": ({"q": {"fmu": "DoublePendulum", "start": {"phi1": 0.3, "phi2": -0.2}}}, 5.0, 1e-3),
    "two objects, tight": ({"p": {"fmu": "SimplePendulum", "start": {"phi": 1.0, "L": 0.5}},
                            "s": {"fmu": "SpringPendulum", "start": {"D": 50.0}}}, 5.0, 1e-5),
}


COUPLED = {"coupled": "coupled_pendulums.json", "double and cart": "double_and_cart.json"}


def scene_file(tmp_path, name, components, duration) -> str:
    path = tmp_path / "scene.json"
    path.write_text(json.dumps({"name": name, "stop": duration, "camera": {"frame_rate": 25},
                                "components": components, "connections": []}))
    return str(path)


@pytest.fixture(scope="module")
def plans(fmu_paths, tmp_path_factory):
    out = {}
    for name, (components, duration, tolerance) in SCENES.items():
        system = load_system(scene_file(tmp_path_factory.mktemp("scene"), name, components, duration))
        out[name] = (system, tolerance, plan_scene(system, tolerance))
    for name, file in COUPLED.items():
        system = load_system(PROJECT_ROOT / "scenes" / file)
        out[name] = (system, 1e-3, plan_scene(system, 1e-3, duration=5.0))
    return out


@pytest.mark.parametrize("scene", [*SCENES, *COUPLED])
def test_verified_error_within_the_tolerance(plans, scene):
    system, tolerance, plan = plans[scene]
    springs = [c for c in system.components if c.fmu.stem == "Spring"]
    assert len(plan) == len(system.components) - len(springs)
    for p in plan:
        assert p.verified_error <= tolerance, p
        assert p.predicted_error <= 0.5 * tolerance or p.how == "the default, verified"
        # the prediction is not wildly optimistic
        assert p.verified_error <= 3 * p.predicted_error + tolerance / 100, p


@pytest.mark.parametrize("scene", [*SCENES, *COUPLED])
def test_never_dearer_than_a_default_that_meets_the_tolerance(plans, scene):
    _, tolerance, plan = plans[scene]
    for p in plan:
        if p.default_error <= tolerance:
            assert p.cost <= p.default_cost, p


@pytest.mark.parametrize("scene", list(SCENES))
def test_no_plan_beyond_a_stability_limit(plans, scene):
    system, _, plan = plans[scene]
    tables = plan_tables()
    for p in plan:
        if p.model == "linear":
            continue
        from harness.objects.thesis.equations import Pendulum
        pendulum = Pendulum.from_fmu(system.component(p.object).fmu, system.component(p.object).start)
        assert stable_over(tables[p.method], linearized_eigenvalues(p.kind, pendulum.parameters), p.h, system.stop)


def test_small_swings_take_the_closed_form_and_large_ones_do_not(plans):
    assert plans["small swing, long"][2][0].model == "linear"
    assert plans["large swing"][2][0].model == "nonlinear"


def test_the_verification_is_independent(plans):
    """Re-verify the large-swing plan against the exact elliptic solution, outside the planner."""
    from harness.fmi.simulation import simulate
    system, tolerance, (plan,) = plans["large swing"]
    result = simulate(system.component("p").fmu, 10.0, 0.04,
                      start_values={**system.component("p").start, **plan.settings})
    phi, _ = exact_simple_pendulum(3.0, result.time)
    error = np.max(np.hypot(result["x"] - np.sin(phi), result["y"] + np.cos(phi)))
    assert error == pytest.approx(plan.verified_error, rel=1e-6) and error <= tolerance


@pytest.mark.parametrize("method,h", [("taylor6", 0.04), ("taylor6", 0.02), ("taylor10", 0.04), ("gbs6", 0.04),
                                      ("gbs6", 0.02)])
def test_fixed_step_taylor_and_gbs_candidates_are_predicted_at_their_order(fmu_paths, tmp_path, method, h):
    """The planner's taylor<order> and gbs<order> candidates (their fixed step, tol = 0): step doubling on
    the large swing predicts their error within 20% of the exact elliptic solution's. (The planner rarely
    picks them: a step counts p (p + 1) / 2 or 1 + (p / 2)^2 evaluations, and ab6 meets the same error for
    fewer.)"""
    from harness.studies.planner import _columns, _predict
    from harness.studies.references import ObjectRunner
    system = load_system(scene_file(tmp_path, "swing", {"p": {"fmu": "SimplePendulum", "start": {"phi": 3.0}}}, 10.0))
    component = system.component("p")
    runner = ObjectRunner(component, 10.0, 0.04, _columns(system, component))
    try:
        predicted, cost, _ = _predict(runner, method, h, 1e-3)
        positions, _ = runner.run(runner.settings(method, h))
    finally:
        runner.close()
    phi, _ = exact_simple_pendulum(3.0, runner.grid)
    error = np.max(np.hypot(positions[:, 0, 0] - np.sin(phi), positions[:, 0, 1] + np.cos(phi)))
    assert predicted == pytest.approx(error, rel=0.2)
    order = plan_order(method)
    per_step = order * (order + 1) // 2 if plan_solver(method) == "taylor" else 1 + (order // 2) ** 2
    assert cost == round(10.0 / h) * per_step


def test_plan_command_prints_and_writes(fmu_paths, tmp_path, capsys):
    path = scene_file(tmp_path, "one", {"p": {"fmu": "SimplePendulum", "start": {"phi": 0.5}}}, 5.0)
    data = json.loads(open(path).read())
    data.update(accuracy={"pixels": 1.0}, camera={"scale": 250.0, "frame_rate": 25.0})
    open(path, "w").write(json.dumps(data))
    assert main(["plan", path, "--out", str(tmp_path / "plan.csv")]) == 0
    out = capsys.readouterr().out
    assert "tolerance 0.004 m" in out and "cheaper than the default" in out
    assert (tmp_path / "plan.csv").read_text().startswith("object,kind,model,method,h,")


def test_a_scene_without_accuracy_is_a_one_line_error(fmu_paths, tmp_path, capsys):
    path = scene_file(tmp_path, "none", {"p": {"fmu": "SimplePendulum"}}, 5.0)
    assert main(["plan", path]) == 2
    err = capsys.readouterr().err
    assert "give --tolerance" in err and err.count("\n") == 1


def test_pixels_need_a_scale(fmu_paths, tmp_path, capsys):
    path = scene_file(tmp_path, "noscale", {"p": {"fmu": "SimplePendulum"}}, 5.0)
    assert main(["plan", path, "--pixels", "1"]) == 2
    assert "needs the camera's \"scale\"" in capsys.readouterr().err


def test_thesis_scene_file_is_the_contract():
    """SPEC section 6: step widths, anchors, lengths and releases."""
    system = load_system(PROJECT_ROOT / "scenes" / "thesis_scene.json")
    starts = {c.name: c.start for c in system.components}
    assert starts["simple"]["h"] == 0.008 and starts["simple"]["L"] == 1.0
    for name, stiffness in (("spring_D34", 34.0), ("spring_D104", 104.0)):
        s = starts[name]
        assert (s["D"], s["h"], s["anchor_y"], s["l0"]) == (stiffness, 0.05, 0.7, 1.4)
        assert s["phi"] == pytest.approx(0.75 * math.pi)
    d = starts["double"]
    assert (d["h"], d["l1"], d["l2"], d["anchor_y"]) == (0.04, 0.9, 0.9, 0.9)
    assert d["phi1"] == d["phi2"] == pytest.approx(0.5 * math.pi)
    assert system.tolerance() == pytest.approx(1 / 250)


@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf"])
def test_a_tolerance_that_is_not_a_positive_number_is_a_one_line_error(fmu_paths, value, capsys):
    assert main(["plan", str(PROJECT_ROOT / "scenes" / "thesis_scene.json"), "--tolerance", value]) == 2
    err = capsys.readouterr().err
    assert f"argument --tolerance: '{value}' must be a positive finite number" in err and err.count("\n") == 1


def test_a_damped_scene_linearized_away_from_rest_is_planned(fmu_paths, tmp_path):
    """A spring pendulum joined by a damped spring to a damped pendulum: linearized at its start the
    scene shows a growing mode (Re > 0), which is no instability of the motion and must not make every
    step look unstable."""
    from harness.studies.monolithic import MonolithicScene
    bob = [["x", "x"], ["y", "y"], ["v_x", "vx"], ["v_y", "vy"]]
    scene = {
        "name": "mixed", "stop": 1.5, "camera": {"frame_rate": 25},
        "components": {
            "link": {"fmu": "Spring", "start": {"k": 25.0, "c": 0.3, "l0": 1.2, "a_x": 0.0, "a_y": -1.0,
                                                "b_x": 1.2, "b_y": -1.0}},
            "springy": {"fmu": "SpringPendulum", "start": {"phi": 0.2, "eps": 0.05, "D": 40.0}},
            "swing": {"fmu": "SimplePendulum", "start": {"phi": -0.3, "anchor_x": 1.2, "L": 0.9, "d": 0.05}}},
        "connections": [[f"springy.{o}", f"link.a_{i}"] for o, i in bob]
        + [[f"swing.{o}", f"link.b_{i}"] for o, i in bob]
        + [["link.Fa_x", "springy.F_x"], ["link.Fa_y", "springy.F_y"], ["link.Fb_x", "swing.F2_x"],
           ["link.Fb_y", "swing.F2_y"]]}
    path = tmp_path / "mixed.json"
    path.write_text(json.dumps(scene))
    system = load_system(path)
    assert max(lam.real for lam in MonolithicScene(system).eigenvalues()) > 0  # what the plan must not trip on
    plan = plan_scene(system, 2e-3)
    assert [p.object for p in plan] == ["springy", "swing"]
    for p in plan:
        assert p.verified_error <= 2e-3 and p.cost < p.default_cost, p
