"""The pendulums' equations of motion coded by hand in Python, independent of the C models: the
right-hand sides for scipy's integrators and the long-double reference, and the position of each
object's outer mass (the point whose error the work-precision chart measures). Parameters and start
states come from the FMU's model description, so both sides start from the same numbers.

Equations (Lagrange, no external force):
  simple:  phi'' = -(g/L) sin phi - d phi'
  double:  M(q) q'' = f(q, q'), with M11 = m1 s1^2 + J1 + m2 l1^2, M12 = m2 l1 s2 cos(phi1 - phi2),
           M22 = m2 s2^2 + J2, f1 = -m2 l1 s2 sin(phi1 - phi2) omega2^2 - (m1 s1 + m2 l1) g sin phi1,
           f2 = m2 l1 s2 sin(phi1 - phi2) omega1^2 - m2 s2 g sin phi2; then -d omega_i
  spring:  r = l0 + eps; eps'' = r phi'^2 - (D/m) eps + g cos phi - d eps',
           phi'' = -(2 eps' phi' + g sin phi) / r - d phi'
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

STATES = {"SimplePendulum": ("phi", "omega"), "DoublePendulum": ("phi1", "phi2", "omega1", "omega2"),
          "SpringPendulum": ("phi", "eps", "omega", "v_eps")}
OUTER_MASS = {"SimplePendulum": ("x", "y"), "DoublePendulum": ("x2", "y2"), "SpringPendulum": ("x", "y")}


@dataclass
class Pendulum:
    """One pendulum's parameters and start state, with its right-hand side and outer-mass position."""
    name: str
    parameters: dict[str, float]
    start: list[float]
    # math for Python floats (fast scalar calls), numpy for long double
    lib: object = field(default=math, repr=False)

    @classmethod
    def from_fmu(cls, fmu: str | Path, overrides: dict[str, float] | None = None, lib=math) -> "Pendulum":
        from harness.fmi.fmu_instance import float_start_values, read_description
        description = read_description(Path(fmu))
        name = description.coSimulation.modelIdentifier
        values = float_start_values(description, overrides)
        return cls(name, values, [values[s] for s in STATES[name]], lib)

    def convert(self, dtype) -> "Pendulum":
        """The same pendulum computing in another float type (np.longdouble for the reference)."""
        return Pendulum(self.name, {k: dtype(v) for k, v in self.parameters.items()},
                        [dtype(v) for v in self.start], np)

    @property
    def rhs(self) -> Callable:
        return {"SimplePendulum": self._simple, "DoublePendulum": self._double,
                "SpringPendulum": self._spring}[self.name]

    def _simple(self, t, y):
        p, sin = self.parameters, self.lib.sin
        phi, omega = y
        return [omega, -p["g"] / p["L"] * sin(phi) - p["d"] * omega]

    def _double(self, t, y):
        p, sin, cos = self.parameters, self.lib.sin, self.lib.cos
        phi1, phi2, w1, w2 = y
        c, s = cos(phi1 - phi2), sin(phi1 - phi2)
        m11 = p["m1"] * p["s1"] ** 2 + p["J1"] + p["m2"] * p["l1"] ** 2
        m12 = p["m2"] * p["l1"] * p["s2"] * c
        m22 = p["m2"] * p["s2"] ** 2 + p["J2"]
        f1 = -p["m2"] * p["l1"] * p["s2"] * s * w2 * w2 - (p["m1"] * p["s1"] + p["m2"] * p["l1"]) * p["g"] * sin(phi1)
        f2 = p["m2"] * p["l1"] * p["s2"] * s * w1 * w1 - p["m2"] * p["s2"] * p["g"] * sin(phi2)
        det = m11 * m22 - m12 * m12
        return [w1, w2, (m22 * f1 - m12 * f2) / det - p["d"] * w1, (m11 * f2 - m12 * f1) / det - p["d"] * w2]

    def _spring(self, t, y):
        p, sin, cos = self.parameters, self.lib.sin, self.lib.cos
        phi, eps, omega, v = y
        r = p["l0"] + eps
        return [omega, v, -(2 * v * omega + p["g"] * sin(phi)) / r - p["d"] * omega,
                r * omega * omega - p["D"] / p["m"] * eps + p["g"] * cos(phi) - p["d"] * v]

    def outer_mass(self, states: np.ndarray) -> np.ndarray:
        """Positions (n, 2) of the outer mass for states (n, n_states)."""
        return self.points(states)[OUTER_MASS[self.name]]

    def traced_point(self, states: np.ndarray, times: np.ndarray | None = None) -> np.ndarray:
        """The point the studies trace (the outer mass; the anchor does not move, so times do not matter)."""
        return self.outer_mass(states)

    def points(self, states: np.ndarray) -> dict[tuple[str, str], np.ndarray]:
        """Positions (n, 2) of every point the FMU reports, keyed by its output columns."""
        p = self.parameters
        s = np.asarray(states)
        if self.name == "SimplePendulum":
            chain = [(("x", "y"), p["L"], s[:, 0])]
        elif self.name == "DoublePendulum":
            chain = [(("x1", "y1"), p["l1"], s[:, 0]), (("x2", "y2"), p["l2"], s[:, 1])]
        else:
            chain = [(("x", "y"), p["l0"] + s[:, 1], s[:, 0])]
        x, y, out = p["anchor_x"], p["anchor_y"], {}
        for columns, length, angle in chain:
            x, y = x + length * np.sin(angle), y - length * np.cos(angle)
            out[columns] = np.column_stack([x * np.ones(len(s)), y * np.ones(len(s))])
        return out
