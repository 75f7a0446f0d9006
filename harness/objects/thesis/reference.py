"""Independent references: the exact simple pendulum, a tight long-double reference for the other
pendulums, and the measured order of a sequence."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ellipj, ellipk


def exact_simple_pendulum(phi0: float, t, g: float = 9.81, L: float = 1.0):
    """Release from rest at phi0 > 0, no damping or force:
    phi(t) = 2 asin(k sn(K(m) - w0 t | m)), omega(t) = -2 k w0 cn(K(m) - w0 t | m), k = sin(phi0/2), m = k^2."""
    k = np.sin(phi0 / 2.0)
    m = k * k
    w0 = np.sqrt(g / L)
    sn, cn, _, _ = ellipj(ellipk(m) - w0 * np.asarray(t, dtype=float), m)
    return 2.0 * np.arcsin(k * sn), -2.0 * k * w0 * cn


def slope(hs, errors) -> float:
    """Least-squares slope of log(error) against log(h): the measured order."""
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


# Butcher's sixth-stage fifth-order method (1964): c = (0, 1/4, 1/4, 1/2, 3/4, 1). A method the FMUs
# do not have, run in long double, so that the reference shares neither code nor tableau nor
# rounding with what it checks.
_BUTCHER5_A_EXACT = (((1, 4),), ((1, 8), (1, 8)), ((0, 1), (-1, 2), (1, 1)), ((3, 16), (0, 1), (0, 1), (9, 16)),
                     ((-3, 7), (2, 7), (12, 7), (-12, 7), (8, 7)))
_BUTCHER5_B_EXACT = ((7, 90), (0, 1), (32, 90), (12, 90), (32, 90), (7, 90))


@dataclass
class Reference:
    """States at the output times and the estimated largest error of the outer mass's position."""
    states: np.ndarray
    positions: np.ndarray
    estimated_error: float


def _fraction(pair) -> np.longdouble:
    return np.longdouble(pair[0]) / np.longdouble(pair[1])


def _integrate_long_double(rhs, start, steps_per_output: int, outputs: int, dt: np.longdouble) -> np.ndarray:
    a = [[_fraction(x) for x in row] for row in _BUTCHER5_A_EXACT]
    b = [_fraction(x) for x in _BUTCHER5_B_EXACT]
    h = dt / steps_per_output
    y = np.array(start, dtype=np.longdouble)
    out = np.empty((outputs + 1, len(y)), dtype=np.longdouble)
    out[0] = y
    for i in range(outputs):
        for _ in range(steps_per_output):
            k = [np.array(rhs(0, y), dtype=np.longdouble)]
            for row in a:
                k.append(np.array(rhs(0, y + h * sum(c * kj for c, kj in zip(row, k))), dtype=np.longdouble))
            y = y + h * sum(c * kj for c, kj in zip(b, k))
        out[i + 1] = y
    return out


def tight_reference(pendulum, stop: float, dt: float, steps_per_output: int = 40, exact: bool = True) -> Reference:
    """The pendulum's states at 0, dt, ..., stop. Undamped SimplePendulum from rest: the exact elliptic
    solution. Otherwise Butcher's fifth-order method in long double with dt/steps_per_output and
    again with half that step; the difference bounds the error of the finer run (it is 31/32 of the
    coarse run's error for a fifth-order method). exact=False takes the numerical path always (to
    check it against the exact solution)."""
    outputs = int(round(stop / dt))
    times = np.arange(outputs + 1) * dt
    p = pendulum.parameters
    if exact and pendulum.name == "SimplePendulum" and p["d"] == 0 and pendulum.start[1] == 0 and pendulum.start[0] > 0:
        phi, omega = exact_simple_pendulum(pendulum.start[0], times, p["g"], p["L"])
        states = np.column_stack([phi, omega])
        return Reference(states, pendulum.outer_mass(states), 1e-15)
    precise = pendulum.convert(np.longdouble)
    coarse = _integrate_long_double(precise.rhs, precise.start, steps_per_output, outputs, np.longdouble(dt))
    fine = _integrate_long_double(precise.rhs, precise.start, 2 * steps_per_output, outputs, np.longdouble(dt))
    difference = np.hypot(*(precise.outer_mass(fine) - precise.outer_mass(coarse)).T)
    states = fine.astype(float)
    return Reference(states, pendulum.outer_mass(states), float(np.max(difference)))
