"""Independent references: the exact simple pendulum, and the measured order of a sequence."""
from __future__ import annotations

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
