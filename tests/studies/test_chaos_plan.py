"""Chaos-aware planning: the finite-time Lyapunov exponent and the predictability horizon, and the
plausible plan of the thesis scene's double pendulum (its motion parts faster than the scene lasts)
checked independently: its energy error through `simulate`, against the weight worked out by hand."""
from __future__ import annotations

import math

import numpy as np
import pytest

from harness.cosim.structure import System
from harness.fmi.simulation import simulate
from harness.scene.thesis_scene import load_thesis_scene
from harness.studies.chaos import REACHABLE_ERROR, horizon, lyapunov_exponent
from harness.studies.planner import plan_scene
from harness.studies.stability import linearized_eigenvalues, plan_tables, stable_over


def test_the_exponent_of_known_partings():
    frame = 0.04
    t = np.arange(501) * frame
    base = np.zeros((501, 1, 2))
    exponential = base.copy()
    exponential[:, 0, 0] = 1e-12 * np.exp(0.8 * t)  # reaches the saturation (1e-4 m) at about 23 s: not here
    assert lyapunov_exponent(base, exponential, frame) == pytest.approx(0.8, rel=1e-9)
    fast = base.copy()
    fast[:, 0, 0] = 1e-12 * np.exp(3.0 * t)  # saturates after about 8.4 s: measured up to there
    assert lyapunov_exponent(base, fast, frame) == pytest.approx(3.0, rel=1e-9)
    linear = base.copy()
    linear[:, 0, 0] = 1e-12 * (1 + t)  # regular motion parts linearly: a small exponent, a long horizon
    assert lyapunov_exponent(base, linear, frame) < 0.2
    assert horizon(lyapunov_exponent(base, linear, frame), 4e-3) > 80
    assert horizon(1.0, 4e-3) == pytest.approx(math.log(4e-3 / REACHABLE_ERROR))
    assert horizon(0.0, 4e-3) == math.inf


@pytest.fixture(scope="module")
def double_plans(fmu_paths):
    scene = load_thesis_scene()
    double = [c for c in scene.components if c.name == "double"]
    system = System("thesis double", double, [], stop=scene.stop, step=scene.step, accuracy=scene.accuracy,
                    camera=scene.camera, traces={"double": scene.traces["double"]})
    return system, plan_scene(system)[0], plan_scene(system, exact=True)[0]


def test_the_double_pendulum_parts_too_fast_for_a_pointwise_plan(double_plans):
    system, plausible, exact = double_plans
    assert 0.5 < plausible.lyapunov < 2.0 and plausible.horizon < system.stop
    assert plausible.plan == "plausible" and exact.plan == "pointwise"
    assert exact.lyapunov == plausible.lyapunov  # the same estimate; --exact only keeps the pointwise plan
    assert exact.verified_error <= exact.tolerance
    assert plausible.cost < exact.cost / 5  # what giving up the path buys


def test_the_plausible_plan_keeps_its_promises(double_plans):
    """Energy within one pixel of the centre of mass's height (M g / 250 with M = m1 + m2 = 2 kg),
    measured again through simulate; stable over the scene by the atlas's criterion."""
    system, plan, _ = double_plans
    start = dict(system.components[0].start)
    start.update(plan.settings)
    result = simulate(system.components[0].fmu, system.stop, 0.04, start_values=start)
    assert result.discarded_at is None
    drift = float(np.max(np.abs(result["E"] - result["E"][0])))
    limit = 2.0 * 9.81 / 250.0
    assert plan.energy_limit == pytest.approx(limit)
    assert drift == pytest.approx(plan.energy_error, rel=1e-9) and drift <= limit
    parameters = {k: float(v) for k, v in start.items() if not isinstance(v, str)}
    eigenvalues = linearized_eigenvalues("DoublePendulum", {"g": 9.81, "d": 0.0, "m1": 1.0, "m2": 1.0, **parameters})
    assert stable_over(plan_tables()[plan.method], eigenvalues, plan.h, system.stop)
    # pointwise it is far off, as any affordable run is: that is what "plausible" says
    assert plan.verified_error > plan.tolerance
