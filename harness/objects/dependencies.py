"""What each output and state derivative of an object's FMU depends on, from its derivation: the one
source of the dependency lists of both FMI versions' model descriptions.

At a communication point and in Continuous-Time Mode the knowns are the continuous states, the inputs
and time; in Initialization Mode also the variables with initial = "exact": the states' start values
and the parameters. An unknown depends on a known where its derivative by the known is not zero, tested
by evaluation as derivation.vanishes does (a free symbol alone says too much: sin(psi)^2 + cos(psi)^2
has psi, and the inverse mass matrix can cancel a force's effect on a coordinate it does not reach
directly). The accelerations a = M^-1 (f + Q) are differentiated numerically through the
factorization, da = M^-1 (d(f + Q) - dM a), never by a symbolic inverse. On top of them come the
framework's damping -d v_j of each acceleration (its own velocity; d in Initialization Mode) and, for
an object with a linear model, the switch `model` (a parameter) of whichever of the accelerations and
the energies the linear model computes otherwise (its T and U are quadratic).
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from harness.fmi.methods import COUNTER_NAMES
from harness.objects.derivation import Derivation, sample_points, vanishes
from harness.objects.object_file import EVENT_COUNTER

ACCELERATION = "accelerations"


def dependencies(derivation: Derivation, initial: bool = False) -> dict[str, set[str]]:
    """For each output and state derivative: the names of the knowns it depends on ("time" for time),
    in Initialization Mode when `initial`."""
    spec = derivation.spec
    q, v = list(spec.q), list(spec.v)
    known = {symbol: str(symbol) for symbol in q + v + list(derivation.inputs)}
    known[spec.time] = "time"
    if initial:
        known.update({symbol: str(symbol) for symbol in spec.parameter_symbols()})
    switched = _switched(derivation) if initial else set()

    def of(expression) -> set[str]:
        expression = sp.sympify(expression)
        return {known[s] for s in expression.free_symbols if s in known and not vanishes(sp.diff(expression, s), spec)}

    def switch(what: str) -> set[str]:
        return {"model"} if what in switched else set()

    result: dict[str, set[str]] = {}
    for c, velocity in zip(spec.coordinates, v):
        result[f"der({c.name})"] = {str(velocity)}
    for c, velocity, needs in zip(spec.coordinates, v, _acceleration_needs(derivation, list(known))):
        result[f"der({c.velocity})"] = {known[s] for s in needs} | {str(velocity)} | \
            ({"d"} if initial else set()) | switch(ACCELERATION)
    for c, coordinate, velocity in zip(spec.coordinates, q, v):
        result[c.name] = {str(coordinate)}
        result[c.velocity] = {str(velocity)}
    for point, position, velocity in zip(spec.points, derivation.positions, derivation.velocities):
        for kind, name in point.outputs.items():
            axis = "xyz".index(kind[-1])
            result[name] = of(velocity[axis] if kind.startswith("v_") else position[axis])
    damping = spec.symbols["d"]
    for output in spec.outputs:  # what its expression holds, and what the accelerations in it need
        result[output.name] = of(output.value)
        for c, acceleration in zip(spec.coordinates, spec.accelerations):
            if acceleration in output.value.free_symbols:
                result[output.name] |= result[f"der({c.velocity})"] - {"d"}
        # the damping: in the accelerations (each gets -d v) and written out; a tension that adds d v back
        # to the acceleration does not depend on it
        undamped = output.value.xreplace({a: sp.Symbol(f"undamped {a}") - damping * velocity
                                          for a, velocity in zip(spec.accelerations, v)})
        if initial and sp.expand(sp.diff(undamped, damping)) != 0:
            result[output.name].add("d")
    result["E_kin"], result["E_pot"] = of(derivation.T) | switch("E_kin"), of(derivation.U) | switch("E_pot")
    result["E"] = result["E_kin"] | result["E_pot"]
    for counter in COUNTER_NAMES:
        result[counter] = set()
    if spec.constraints:
        # The constraint forces couple every acceleration to every state and input: not listed, which
        # reads as "depends on every known". A gap depends on what its expression holds; the compliant
        # laws' energies join E_pot.
        for c in spec.coordinates:
            del result[f"der({c.velocity})"]
        # A constraint's force holds the bodies wherever the states, the inputs and (for an object that moves with
        # time) time take them: it depends on every one of those knowns, listed (in Initialization Mode: not listed)
        every = {known[s] for s in q + v + list(derivation.inputs)}
        if any(spec.time in sp.sympify(e).free_symbols for e in (derivation.M, derivation.f, derivation.Q, derivation.U,
                                                                  *(terms.gap for terms in derivation.constraints))):
            every.add("time")
        for constraint, terms in zip(spec.constraints, derivation.constraints):
            result[f"{constraint.name}_gap"] = of(terms.gap)
            if not initial:
                result[f"{constraint.name}_force"] = set(every)
            if constraint.compliant:  # the energy k delta^(exponent + 1) / (exponent + 1) the overlap stores
                result["E_pot"] |= of(terms.gap) | of(constraint.stiffness)
        result["E"] = result["E_kin"] | result["E_pot"]
        result[EVENT_COUNTER] = set()
    return result


def _acceleration_needs(derivation: Derivation, knowns: list[sp.Symbol]) -> list[set[sp.Symbol]]:
    """For each acceleration, the knowns its value moves with (damping aside), from the derivatives of
    M a = f + Q at the sample points; every candidate where no point can be evaluated."""
    M, right = derivation.M, derivation.f + derivation.Q
    present = M.free_symbols | right.free_symbols
    candidates = [k for k in knowns if k in present]
    symbols = sorted(present, key=str)
    evaluate = sp.lambdify(symbols, [M, right, *[M.diff(k) for k in candidates], *[right.diff(k) for k in candidates]],
                           "numpy")
    n, found, evaluated = derivation.n, [set() for _ in range(derivation.n)], False
    for values in sample_points(derivation.spec, symbols):
        try:
            with np.errstate(all="raise"):
                matrices = [np.array(m, dtype=float).reshape(n, -1) for m in evaluate(*values)]
                mass, force = matrices[0], matrices[1][:, 0]
                acceleration = np.linalg.solve(mass, force)
                for k, known in enumerate(candidates):
                    change = matrices[2 + len(candidates) + k][:, 0] - matrices[2 + k] @ acceleration
                    column = np.linalg.solve(mass, change)
                    scale = max(1.0, float(np.abs(column).max()), float(np.abs(change).max()))
                    for i in np.flatnonzero(np.abs(column) > 1e-9 * scale):
                        found[i].add(known)
        except (ValueError, TypeError, ZeroDivisionError, FloatingPointError, np.linalg.LinAlgError):
            continue
        evaluated = True
    return found if evaluated else [set(candidates) for _ in range(n)]


def _switched(derivation: Derivation) -> set[str]:
    """Which of the accelerations, "E_kin" and "E_pot" the linear model (M0 a = -K0 (q - rest) + B0 F,
    T = v M0 v / 2, U = U0 + (q - rest) K0 (q - rest) / 2) computes otherwise than the full equations."""
    linear, spec = derivation.linear, derivation.spec
    if linear is None:
        return set()
    v, dq = sp.Matrix(spec.v), sp.Matrix(spec.q) - sp.Matrix(linear.rest)
    right = -linear.K0 * dq + (linear.B0 * sp.Matrix(derivation.inputs) if derivation.inputs else sp.zeros(len(dq), 1))
    same = {
        ACCELERATION: all(vanishes(e, spec)
                          for e in [*(derivation.M - linear.M0), *(derivation.f + derivation.Q - right)]),
        "E_kin": vanishes(derivation.T - (v.T * linear.M0 * v)[0] / 2, spec),
        "E_pot": vanishes(derivation.U - linear.U0 - (dq.T * linear.K0 * dq)[0] / 2, spec),
    }
    return {what for what, equal in same.items() if not equal}
