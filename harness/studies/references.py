"""Running one object on a grid of frames, and the FMU's own tight reference for any object.

The thesis pendulums have hand-coded references (`harness.objects.thesis.reference`); every other
object is measured against its FMU's nystrom5 (order 5) at a step where halving the step changes the
traced points by little: |y_h - y_(h/2)| / 31 estimates the error of the finer run. The reference
shares the FMU's right-hand side with what it measures, so it measures the methods' error, not the
model's: the model itself is proven against an independent numeric route by `harness validate`.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from harness.cosim.structure import Component
from harness.fmi.fmu_instance import FmuInstance, read_description
from harness.fmi.methods import plan_settings
from harness.fmi.simulation import Recorder, communication_grid
from harness.objects.proof import object_file_in
from harness.objects.thesis.equations import OUTER_MASS
from harness.studies.plans import largest_distance

REFERENCE_METHOD, REFERENCE_ORDER = "nystrom5", 5


def traced_columns(fmu: str | Path) -> tuple[str, ...]:
    """The output names of the point the studies trace by default: the thesis pendulums' outer mass,
    any other object's last point (x, y and, for a 3-D point, z)."""
    kind = read_description(Path(fmu)).coSimulation.modelIdentifier
    if kind in OUTER_MASS:
        return OUTER_MASS[kind]
    spec = object_file_in(fmu)
    if spec is None or not spec.points:
        raise ValueError(f"{Path(fmu).name}: no object file with points to trace")
    last = spec.points[-1]
    return tuple(last.outputs[axis] for axis in ("x", "y", "z") if axis in last.outputs)


class ObjectRunner:
    """Runs one object (an FMU with the given start values) on the frame grid, recording the traced
    points: each a tuple of output names of equal length (x, y or x, y, z)."""

    def __init__(self, component: Component, duration: float, frame: float, columns: list[tuple[str, ...]]):
        self.component = component
        self.instance = FmuInstance(component.fmu, name=component.name)
        self.switchable = "model" in self.instance.variables  # an object with a linear model
        self.grid = communication_grid(0.0, duration, frame)
        self.columns = columns
        self.recorder = Recorder(self.instance, self.grid, [c for point in columns for c in point] + ["E"])
        self.energies = np.empty(0)  # E at the frames of the last run (inf after a discard)

    @property
    def default_h(self) -> float:
        return float(self.instance.variables["h"].start)

    def settings(self, method: str, h: float) -> dict:
        """Start values for a fixed-step run of the nonlinear model with a method a plan may name."""
        settings = plan_settings(method, h)
        if self.switchable:
            settings["model"] = "nonlinear"
        return settings

    def run(self, overrides: dict) -> tuple[np.ndarray, int]:
        """Positions (frames, points, width) and the evaluations spent (`FmuInstance.work`: the implicit
        methods' Jacobians included); inf positions after a discard."""
        instance = self.instance
        instance.reset()
        instance.initialize(0.0, **{**self.component.start, **overrides})
        result = self.recorder.run()
        width = len(self.columns[0])
        positions = np.full((len(self.grid), len(self.columns), width), np.inf)
        rows = len(result.values) if result.discarded_at is None else len(result.values) - 1
        for k, point in enumerate(self.columns):
            for axis, name in enumerate(point):
                positions[:rows, k, axis] = result[name][:rows]
        self.energies = np.full(len(self.grid), np.inf)
        self.energies[:rows] = result["E"][:rows]
        evaluations = instance.work()
        if overrides.get("model") == "linear":
            evaluations = int(instance.get("n_steps")[0])
        return positions, evaluations

    def close(self) -> None:
        self.instance.free()

    def __enter__(self) -> "ObjectRunner":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def fmu_reference(runner: ObjectRunner, first_h: float, target: float,
                  halvings: int = 8) -> tuple[np.ndarray, float, float]:
    """nystrom5 from the frame step divided down to about first_h, halving the step until the finer
    run's estimated error is at most target, the estimate stops falling (rounding has taken over) or
    `halvings` are spent. Returns the positions of the finer run with the smallest estimate, that
    estimate, and its step."""
    frame = float(runner.grid[1] - runner.grid[0])
    steps = max(1, math.ceil(frame / first_h))
    coarse, _ = runner.run(runner.settings(REFERENCE_METHOD, frame / steps))
    best = (coarse, math.inf, frame / steps)
    for _ in range(halvings):
        steps *= 2
        fine, _ = runner.run(runner.settings(REFERENCE_METHOD, frame / steps))
        estimate = largest_distance(coarse, fine) / (2 ** REFERENCE_ORDER - 1)
        if math.isfinite(best[1]) and not estimate < best[1]:
            break
        if estimate < best[1]:
            best = (fine, estimate, frame / steps)
        if estimate <= target:
            break
        coarse = fine
    return best
