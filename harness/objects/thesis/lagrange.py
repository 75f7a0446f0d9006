"""An independent derivation of the pendulums' equations of motion: Euler-Lagrange from T and U,
with generalized forces Q_j = F . dr/dq_j and the damping -d qdot_j, done symbolically by SymPy from
the positions alone (no equation of the C code is reused)."""
from __future__ import annotations

from functools import lru_cache
from typing import Callable

import numpy as np
import sympy as sp

g, d, ax, ay, Fx, Fy, t = sp.symbols("g d anchor_x anchor_y F_x F_y t", real=True)


def unit(angle):
    """Direction from a pivot at the given angle from the downward vertical."""
    return sp.Matrix([sp.sin(angle), -sp.cos(angle)])


def lagrange_accelerations(q, qd, T, U, force_point, force):
    """Solve d/dt dL/dqd - dL/dq = Q for the accelerations, then apply the damping -d qd."""
    qdd = sp.symbols(f"qdd0:{len(q)}")
    L = T - U
    equations = []
    for j, (qj, qdj) in enumerate(zip(q, qd)):
        p = sp.diff(L, qdj)
        dp_dt = sum(sp.diff(p, qk) * qdk + sp.diff(p, qdk) * qddk for qk, qdk, qddk in zip(q, qd, qdd))
        Q = (force.T * force_point.diff(qj))[0]
        equations.append(sp.Eq(dp_dt - sp.diff(L, qj), Q))
    solution = sp.solve(equations, qdd, dict=True)[0]
    return [solution[a] - d * v for a, v in zip(qdd, qd)]


def speed_squared(r, q, qd):
    v = r.jacobian(sp.Matrix(q)) * sp.Matrix(qd)
    return (v.T * v)[0]


def simple_pendulum():
    L, m, phi, omega = sp.symbols("L m phi omega", real=True)
    r = sp.Matrix([ax, ay]) + L * unit(phi)
    T = m / 2 * speed_squared(r, [phi], [omega])
    U = m * g * (r[1] - ay)
    params = {"L": L, "m": m}
    return params, [phi], [omega], T, U, r, {"x": r[0], "y": r[1]}


def double_pendulum():
    m1, m2, J1, J2, s1, s2, l1, l2 = sp.symbols("m1 m2 J1 J2 s1 s2 l1 l2", real=True)
    phi1, phi2, w1, w2 = sp.symbols("phi1 phi2 omega1 omega2", real=True)
    anchor = sp.Matrix([ax, ay])
    r1 = anchor + s1 * unit(phi1)
    pivot2 = anchor + l1 * unit(phi1)
    r2 = pivot2 + s2 * unit(phi2)
    tip = pivot2 + l2 * unit(phi2)
    q, qd = [phi1, phi2], [w1, w2]
    T = (m1 / 2 * speed_squared(r1, q, qd) + J1 / 2 * w1 ** 2 + m2 / 2 * speed_squared(r2, q, qd)
         + J2 / 2 * w2 ** 2)
    U = m1 * g * (r1[1] - ay) + m2 * g * (r2[1] - ay)
    params = dict(m1=m1, m2=m2, J1=J1, J2=J2, s1=s1, s2=s2, l1=l1, l2=l2)
    return params, q, qd, T, U, tip, {"x1": pivot2[0], "y1": pivot2[1], "x2": tip[0], "y2": tip[1]}


def spring_pendulum():
    m, D, l0, phi, eps, omega, v = sp.symbols("m D l0 phi eps omega v_eps", real=True)
    r = sp.Matrix([ax, ay]) + (l0 + eps) * unit(phi)
    q, qd = [phi, eps], [omega, v]
    T = m / 2 * speed_squared(r, q, qd)
    U = D / 2 * eps ** 2 + m * g * (r[1] - ay)
    return dict(m=m, D=D, l0=l0), q, qd, T, U, r, {"x": r[0], "y": r[1]}


MODELS: dict[str, Callable] = {"SimplePendulum": simple_pendulum, "DoublePendulum": double_pendulum,
                               "SpringPendulum": spring_pendulum}




@lru_cache(maxsize=None)  # the derivation takes seconds; its result never changes
def derived_model(name: str):
    """(names of the arguments, f(*values) -> [accelerations..., T, U, positions...], positions' names)."""
    params, q, qd, T, U, force_point, positions = MODELS[name]()
    accelerations = lagrange_accelerations(q, qd, T, U, force_point, sp.Matrix([Fx, Fy]))
    symbols = [g, d, ax, ay, Fx, Fy] + list(params.values()) + list(q) + list(qd)
    names = ["g", "d", "anchor_x", "anchor_y", "F_x", "F_y"] + list(params) + [str(s) for s in q + qd]
    function = sp.lambdify(symbols, accelerations + [T, U] + list(positions.values()), "math")
    return names, function, list(positions), [str(s) for s in q], [str(s) for s in qd]


def random_point(name: str, rng: np.random.Generator) -> dict[str, float]:
    values = {"g": rng.uniform(0, 20), "d": rng.uniform(0, 2), "anchor_x": rng.uniform(-2, 2),
              "anchor_y": rng.uniform(-2, 2), "F_x": rng.uniform(-5, 5), "F_y": rng.uniform(-5, 5)}
    if name == "SimplePendulum":
        values.update(L=rng.uniform(0.2, 3), m=rng.uniform(0.1, 5), phi=rng.uniform(-3, 3), omega=rng.uniform(-5, 5))
    elif name == "DoublePendulum":
        values.update({k: rng.uniform(0.1, 3) for k in ("m1", "m2", "l1", "l2")})
        values.update({k: rng.uniform(0.0, 0.5) for k in ("J1", "J2")})
        values.update({k: rng.uniform(0.0, 2) for k in ("s1", "s2")})
        values.update({k: rng.uniform(-3, 3) for k in ("phi1", "phi2")})
        values.update({k: rng.uniform(-5, 5) for k in ("omega1", "omega2")})
    else:
        values.update(m=rng.uniform(0.1, 5), D=rng.uniform(1, 100), l0=rng.uniform(0.3, 2), phi=rng.uniform(-3, 3),
                      omega=rng.uniform(-5, 5), v_eps=rng.uniform(-3, 3))
        values["eps"] = rng.uniform(-0.9 * values["l0"], 2)
    return values
