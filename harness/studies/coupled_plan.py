"""Planning coupled objects (see `harness.studies.planner`): two SimplePendulums joined by a Spring, stepped by
the Gauss-Seidel master with linear extrapolation. One method and internal step for the pendulums
and a communication step H are chosen together; the prediction doubles H and h together (the
coupling is second order, the method order p: error ~ D 2^q / (2^q - 1), q = min(2, p)), and the
plan is verified against the monolithic reference."""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from harness.cosim.master import MasterOptions, run_system
from harness.cosim.structure import System
from harness.errors import HarnessError
from harness.fmi.methods import ORDER
from harness.studies.coupling import CoupledPendulums
from harness.studies.plans import DEFAULT, SAFETY, ObjectPlan, largest_distance, step_doubling
from harness.studies.stability import linearized_eigenvalues, method_tables, stable_over

COMMUNICATION_DIVISORS = (1, 2, 4, 8, 16)
INTERNAL_DIVISORS = (1, 2, 4, 8, 16, 32)


def _run(system: System, names: tuple[str, str], method: str, H: float, h: float, duration: float,
         frame: float) -> tuple[np.ndarray, dict[str, int]]:
    """Both bobs at the frames (frames, 2, 2) and each pendulum's evaluations; inf after a stop."""
    components = [replace(c, start={**c.start, "solver": method, "h": h}) if c.name in names else c
                  for c in system.components]
    result = run_system(replace(system, components=components),
                        MasterOptions(stop=duration, step=H, algorithm="gauss-seidel", extrapolation="linear"))
    every = max(1, round(frame / H))
    frames = len(np.arange(0, len(result.time), every))
    positions = np.full((frames, 2, 2), np.inf)
    if result.stopped_at is None:
        for k, name in enumerate(names):
            positions[:, k, 0] = result[f"{name}.x"][::every]
            positions[:, k, 1] = result[f"{name}.y"][::every]
    # FmuInstance.work's count: a Jacobian of a simple pendulum is 2 directional derivatives
    evaluations = {name: int(result[f"{name}.n_rhs"][-1]) + 2 * int(result[f"{name}.n_jacobians"][-1])
                   for name in names}
    return positions, evaluations


def plan_coupled(system: System, tolerance: float, duration: float, frame: float, scheduler=None,
                 workers=None) -> list[ObjectPlan]:
    physics = CoupledPendulums.from_system(system)
    names = physics.names
    grid = np.arange(round(duration / frame) + 1) * frame
    left, right = physics.reference(grid)
    reference = np.stack([left, right], axis=1)
    tables = method_tables()
    # the stiffest motion: each pendulum's own mode, or the bobs bouncing on the spring
    spring_rate = math.sqrt(2 * physics.spring["k"] / min(physics.left["m"], physics.right["m"]))
    eigenvalues = [*linearized_eigenvalues("SimplePendulum", physics.left),
                   *linearized_eigenvalues("SimplePendulum", physics.right), 1j * spring_rate, -1j * spring_rate]

    def predict(method: str, H: float, h: float):
        evaluations = {}

        def run(scale: float) -> np.ndarray:
            positions, evaluations[scale] = _run(system, names, method, H * scale, h * scale, duration, frame)
            return positions
        predicted = step_doubling(run, min(2, ORDER[method]), tolerance)
        return None if predicted is None else (predicted, evaluations[1.0])

    candidates = []
    for m in COMMUNICATION_DIVISORS:
        H = frame / m
        for method in ORDER:
            for k in INTERNAL_DIVISORS:
                h = H / k
                if not stable_over(tables[method], eigenvalues, h, duration):
                    continue
                prediction = predict(method, H, h)
                if prediction is not None and prediction[0] <= SAFETY * tolerance:
                    candidates.append((sum(prediction[1].values()), method, H, h, prediction[0]))
                    break
        if candidates:
            break  # a coarser communication step already works: finer ones only add exchanges
    default_positions, default_evaluations = _run(system, names, *DEFAULT[:1], frame, DEFAULT[1], duration, frame)
    default_errors = [largest_distance(default_positions[:, k:k + 1], reference[:, k:k + 1]) for k in range(2)]
    if max(default_errors) <= tolerance:  # the default is what the plan is measured against: always a choice
        candidates.append((sum(default_evaluations.values()), DEFAULT[0], frame, DEFAULT[1], max(default_errors)))
    for cost, method, H, h, predicted in sorted(candidates):
        positions, evaluations = _run(system, names, method, H, h, duration, frame)
        errors = [largest_distance(positions[:, k:k + 1], reference[:, k:k + 1]) for k in range(2)]
        if max(errors) <= tolerance:
            return [ObjectPlan(name, "SimplePendulum", "nonlinear", method, h, predicted, errors[k],
                               evaluations[name], default_errors[k], default_evaluations[name],
                               "step doubling of H and h (coupled)", tolerance, H)
                    for k, name in enumerate(names)]
    raise HarnessError(f"{system.name}: no communication step down to {frame / COMMUNICATION_DIVISORS[-1]:.3g} s "
                       f"meets {tolerance:.3g} m")
