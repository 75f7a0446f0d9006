"""An independent monolithic reference of the coupled-pendulums scene, coded by hand: two simple
pendulums (phi'' = -g/L sin(phi) - d phi' + tangential force / (m L)) whose bobs a spring joins,
integrated by scipy's DOP853 at rtol = atol = 1e-12. The derived reference
(`harness.studies.monolithic`) is checked against it."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from harness.cosim.structure import System
from harness.fmi.fmu_instance import float_start_values, read_description


def _values(component) -> dict[str, float]:
    return float_start_values(read_description(component.fmu), component.start)


@dataclass(frozen=True)
class CoupledPair:
    left: dict
    right: dict
    spring: dict

    @classmethod
    def from_system(cls, system: System, left: str = "left", right: str = "right",
                    spring: str = "spring") -> "CoupledPair":
        """Parameters and starts of the coupled-pendulums scene (end a of the spring at `left`)."""
        return cls(*(_values(system.component(name)) for name in (left, right, spring)))

    def _bobs(self, y):
        a, b = self.left, self.right
        pa = np.array([a["anchor_x"] + a["L"] * np.sin(y[0]), a["anchor_y"] - a["L"] * np.cos(y[0])])
        pb = np.array([b["anchor_x"] + b["L"] * np.sin(y[2]), b["anchor_y"] - b["L"] * np.cos(y[2])])
        va = a["L"] * y[1] * np.array([np.cos(y[0]), np.sin(y[0])])
        vb = b["L"] * y[3] * np.array([np.cos(y[2]), np.sin(y[2])])
        return pa, pb, va, vb

    def rhs(self, t, y):
        a, b, s = self.left, self.right, self.spring
        pa, pb, va, vb = self._bobs(y)
        d = pb - pa
        r = math.hypot(*d)
        e = d / r
        force_on_a = (s["k"] * (r - s["l0"]) + s["c"] * float((vb - va) @ e)) * e
        # the tangential component of the force, divided by m L: the angular acceleration it adds
        torque_a = (force_on_a[0] * math.cos(y[0]) + force_on_a[1] * math.sin(y[0])) / (a["m"] * a["L"])
        torque_b = -(force_on_a[0] * math.cos(y[2]) + force_on_a[1] * math.sin(y[2])) / (b["m"] * b["L"])
        return [y[1], -a["g"] / a["L"] * math.sin(y[0]) - a["d"] * y[1] + torque_a,
                y[3], -b["g"] / b["L"] * math.sin(y[2]) - b["d"] * y[3] + torque_b]

    @property
    def start(self) -> list[float]:
        return [self.left["phi"], self.left["omega"], self.right["phi"], self.right["omega"]]

    def states(self, times: np.ndarray) -> np.ndarray:
        solution = solve_ivp(self.rhs, (times[0], times[-1]), self.start, method="DOP853", rtol=1e-12, atol=1e-12,
                             t_eval=times)
        assert solution.success
        return solution.y

    def reference(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (n, 2) of the bob at end a and at end b."""
        bobs = [self._bobs(y) for y in self.states(times).T]
        return np.array([b[0] for b in bobs]), np.array([b[1] for b in bobs])
