"""An independent numeric route to an object's accelerations, for checking the generated FMU.

Nothing here comes from the symbolic derivation or the generated C: T, U and the points are
evaluated plainly (the object file's expressions, as functions of numbers), and every derivative
Lagrange's equations need is taken numerically, by mpmath's high-precision finite differences:

    M_jk = d2T/dv_j dv_k,   f_j = dL/dq_j - sum_k d2T/dv_j dq_k v_k - d2T/dv_j dt,
    Q_j = sum over force inputs F . dr/dq_j,   a = M^-1 (f + Q) - d v.
"""
from __future__ import annotations

from dataclasses import dataclass

import mpmath
import numpy as np
import sympy as sp

from harness.objects.object_file import FRAMEWORK_PARAMETERS, ObjectSpec

mpmath.mp.dps = 40


@dataclass
class NumericLagrangian:
    spec: ObjectSpec

    def __post_init__(self):
        spec = self.spec
        self.parameter_names = [p.name for p in spec.parameters if p.name not in FRAMEWORK_PARAMETERS]
        self.n = len(spec.coordinates)
        arguments = [spec.symbols[name] for name in self.parameter_names] + spec.q + spec.v + [spec.time]
        self._T = sp.lambdify(arguments, spec.T, "mpmath")
        self._U = sp.lambdify(arguments, spec.U, "mpmath")
        point_by_name = {p.name: p for p in spec.points}
        self._forces = []
        for force in spec.forces:
            position = point_by_name[force.point].position
            for axis, name in force.inputs.items():
                self._forces.append((name, sp.lambdify(arguments, position["xyz".index(axis)], "mpmath")))

    def accelerations(self, values: dict[str, float], t: float = 0.0) -> np.ndarray:
        """a for the parameters, states and force inputs in values (missing inputs are 0)."""
        spec, n = self.spec, self.n
        p = [mpmath.mpf(values[name]) for name in self.parameter_names]
        q = [mpmath.mpf(values[c.name]) for c in spec.coordinates]
        v = [mpmath.mpf(values[c.velocity]) for c in spec.coordinates]
        t = mpmath.mpf(t)

        def at(function, q_, v_, t_):
            return function(*p, *q_, *v_, t_)

        def lagrangian(*z):
            return at(self._T, z[:n], z[n:2 * n], z[2 * n]) - at(self._U, z[:n], z[n:2 * n], z[2 * n])

        def kinetic(*z):
            return at(self._T, z[:n], z[n:2 * n], z[2 * n])

        z = q + v + [t]
        M = mpmath.matrix(n, n)
        f = mpmath.matrix(n, 1)
        for j in range(n):
            for k in range(n):
                orders = [0] * (2 * n + 1)
                orders[n + j] += 1
                orders[n + k] += 1
                M[j, k] = mpmath.diff(kinetic, z, orders)
            orders = [0] * (2 * n + 1)
            orders[j] = 1
            value = mpmath.diff(lagrangian, z, orders)
            for k in range(n):
                orders = [0] * (2 * n + 1)
                orders[n + j] = 1
                orders[k] = 1
                value -= mpmath.diff(kinetic, z, orders) * v[k]
            orders = [0] * (2 * n + 1)
            orders[n + j] = 1
            orders[2 * n] = 1
            value -= mpmath.diff(kinetic, z, orders)
            for name, position in self._forces:
                F = mpmath.mpf(values.get(name, 0.0))
                if F:
                    orders = [0] * (2 * n + 1)
                    orders[j] = 1
                    value += F * mpmath.diff(lambda *w: at(position, w[:n], w[n:2 * n], w[2 * n]), z, orders)
            f[j] = value
        a = mpmath.lu_solve(M, f)
        d = mpmath.mpf(values.get("d", 0.0))
        return np.array([float(a[j] - d * v[j]) for j in range(n)])

    def energies(self, values: dict[str, float], t: float = 0.0) -> tuple[float, float]:
        spec = self.spec
        args = [values[name] for name in self.parameter_names] + [values[c.name] for c in spec.coordinates] + \
               [values[c.velocity] for c in spec.coordinates] + [t]
        return float(self._T(*args)), float(self._U(*args))
