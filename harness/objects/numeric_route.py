"""An independent numeric route to an object's accelerations, for checking the generated FMU.

Nothing here comes from the symbolic derivation or the generated C: T, U, the points and the gaps are
evaluated plainly (the object file's expressions, as functions of numbers), and every derivative
Lagrange's equations need is taken numerically, by mpmath's high-precision finite differences:

    M_jk = d2T/dv_j dv_k,   f_j = dL/dq_j - sum_k d2T/dv_j dq_k v_k - d2T/dv_j dt,
    Q_j = sum over force inputs F . dr/dq_j,   a_free = M^-1 (f + Q) - d v.

Constraints (Lagrange's equations of the first kind): G_ij = dg_i/dq_j, the gap's rate G v + dg/dt and
gamma_i = d2/ds2 g_i(q + s v, t + s) at s = 0 (its second derivative along the motion at a = 0). A
compliant constraint adds M^-1 G_i^T F_i with F_i = k delta^e (1 + c d(delta)/dt), never pulling, where
the overlap delta = -g_i is positive; the acting rigid ones S (bilateral, and the unilateral ones given
as active) add M^-1 G_S^T lambda with (G_S M^-1 G_S^T) lambda = -gamma_S - G_S a.
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
        self._gaps = [sp.lambdify(arguments, c.gap, "mpmath") for c in spec.constraints]
        self._laws = [(sp.lambdify(arguments, c.stiffness, "mpmath"), c.exponent,
                       sp.lambdify(arguments, c.damping, "mpmath")) if c.compliant else None for c in spec.constraints]
        point_by_name = {p.name: p for p in spec.points}
        self._forces = []
        for force in spec.forces:
            position = point_by_name[force.point].position
            for axis, name in force.inputs.items():
                self._forces.append((name, sp.lambdify(arguments, position["xyz".index(axis)], "mpmath")))

    def accelerations(self, values: dict[str, float], t: float = 0.0,
                      active: frozenset[int] = frozenset()) -> np.ndarray:
        """a for the parameters, states and force inputs in values (missing inputs are 0), with the rigid
        unilateral constraints whose indices are in `active` acting (bilateral ones always act)."""
        a, _ = self._motion(values, t, active)
        return np.array([float(value) for value in a])

    def forces(self, values: dict[str, float], t: float = 0.0, active: frozenset[int] = frozenset()) -> np.ndarray:
        """Each constraint's force: lambda of an acting rigid one, the compliant law's, else 0."""
        _, force = self._motion(values, t, active)
        return np.array([float(value) for value in force])

    def gaps(self, values: dict[str, float], t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Each gap and its rate."""
        p, q, v, t = self._numbers(values, t)
        return (np.array([float(g(*p, *q, *v, t)) for g in self._gaps]),
                np.array([float(self._along(g, p, q, v, t, 1)) for g in self._gaps]))

    def resting(self, values: dict[str, float], t: float = 0.0) -> frozenset[int]:
        """The rigid unilateral constraints that act at a start (SPEC 10): touching at rest (gap and rate
        within 1e-12), the motion left free closing them faster than 1e-6 per second squared, and their
        force pushing; taken in the file's order."""
        gaps, rates = self.gaps(values, t)
        active: frozenset[int] = frozenset()
        for i, c in enumerate(self.spec.constraints):
            if c.compliant or c.bilateral or abs(gaps[i]) > 1e-12 or abs(rates[i]) > 1e-12:
                continue
            p, q, v, t_ = self._numbers(values, t)
            a, _ = self._motion(values, t, active)
            n = self.n
            G = [mpmath.diff(lambda *w: self._gaps[i](*p, *w[:n], *v, w[n]), q + [t_],
                             [int(k == j) for k in range(n)] + [0])
                 for j in range(n)]
            closing = self._along(self._gaps[i], p, q, v, t_, 2) + sum(G[j] * a[j] for j in range(n))
            if closing < -1e-6 and self.forces(values, t, active | {i})[i] > 0:
                active = active | {i}
        return active

    def _numbers(self, values: dict[str, float], t: float):
        spec = self.spec
        return ([mpmath.mpf(values[name]) for name in self.parameter_names],
                [mpmath.mpf(values[c.name]) for c in spec.coordinates],
                [mpmath.mpf(values[c.velocity]) for c in spec.coordinates], mpmath.mpf(t))

    @staticmethod
    def _along(gap, p, q, v, t, order: int):
        """The order-th derivative of the gap along the motion with zero acceleration: rate (1), gamma (2)."""
        return mpmath.diff(lambda s: gap(*p, *[qj + s * vj for qj, vj in zip(q, v)], *v, t + s), 0, order)

    def _motion(self, values: dict[str, float], t: float, active: frozenset[int]):
        spec, n = self.spec, self.n
        p, q, v, t = self._numbers(values, t)

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
        a = mpmath.matrix([a[j] - d * v[j] for j in range(n)])
        force = [mpmath.mpf(0)] * len(spec.constraints)
        if not spec.constraints:
            return a, force
        G = [[mpmath.diff(lambda *w: gap(*p, *w[:n], *v, w[n]), q + [t], [int(k == j) for k in range(n)] + [0])
              for j in range(n)] for gap in self._gaps]
        for i, (gap, law) in enumerate(zip(self._gaps, self._laws)):
            overlap = -gap(*p, *q, *v, t)
            if law is None or overlap <= 0:
                continue
            stiffness, exponent, damping = law
            rate = self._along(gap, p, q, v, t, 1)
            force[i] = max(mpmath.mpf(0), stiffness(*p, *q, *v, t) * overlap ** exponent *
                           (1 - damping(*p, *q, *v, t) * rate))
            a += mpmath.lu_solve(M, mpmath.matrix([G[i][j] * force[i] for j in range(n)]))
        acting = [i for i, c in enumerate(spec.constraints) if not c.compliant and (c.bilateral or i in active)]
        if acting:
            Y = [mpmath.lu_solve(M, mpmath.matrix(G[i])) for i in acting]
            W = mpmath.matrix([[sum(G[i][j] * Y[b][j] for j in range(n)) for b in range(len(acting))] for i in acting])
            r = mpmath.matrix([-self._along(self._gaps[i], p, q, v, t, 2) - sum(G[i][j] * a[j] for j in range(n))
                               for i in acting])
            lam = mpmath.lu_solve(W, r)
            for b, i in enumerate(acting):
                force[i] = lam[b]
                a += Y[b] * lam[b]
        return a, force

    def energies(self, values: dict[str, float], t: float = 0.0) -> tuple[float, float]:
        """T and U, U with the energy the compliant overlaps store, k delta^(e + 1) / (e + 1)."""
        spec = self.spec
        args = [values[name] for name in self.parameter_names] + [values[c.name] for c in spec.coordinates] + \
               [values[c.velocity] for c in spec.coordinates] + [t]
        stored = 0.0
        for gap, law in zip(self._gaps, self._laws):
            overlap = -float(gap(*args))
            if law is not None and overlap > 0:
                stored += float(law[0](*args)) * overlap ** (law[1] + 1) / (law[1] + 1)
        return float(self._T(*args)), float(self._U(*args)) + stored
