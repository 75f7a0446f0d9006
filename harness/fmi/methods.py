"""The FMUs' integration methods: names, orders and descriptions, in the order of the `Solver`
enumeration (item values 1, 2, ...). The generated model descriptions take them from here."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Method:
    name: str
    order: int
    fixed_step: bool
    description: str


METHODS = (
    Method("euler", 1, True, "explicit Euler, order 1"),
    Method("midpoint", 2, True, "improved polygon (explicit midpoint), order 2"),
    Method("heun", 2, True, "Heun, order 2"),
    Method("rk3", 3, True, "Runge-Kutta 3 (thesis 4.38, corrected)"),
    Method("rk4", 4, True, "classic Runge-Kutta 4"),
    Method("rkf45", 4, False, "Runge-Kutta-Fehlberg 4(5) with step-size control on tol"),
    Method("nystrom5", 5, True, "Kutta-Nystrom, order 5 (thesis 4.36, corrected)"),
    Method("ab2", 2, True, "Adams-Bashforth 2-step"),
    Method("ab3", 3, True, "Adams-Bashforth 3-step"),
    Method("ab4", 4, True, "Adams-Bashforth 4-step"),
    Method("ab5", 5, True, "Adams-Bashforth 5-step"),
    Method("ab6", 6, True, "Adams-Bashforth 6-step (nystrom5 start)"),
)
SOLVERS = tuple(m.name for m in METHODS)
FIXED_STEP = tuple(m.name for m in METHODS if m.fixed_step)
ORDER = {m.name: m.order for m in METHODS}
