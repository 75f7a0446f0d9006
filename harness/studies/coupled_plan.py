"""Planning coupled objects (see `harness.studies.planner`): any scene of objects joined by Springs,
stepped by the Gauss-Seidel master with linear extrapolation. One method and internal step for all
objects and a communication step H are chosen together; the prediction doubles H and h together
(the coupling is second order, the method order p: error ~ D 2^q / (2^q - 1), q = min(2, p)), and
the plan is verified against the scene's derived monolithic reference (`harness.studies.monolithic`).
Stability is judged on the eigenvalues of the whole scene's equations linearized at its start (a
positive real part, which linearizing away from rest can give, counted as zero)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from harness.cosim.master import MasterOptions, run_system
from harness.cosim.structure import System
from harness.errors import HarnessError
from harness.fmi.fmu_instance import SharedFmus, accepted_methods
from harness.fmi.methods import PLANNABLE, plan_order, plan_settings, plan_solver
from harness.studies.coupling import derived_reference
from harness.studies.monolithic import MonolithicScene
from harness.studies.plans import DEFAULT, SAFETY, ObjectPlan, largest_distance, step_doubling
from harness.studies.stability import plan_tables, stable_over

COMMUNICATION_DIVISORS = (1, 2, 4, 8, 16)
INTERNAL_DIVISORS = (1, 2, 4, 8, 16, 32)


def _run(system: System, objects: dict[str, int], pairs: list[tuple[str, str]], method: str, H: float, h: float,
         duration: float, frames: np.ndarray, fmus: SharedFmus) -> tuple[np.ndarray, dict[str, int]]:
    """Every object point at the frame times (frames, points, 2), which are whole multiples of H, and
    each object's evaluations (a Jacobian counts one per state, as `FmuInstance.work`); inf after a
    stop."""
    components = [replace(c, start={**c.start, **plan_settings(method, h)}) if c.name in objects else c
                  for c in system.components]
    result = run_system(replace(system, components=components),
                        MasterOptions(stop=duration, step=H, algorithm="gauss-seidel", extrapolation="linear"), fmus)
    rows = np.rint(frames / H).astype(int)
    positions = np.full((len(frames), len(pairs), 2), np.inf)
    if result.stopped_at is None:
        for k, (x, y) in enumerate(pairs):
            positions[:, k, 0] = result[x][rows]
            positions[:, k, 1] = result[y][rows]
    evaluations = {name: int(result[f"{name}.n_rhs"][-1]) + states * int(result[f"{name}.n_jacobians"][-1])
                   for name, states in objects.items()}
    return positions, evaluations


def plan_coupled(system: System, tolerance: float, duration: float, frame: float, scheduler=None,
                 workers=None) -> list[ObjectPlan]:
    # the candidates' runs, a thousand on a scene of three FMUs, share each FMU's extraction and library
    with SharedFmus() as shared:
        return _plan_coupled(system, tolerance, duration, frame, shared)


def _plan_coupled(system: System, tolerance: float, duration: float, frame: float,
                  shared: SharedFmus) -> list[ObjectPlan]:
    scene = MonolithicScene(system)
    objects = {name: 2 * kind.functions["n"] for kind in scene.kinds.values() for name in kind.names}
    kinds = {name: identifier for identifier, kind in scene.kinds.items() for name in kind.names}
    grid = np.arange(int(np.floor(duration / frame + 1e-9)) + 1) * frame  # the frames within the duration
    columns, pairs = derived_reference(system, grid)
    reference = np.stack([np.column_stack([columns[x], columns[y]]) for x, y in pairs], axis=1)
    owner = [x.split(".")[0] for x, _ in pairs]  # the object each traced point belongs to
    tables = plan_tables()
    # Linearized away from rest the equations can show a growing mode (a positive real part) that is no
    # instability of the motion: stability is judged on the frequencies and on the damping there is.
    eigenvalues = [complex(min(lam.real, 0.0), lam.imag) for lam in scene.eigenvalues()]
    fmus = {str(system.component(name).fmu) for name in objects}
    methods = [m for m in PLANNABLE if all(plan_solver(m) in accepted_methods(fmu) for fmu in fmus)]  # one for all

    def errors_of(positions: np.ndarray) -> dict[str, float]:
        return {name: largest_distance(positions[:, [k for k, o in enumerate(owner) if o == name]],
                                       reference[:, [k for k, o in enumerate(owner) if o == name]])
                for name in objects}

    def predict(method: str, H: float, h: float):
        evaluations = {}

        def run(scale: float) -> np.ndarray:
            positions, evaluations[scale] = _run(system, objects, pairs, method, H * scale, h * scale, duration,
                                                 grid, shared)
            return positions
        predicted = step_doubling(run, min(2, plan_order(method)), tolerance)
        return None if predicted is None else (predicted, evaluations[1.0])

    candidates = []
    for m in COMMUNICATION_DIVISORS:
        H = frame / m
        for method in methods:
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
    default_positions, default_evaluations = _run(system, objects, pairs, DEFAULT[0], frame, DEFAULT[1], duration,
                                                  grid, shared)
    default_errors = errors_of(default_positions)
    if max(default_errors.values()) <= tolerance:  # the default is what the plan is measured against: always a choice
        candidates.append((sum(default_evaluations.values()), DEFAULT[0], frame, DEFAULT[1],
                           max(default_errors.values())))
    for cost, method, H, h, predicted in sorted(candidates):
        positions, evaluations = _run(system, objects, pairs, method, H, h, duration, grid, shared)
        errors = errors_of(positions)
        if max(errors.values()) <= tolerance:
            return [ObjectPlan(name, kinds[name], "nonlinear", method, h, predicted, errors[name],
                               evaluations[name], default_errors[name], default_evaluations[name],
                               "step doubling of H and h (coupled)", tolerance, H)
                    for name in objects]
    raise HarnessError(f"{system.name}: no communication step down to {frame / COMMUNICATION_DIVISORS[-1]:.3g} s "
                       f"meets {tolerance:.3g} m")
