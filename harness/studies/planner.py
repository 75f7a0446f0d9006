"""The scene planner: per object, the cheapest model, method and internal step that still keeps every
visible point within the scene's position tolerance at every frame, for the scene's duration.

Any object made from an object file can be planned. How each candidate's error is predicted (before
it is trusted):
  * `model = linear` (closed form, for every object with a stable rest state and no force input set):
    its difference from the nonlinear motion is computed outright against the reference;
  * a fixed-step method at step h: step doubling on the frame grid, D = max |y_h - y_(h/2)|, error
    ~ D 2^p / (2^p - 1); trusted when a third run at h/4 shows the method's order (D(h)/D(h/2)
    within a factor 2.5 of 2^p) or D is below a hundredth of the tolerance;
  * a candidate is admitted only when its predicted error is at most half the tolerance and it is
    stable over the scene by the stability atlas's criterion (growth^(2N) <= 1.5 on the eigenvalues
    of the object linearized at rest, from its energies, N = duration / h; an object without a linear
    model, driven or singular at rest, relies on step doubling and the verification alone).
The cheapest admitted candidate (right-hand-side evaluations, or closed-form evaluations, over the
scene) is run against a tight reference with an error estimate below a hundredth of the tolerance:
for the thesis pendulums `reference.tight_reference` (exact, or long double over the hand-coded
equations), for every other object the FMU's own nystrom5 at a step where halving it changes the
visible points by less than that (`harness.studies.references`). That is the verified error. Should it
exceed the tolerance, the next cheapest candidate is verified instead. The visible points are the
scene's traces, by default the thesis pendulums' outer mass or an object's last point.

Objects joined by connections are planned together: one method and internal step for all objects
and a communication step H (Gauss-Seidel, linear extrapolation), predicted by doubling H and h
together and verified against the scene's derived monolithic reference (`harness.studies.monolithic`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from harness.cosim.structure import Component, System
from harness.errors import HarnessError
from harness.fmi.fmu_instance import accepted_methods, float_start_values, read_description
from harness.fmi.methods import PLANNABLE, plan_order, plan_solver
from harness.objects.proof import object_file_in
from harness.objects.thesis.equations import OUTER_MASS, Pendulum
from harness.objects.thesis.reference import tight_reference
from harness.studies.coupled_plan import plan_coupled
from harness.studies.chaos import (REGIME_FACTOR, Parting, conservative_reason, energy_error, lyapunov_exponent,
                                   perturbed, weight)
from harness.studies.chaos import horizon as chaos_horizon
from harness.studies.plans import DEFAULT, SAFETY, ObjectPlan, largest_distance, step_doubling
from harness.studies.references import ObjectRunner, fmu_reference, traced_columns
from harness.studies.stability import linearized_eigenvalues, plan_tables, stable_over
from harness.studies.sweep import run_sweep

SUBSTEPS = (1, 2, 3, 4, 5, 6, 8, 10, 12, 16, 20, 25, 32, 40, 50, 64, 80, 100, 128, 160, 200, 256, 320, 400)


@dataclass
class Candidate:
    model: str
    method: str
    h: float
    predicted: float
    cost: int
    how: str


THESIS_PENDULUMS = tuple(OUTER_MASS)


def plannable(fmu) -> list[str]:
    """The methods a plan may name that the FMU accepts, fixed-step methods first."""
    accepted = accepted_methods(str(fmu))
    return [m for m in PLANNABLE if plan_solver(m) in accepted]


def object_parameters(component: Component) -> dict[str, float]:
    """The FMU's Real start values with the scene's overrides."""
    return float_start_values(read_description(component.fmu), component.start)


def object_eigenvalues(kind: str, component: Component) -> list[complex] | None:
    """The object's eigenvalues linearized at rest, from the object file its FMU carries (a derived
    FMU's own energies, not the registry's object of the same name), or None for one without a
    linear model or an object file."""
    spec = object_file_in(component.fmu)
    if spec is None:
        return None
    try:
        return linearized_eigenvalues(spec, object_parameters(component))
    except ValueError:
        return None


def reference_positions(component: Component, kind: str, duration: float, frame: float,
                        columns: list[tuple[str, str]], tolerance: float,
                        eigenvalues: list[complex] | None) -> tuple[np.ndarray, float]:
    """The tight reference's visible points (frames, points, 2) and its estimated error
    (`eigenvalues`: the object's at rest, or None without a linear model)."""
    if kind not in THESIS_PENDULUMS:
        return _fmu_reference(component, duration, frame, columns, tolerance, eigenvalues)
    pendulum = Pendulum.from_fmu(component.fmu, component.start)
    eigen = max(abs(lam) for lam in eigenvalues)
    steps = max(4, math.ceil(frame * eigen / 0.02))  # h * |lambda| about 0.02 to start with
    for _ in range(4):
        reference = tight_reference(pendulum, duration, frame, steps)
        if reference.estimated_error <= tolerance / 100:
            break
        steps *= 2
    else:
        raise HarnessError(f"{component.name}: no reference within {tolerance / 100:.1e} m "
                           f"(estimate {reference.estimated_error:.1e} m)")
    points = pendulum.points(reference.states)
    return np.stack([points[c] for c in columns], axis=1), reference.estimated_error


def _fmu_reference(component: Component, duration: float, frame: float, columns: list[tuple[str, str]],
                   tolerance: float, eigenvalues: list[complex] | None) -> tuple[np.ndarray, float]:
    """The FMU's nystrom5 reference (`references.fmu_reference`) with an estimate below a hundredth of
    the tolerance, starting at h |lambda| = 0.05 or, without eigenvalues, a quarter of the default h."""
    with ObjectRunner(component, duration, frame, columns) as runner:
        first_h = min(frame, runner.default_h / 4) if eigenvalues is None else \
            min(frame, 0.05 / max(1e-12, max(abs(lam) for lam in eigenvalues)))
        positions, estimate, h = fmu_reference(runner, first_h, tolerance / 100, halvings=6)
    if not estimate <= tolerance / 100:
        raise HarnessError(f"{component.name}: no reference within {tolerance / 100:.1e} m "
                           f"(estimate {estimate:.1e} m at h = {h:.3g} s)")
    return positions, estimate


def _predict(runner: ObjectRunner, method: str, h: float, tolerance: float) -> tuple[float, int, str] | None:
    """Step doubling on h; (predicted error, evaluations at h, how) or None."""
    costs = {}

    def run(scale: float) -> np.ndarray:
        positions, costs[scale] = runner.run(runner.settings(method, h * scale))
        return positions
    predicted = step_doubling(run, plan_order(method), tolerance)
    return None if predicted is None else (predicted, costs[1.0], "step doubling")


def _parting(runner: ObjectRunner, twin: ObjectRunner, frame: float, tolerance: float) -> tuple[Parting, np.ndarray]:
    """The object's exponent and horizon from twin runs of nystrom5 at a quarter of its default step,
    and the unperturbed run's traced points."""
    settings = runner.settings("nystrom5", min(frame, runner.default_h / 4))
    base, _ = runner.run(settings)
    other, _ = twin.run(settings)
    lyapunov = lyapunov_exponent(base, other, frame)
    return Parting(lyapunov, chaos_horizon(lyapunov, tolerance)), base


def _plausible_plan(component: Component, kind: str, runner: ObjectRunner, twin: ObjectRunner, frame: float,
                    tolerance: float, pixel: float, reference: np.ndarray, parting: Parting,
                    stable) -> ObjectPlan | None:
    """The cheapest setting that keeps the energy within one pixel of the centre of mass's height, is
    stable over the scene and parts from its twin like the reference does (see harness.studies.chaos);
    None when the object's energy is not conserved or no setting qualifies."""
    if conservative_reason(component):
        return None
    weight_n = weight(component)
    if weight_n is None or not weight_n > 0:
        return None
    limit = weight_n * pixel
    found = []
    for method in plannable(component.fmu):
        for k in SUBSTEPS:
            h = frame / k
            if not stable(method, h):
                continue
            positions, cost = runner.run(runner.settings(method, h))
            error = energy_error(runner.energies)
            if not error <= limit:
                continue
            other, _ = twin.run(twin.settings(method, h))
            lyapunov = lyapunov_exponent(positions, other, frame)
            if parting.lyapunov / REGIME_FACTOR <= lyapunov <= parting.lyapunov * REGIME_FACTOR:
                found.append((cost, method, h, error, largest_distance(positions, reference)))
                break
    if not found:
        return None
    cost, method, h, error, distance = min(found)
    return ObjectPlan(component.name, kind, "nonlinear", method, h, distance, distance, cost, math.nan, 0,
                      "plausible: energy within a pixel of height, stable, parting like the reference",
                      tolerance, plan="plausible", lyapunov=parting.lyapunov, horizon=parting.horizon,
                      energy_error=error, energy_limit=limit)


def plan_object(job: tuple[Component, float, float, float, list, dict, float, bool]) -> ObjectPlan:
    """Plans one independent object (runs in a worker; `tables` are plan_tables(), read by the caller).
    `pixel`: metres per pixel of the scene's camera; `exact`: pointwise plans only."""
    component, duration, frame, tolerance, columns, tables, pixel, exact = job
    kind = read_description(component.fmu).coSimulation.modelIdentifier
    eigenvalues = object_eigenvalues(kind, component)
    runner = ObjectRunner(component, duration, frame, columns)
    twin = ObjectRunner(perturbed(component), duration, frame, columns) if object_file_in(component.fmu) else None

    def stable(method: str, h: float) -> bool:
        return eigenvalues is None or stable_over(tables[method], eigenvalues, h, duration)
    try:
        parting, close_run = _parting(runner, twin, frame, tolerance) if twin else (Parting(math.nan, math.nan), None)
        if parting.horizon < duration and not exact:
            # the path is not to be tracked: a tight reference would only say how far off the plan is,
            # which the nystrom5 run of the parting says as well
            plausible = _plausible_plan(component, kind, runner, twin, frame, tolerance, pixel, close_run, parting,
                                        stable)
            if plausible is not None:
                return _with_default(plausible, runner, close_run)
        reference, _ = reference_positions(component, kind, duration, frame, columns, tolerance, eigenvalues)
        plan = _pointwise_plan(component, kind, runner, frame, tolerance, reference, stable, duration)
        return replace(plan, lyapunov=parting.lyapunov, horizon=parting.horizon)
    finally:
        runner.close()
        if twin is not None:
            twin.close()


def _default_run(runner: ObjectRunner, reference: np.ndarray) -> tuple[tuple[str, float], float, int]:
    """The default (rk4 at the object's own default step, 0.008 s for the thesis pendulums), its error
    against the reference and its cost."""
    default = (DEFAULT[0], runner.default_h)
    positions, cost = runner.run(runner.settings(*default))
    return default, largest_distance(positions, reference), cost


def _with_default(plan: ObjectPlan, runner: ObjectRunner, reference: np.ndarray) -> ObjectPlan:
    """The plan with the default's error and cost filled in."""
    _, error, cost = _default_run(runner, reference)
    return replace(plan, default_error=error, default_cost=cost)


def _pointwise_plan(component: Component, kind: str, runner: ObjectRunner, frame: float, tolerance: float,
                    reference: np.ndarray, stable, duration: float) -> ObjectPlan:
    """The cheapest candidate whose error, verified against the reference, is within the tolerance."""
    candidates: list[Candidate] = []
    inputs = {v.name for v in runner.instance.model_description.modelVariables if v.causality == "input"}
    if runner.switchable and not inputs & set(component.start):
        # the FMU's closed form, one evaluation per frame: its error against the reference outright
        linear, _ = runner.run({"model": "linear", "h": frame})
        candidates.append(Candidate("linear", "closed form", frame, largest_distance(linear, reference),
                                    len(runner.grid) - 1, "closed form against the reference"))
    for method in plannable(component.fmu):
        for k in SUBSTEPS:
            h = frame / k
            if not stable(method, h):
                continue
            prediction = _predict(runner, method, h, tolerance)
            if prediction is not None and prediction[0] <= SAFETY * tolerance:
                candidates.append(Candidate("nonlinear", method, h, *prediction))
                break
    default, default_error, default_cost = _default_run(runner, reference)
    if stable(*default):
        prediction = _predict(runner, *default, tolerance)
        if prediction is not None and prediction[0] <= SAFETY * tolerance:
            candidates.append(Candidate("nonlinear", *default, prediction[0], default_cost, "step doubling"))
        elif default_error <= tolerance:  # the default is what the plan is measured against: always a choice
            candidates.append(Candidate("nonlinear", *default, default_error, default_cost, "the default, verified"))
    candidates.sort(key=lambda c: c.cost)
    for candidate in candidates:
        settings = ({"model": "linear", "h": frame} if candidate.model == "linear"
                    else runner.settings(candidate.method, candidate.h))
        positions, cost = runner.run(settings)
        verified = largest_distance(positions, reference)
        if verified <= tolerance:
            return ObjectPlan(component.name, kind, candidate.model, candidate.method, candidate.h,
                              candidate.predicted, verified, cost, default_error, default_cost, candidate.how,
                              tolerance)
    raise HarnessError(f"{component.name}: no candidate meets {tolerance:.3g} m over {duration:g} s "
                       f"(the finest tried was h = {frame / SUBSTEPS[-1]:.3g} s)")


MAX_FRAMES = 1_000_000  # a plan checks every frame several times: about a minute at this bound


def plan_scene(system: System, tolerance: float | None = None, duration: float | None = None,
               scheduler: str | None = None, workers: int | None = None, exact: bool = False) -> list[ObjectPlan]:
    """Plans every object of the scene. Where an independent object's predictability horizon is
    shorter than the scene, its plan is plausible rather than pointwise (harness.studies.chaos)
    unless `exact`."""
    tolerance = tolerance if tolerance is not None else system.tolerance()
    if tolerance is None:
        raise HarnessError(f"{system.name}: give --tolerance (metres) or an \"accuracy\" in the scene")
    if not (tolerance > 0 and math.isfinite(tolerance)):
        raise HarnessError(f"tolerance {tolerance} m: need a positive number")
    duration = duration if duration is not None else system.stop
    frame = system.frame_step()
    if duration is None or frame is None:
        raise HarnessError(f"{system.name}: the scene needs \"stop\" and a frame rate or \"step\"")
    if not frame <= duration:
        raise HarnessError(f"{system.name}: a frame every {frame:g} s is longer than the {duration:g} s planned; "
                           "raise the camera's frame rate or the duration")
    if duration / frame > MAX_FRAMES:
        raise HarnessError(f"{system.name}: {duration:g} s at a frame every {frame:g} s are more than {MAX_FRAMES:g} "
                           "frames; lower the camera's frame rate")
    if system.connections:
        return plan_coupled(system, tolerance, duration, frame, scheduler, workers)
    for component in system.components:
        if object_file_in(component.fmu) is None:
            raise HarnessError(f"{component.name}: only objects made from an object file can be planned alone")
    tables = plan_tables()
    scale = system.camera.get("scale")
    pixel = 1.0 / float(scale) if scale else tolerance  # without a camera, the tolerance stands for a pixel
    jobs = [(c, duration, frame, tolerance, _columns(system, c), tables, pixel, exact) for c in system.components]
    return run_sweep(plan_object, jobs, scheduler, workers)


def _columns(system: System, component: Component) -> list[tuple[str, str]]:
    if component.name in system.traces:
        return [tuple(pair) for pair in system.traces[component.name]]
    return [traced_columns(component.fmu)[:2]]  # what the scene's view shows of the traced point


def write_plan_csv(plans: list[ObjectPlan], path: Path) -> None:
    from harness.studies.records import write_records
    write_records(plans, path, ["object", "kind", "model", "method", "h", "communication_step", "predicted_error",
                                "verified_error", "cost", "default_error", "default_cost", "how", "plan", "lyapunov",
                                "horizon", "energy_error", "energy_limit"])
