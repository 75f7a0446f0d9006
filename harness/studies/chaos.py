"""Chaos over a scene: how fast nearby motions part, and what can be promised where they part fast.

The largest finite-time Lyapunov exponent over the scene comes from a perturbed twin run: the
object's first coordinate moved by PERTURBATION, both runs with the same tight method and step, and
d(t) the running maximum of the distance between their traced points. Until d reaches SATURATION
(well below the object's size, so that the parting is still linear) or the scene ends,
lambda = ln(d(t_end) / d(t_1)) / (t_end - t_1), t_1 the first frame.

The predictability horizon is the time over which an error of REACHABLE_ERROR grows to the
tolerance: ln(tolerance / REACHABLE_ERROR) / lambda. REACHABLE_ERROR, 1e-10 m, is what a fixed-step
method of the FMUs leaves after the first second of a thesis pendulum at a few times its default
cost (ab6 at h = 0.004 on the simple pendulum: 6e-11 m after 10 s); tracking beyond the horizon
needs errors per step that only a cost far above the scene's buys. Regular motion parts linearly:
its exponent is small and its horizon long.

Where the horizon is shorter than the scene the planner offers a plausible plan instead of a
pointwise one: the energy error stays below what raising the centre of mass by one pixel would show
(the object's weight M g, its parameters in kg summed times its g, times the pixel), the method is
stable over the scene, and the motion
stays in the same regime: no step discarded, and its own twin run parts at an exponent within a
factor REGIME_FACTOR of the reference's (chaotic stays chaotic, regular stays regular).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from harness.cosim.structure import Component
from harness.fmi.calls import is_float
from harness.fmi.fmu_instance import read_description
from harness.objects.proof import object_file_in

PERTURBATION = 1e-12  # of the first coordinate (rad or m)
SATURATION = 1e-4     # metres: the parting is measured while it is below this
REACHABLE_ERROR = 1e-10  # metres
REGIME_FACTOR = 2.0


@dataclass
class Parting:
    lyapunov: float  # 1/s
    horizon: float   # s, for the tolerance


def lyapunov_exponent(base: np.ndarray, twin: np.ndarray, frame: float) -> float:
    """The finite-time exponent from two runs' traced points (frames, points, width)."""
    distance = np.maximum.accumulate(np.max(np.linalg.norm(base - twin, axis=-1), axis=1))
    if not np.all(np.isfinite(distance)) or len(distance) < 3 or not distance[1] > 0:
        return math.nan
    end = int(np.searchsorted(distance, SATURATION))  # the first frame at or past saturation
    end = min(max(end, 2), len(distance) - 1)
    return math.log(distance[end] / distance[1]) / ((end - 1) * frame)


def horizon(lyapunov: float, tolerance: float) -> float:
    if not lyapunov > 0:
        return math.inf
    return math.log(tolerance / REACHABLE_ERROR) / lyapunov


def perturbed(component: Component) -> Component:
    """The component with its first coordinate moved by PERTURBATION."""
    spec = object_file_in(component.fmu)
    first = spec.coordinates[0]
    value = component.start.get(first.name, first.start)
    return replace(component, start={**component.start, first.name: float(value) + PERTURBATION})


def weight(component: Component) -> float | None:
    """M g [N]: the object's mass (the sum of its parameters in kg) times its parameter g, at the
    scene's values; None for an object without both."""
    variables = read_description(component.fmu).modelVariables
    value = {v.name: float(component.start.get(v.name, v.start)) for v in variables
             if v.causality == "parameter" and is_float(v) and v.start is not None}
    masses = [value[v.name] for v in variables if v.name in value and v.unit == "kg"]
    if not masses or "g" not in value:
        return None
    return sum(masses) * value["g"]


def conservative_reason(component: Component) -> str:
    """Why the object's energy is not conserved in this scene (empty when it is)."""
    spec = object_file_in(component.fmu)
    if spec is None:
        return "it has no object file"
    if spec.rheonomic:
        return "its energies depend on time"
    if float(component.start.get("d", 0.0)) != 0.0:
        return "it is damped"
    forces = {name for force in spec.forces for name in force.inputs.values()}
    if any(float(component.start.get(name, 0.0)) != 0.0 for name in forces):
        return "a force acts on it"
    return ""


def energy_error(energies: np.ndarray) -> float:
    return float(np.max(np.abs(energies - energies[0]))) if np.all(np.isfinite(energies)) else math.inf
