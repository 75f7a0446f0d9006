"""Normal modes of an object about its rest state, from its energies: the quadratic approximation
M0 (q - rest)'' + K0 (q - rest) = 0 of the derivation, evaluated at given parameter values and solved
as the generalized symmetric eigenproblem K0 v = omega^2 M0 v. The thesis damping d adds -d v to
every acceleration, so each mode's eigenvalues solve lambda^2 + d lambda + omega^2 = 0."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from harness.objects.derivation import Derivation
from harness.objects.object_file import FRAMEWORK_PARAMETERS


@dataclass
class NormalModes:
    coordinates: list[str]
    rest: dict[str, float]        # coordinate -> rest value
    squares: np.ndarray           # omega^2 per mode [1/s^2], ascending
    shapes: np.ndarray            # columns: each mode's coordinate displacements

    def eigenvalues(self, d: float = 0.0) -> list[complex]:
        return [(-d + sign * complex(d * d - 4 * w2) ** 0.5) / 2 for w2 in self.squares for sign in (1, -1)]

    def fastest_release(self, amplitude: float) -> dict[str, float]:
        """Coordinates released from rest in the fastest mode, its largest displacement `amplitude`."""
        shape = self.shapes[:, int(np.argmax(self.squares))]
        shape = amplitude * shape / np.max(np.abs(shape))
        return {name: self.rest[name] + float(x) for name, x in zip(self.coordinates, shape)}


def normal_modes(derivation: Derivation, parameters: dict[str, float] | None = None) -> NormalModes | None:
    """The modes at the object's defaults overridden by `parameters`; None for an object without a
    linear model (driven, unstable or singular at rest)."""
    linear = derivation.linear
    if linear is None:
        return None
    spec = derivation.spec
    values = {p.name: p.start for p in spec.parameters if p.name not in FRAMEWORK_PARAMETERS}
    values.update({k: v for k, v in (parameters or {}).items() if k in values})
    substitution = {spec.symbols[name]: value for name, value in values.items()}

    def numeric(matrix) -> np.ndarray:
        return np.array(matrix.subs(substitution).evalf(), dtype=float)

    squares, shapes = scipy.linalg.eigh(numeric(linear.K0), numeric(linear.M0))
    names = [c.name for c in spec.coordinates]
    rest = {name: float(r.subs(substitution)) for name, r in zip(names, linear.rest)}
    return NormalModes(names, rest, squares, shapes)
