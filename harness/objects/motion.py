"""An object's equations of motion as a plain Python right-hand side, for integrators outside the FMU
(scipy's, the work-precision peers): lambdified from the SymPy derivation, never from the generated C,

    q' = v,   v' = M(q, t)^-1 (f(q, v, t) + Q(q, t) F) - d v,

with the force inputs F held at their given values, and the positions of the object's points.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from harness.objects.derivation import Derivation


@dataclass
class ObjectMotion:
    """One object with its parameter, input and start values (by variable name)."""
    derivation: Derivation
    values: dict[str, float]
    _forcing: object = field(init=False, repr=False)
    _points: list = field(init=False, repr=False)

    def __post_init__(self):
        spec, d = self.derivation.spec, self.derivation
        # one call gives M row by row, then f + Q F; common subexpressions evaluated once
        arguments = spec.q + spec.v + [spec.time]
        fixed = {symbol: self.values[str(symbol)] for symbol in spec.parameter_symbols() + d.inputs}
        M = d.M.subs(fixed)
        forcing = (d.f + d.Q).subs(fixed)
        self._forcing = sp.lambdify(arguments, list(M) + list(forcing), "math", cse=True)
        self._points = [sp.lambdify(arguments, [x.subs(fixed) for x in position], "numpy")
                        for position in d.positions]

    @property
    def name(self) -> str:
        return self.derivation.spec.identifier

    @property
    def start(self) -> list[float]:
        spec = self.derivation.spec
        return [self.values[c.name] for c in spec.coordinates] + [self.values[c.velocity] for c in spec.coordinates]

    def rhs(self, t: float, y) -> list[float]:
        n = self.derivation.n
        q, v = list(y[:n]), list(y[n:])
        entries = self._forcing(*q, *v, t)
        M = np.array(entries[:n * n], dtype=float).reshape(n, n)
        a = np.linalg.solve(M, np.array(entries[n * n:], dtype=float))
        d = self.values.get("d", 0.0)
        return v + [float(a[j]) - d * v[j] for j in range(n)]

    def point(self, index: int, states: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Positions (rows, 2 or 3) of point `index` (in the object file's order) for states (rows, 2n)
        at times (rows)."""
        s = np.asarray(states, dtype=float)
        n = self.derivation.n
        columns = self._points[index](*s[:, :n].T, *s[:, n:].T, np.asarray(times, dtype=float))
        return np.column_stack([np.broadcast_to(np.asarray(c, dtype=float), (len(s),)) for c in columns])

    def traced_point(self, states: np.ndarray, times: np.ndarray) -> np.ndarray:
        """The object's last point, the one the studies trace."""
        return self.point(len(self._points) - 1, states, times)
