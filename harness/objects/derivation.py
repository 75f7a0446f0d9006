"""Lagrange's equations of the second kind for an object file, by SymPy.

With p = dT/dv the momenta, d/dt p - dL/dq = Q and T quadratic in the velocities v:

    M(q, t) a = f(q, v, t) + Q(q, t, F),   M = d2T/dv2,
    f = dL/dq - (dp/dq) v - dp/dt,         Q_j = sum over forces F . dr/dq_j,

then the framework's damping a_j -= d v_j. The mass matrix is left to a factorization in the
generated C, so no symbolic inverse is ever formed. Sines and cosines of sums are expanded first, so
that only sines and cosines of single terms remain (a compiler pairs each into one sincos call).
Multiples such as cos(1000*x) stay whole: their expansion is a polynomial of that degree, slow to
derive and, by cancellation, inaccurate to evaluate.
"""
from __future__ import annotations

import signal
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from harness.objects.object_file import FRAMEWORK_PARAMETERS, ObjectFileError, ObjectSpec


@dataclass
class LinearModel:
    """The quadratic approximation of T and U about the rest state: M0 a + K0 (q - rest) = B0 F."""
    rest: list[sp.Expr]    # parameters only
    M0: sp.Matrix          # n x n, parameters only
    K0: sp.Matrix          # n x n, parameters only
    B0: sp.Matrix          # n x (force inputs), generalized force per input at rest
    U0: sp.Expr            # U at rest


@dataclass
class ConstraintTerms:
    """Lagrange's equations of the first kind for one constraint g(q, t): its force lambda acts along
    G = dg/dq, and along a motion g' = G v + dg/dt, g'' = G a + gamma."""
    gap: sp.Expr
    G: list[sp.Expr]                   # n
    rate: sp.Expr                      # g'
    gamma: sp.Expr                     # g'' - G a: the velocities' and time's part


@dataclass
class Derivation:
    spec: ObjectSpec
    M: sp.Matrix                       # n x n
    f: sp.Matrix                       # n, without forces and damping
    Q: sp.Matrix                       # n, generalized forces, linear in the force inputs
    inputs: list[sp.Symbol]            # force inputs, in variable order
    positions: list[list[sp.Expr]]     # per point
    velocities: list[list[sp.Expr]]    # per point
    T: sp.Expr
    U: sp.Expr
    linear: LinearModel | None
    linear_reason: str                 # why there is no linear model (empty when there is one)
    constraints: list[ConstraintTerms] = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.spec.coordinates)

    @property
    def split_reason(self) -> str:
        """Why the accelerations are not of the form a(q, t, F) - d v that Stormer-Verlet needs (a mass
        matrix that is constant, no velocity in f); empty when they are."""
        spec = self.spec
        reason = constraints_beyond_free_motion(spec)
        if reason:
            return f"{reason}, which depend on its velocities"
        moving = sorted(str(s) for s in self.M.free_symbols & (set(spec.q) | set(spec.v) | {spec.time}))
        if moving:
            return f"the mass matrix of {spec.identifier} depends on {', '.join(moving)}"
        velocities = sorted(str(s) for s in self.f.free_symbols & set(spec.v))
        if velocities:
            return f"the accelerations of {spec.identifier} depend on {', '.join(velocities)}"
        return ""


def constraints_beyond_free_motion(spec) -> str:
    """Why the object's motion is never free of constraint forces (a bilateral constraint always acts, a
    compliant one wherever it overlaps); empty when it has only rigid unilateral constraints, or none, so that
    its free equations hold between contacts (taylor and stormer_verlet integrate them there)."""
    always = [c.name for c in spec.constraints if c.bilateral or c.compliant]
    if not always:
        return ""
    return (f"{spec.identifier}'s constraint{'s' if len(always) > 1 else ''} {', '.join(always)} "
            f"act{'' if len(always) > 1 else 's'} with forces")


def _expand(expr: sp.Expr) -> sp.Expr:
    return expr.replace(lambda e: isinstance(e, (sp.sin, sp.cos)) and e.args[0].is_Add, _angle_sum)


def _angle_sum(function: sp.Expr) -> sp.Expr:
    head, *tail = sp.Add.make_args(function.args[0])
    rest = sp.Add(*tail)
    sin_a, cos_a = sp.sin(head), sp.cos(head)
    sin_b, cos_b = _expand(sp.sin(rest)), _expand(sp.cos(rest))
    if isinstance(function, sp.sin):
        return sin_a * cos_b + cos_a * sin_b
    return cos_a * cos_b - sin_a * sin_b


def total_derivative(expr: sp.Expr, q, v, a, t) -> sp.Expr:
    """d/dt of expr(q, v, t) along a motion with accelerations a."""
    result = sp.diff(expr, t)
    for qj, vj, aj in zip(q, v, a):
        result += sp.diff(expr, qj) * vj + sp.diff(expr, vj) * aj
    return result


def derive(spec: ObjectSpec) -> Derivation:
    q, v, t = spec.q, spec.v, spec.time
    T, U = _expand(spec.T), _expand(spec.U)
    M = sp.hessian(T, v)
    velocity_set = set(v)
    if any(entry.free_symbols & velocity_set for entry in M):
        raise ObjectFileError(f"{spec.path}: energy.T: T is not quadratic in the velocities "
                              f"(its second derivatives in {', '.join(map(str, v))} still depend on them)")
    _check_positive(spec, M)
    _check_real(spec, T, U)
    L = T - U
    p = [sp.diff(T, vj) for vj in v]
    f = []
    for j, qj in enumerate(q):
        dp = sp.diff(p[j], t) + sum(sp.diff(p[j], qk) * vk for qk, vk in zip(q, v))
        f.append(sp.diff(L, qj) - dp)
    inputs: list[sp.Symbol] = []
    Q = [sp.Integer(0)] * len(q)
    point_by_name = {pt.name: pt for pt in spec.points}
    for force in spec.forces:
        position = [_expand(x) for x in point_by_name[force.point].position]
        for axis, name in force.inputs.items():
            F = spec.symbols[name]
            inputs.append(F)
            coordinate = position["xyz".index(axis)]
            for j, qj in enumerate(q):
                Q[j] += F * sp.diff(coordinate, qj)
    positions = [[_expand(x) for x in pt.position] for pt in spec.points]
    velocities = [[sp.diff(x, t) + sum(sp.diff(x, qj) * vj for qj, vj in zip(q, v)) for x in pos]
                  for pos in positions]
    linear, reason = _linearize(spec, M, T, U, Q, inputs)
    constraints = [_constraint_terms(spec, c.gap) for c in spec.constraints]
    _check_start_admissible(spec, constraints)
    return Derivation(spec, M, sp.Matrix(f), sp.Matrix(Q), inputs, positions, velocities, T, U, linear, reason,
                      constraints)


def _constraint_terms(spec: ObjectSpec, gap: sp.Expr) -> ConstraintTerms:
    q, v, t = spec.q, spec.v, spec.time
    gap = _expand(gap)
    G = [sp.diff(gap, qj) for qj in q]
    rate = total_derivative(gap, q, v, [0] * len(q), t)
    gamma = total_derivative(rate, q, v, [0] * len(q), t)  # with a = 0 only the velocities' part remains
    return ConstraintTerms(gap, G, rate, gamma)


# A rigid constraint's start must hold to this (SI units): a gap below -START_GAP_TOLERANCE is an overlap.
START_GAP_TOLERANCE = 1e-12


def _check_start_admissible(spec: ObjectSpec, terms: list[ConstraintTerms]) -> None:
    """Every rigid constraint holds at the start values (the FMU checks it again for the values it is given)."""
    values = _start_values(spec)
    for constraint, term in zip(spec.constraints, terms):
        if constraint.compliant:
            continue
        where = f"{spec.path}: constraints.{constraint.name}"
        try:
            gap, rate = (float(e.subs(values).evalf()) for e in (term.gap, term.rate))
        except (TypeError, ValueError):
            raise ObjectFileError(f"{where}: the gap is not a finite real number at the start values") from None
        if not (np.isfinite(gap) and np.isfinite(rate)):
            raise ObjectFileError(f"{where}: the gap is not finite at the start values")
        if constraint.bilateral and (abs(gap) > START_GAP_TOLERANCE or abs(rate) > START_GAP_TOLERANCE):
            raise ObjectFileError(f"{where}: the start values violate it (gap = {gap:.6g}, its rate = {rate:.6g}; "
                                  f"a bilateral constraint needs both within {START_GAP_TOLERANCE:g})")
        if gap < -START_GAP_TOLERANCE:
            raise ObjectFileError(f"{where}: the start values violate it (gap = {gap:.6g}, allowed >= "
                                  f"{-START_GAP_TOLERANCE:g})")


# SymPy's simplify has no bound on its work: a 32-operation expression with a tenth power of a sum
# takes half a minute, and its size does not tell. So simplification for display runs on a clock,
# and zero tests are done by evaluation.
SIMPLIFY_SECONDS = 60.0  # for one documentation page; the project's objects need under 15
GENERATION_SECONDS = 300.0  # deriving and generating one object, that page included; the project's need under 20
ZERO_TEST_POINTS = 4


class _OutOfTime(Exception):
    pass


@contextmanager
def _clock(seconds: float):
    """Raises _OutOfTime in the block after `seconds`, or when an enclosing clock runs out first, which
    then goes on with what it has left. Yields False, and measures nothing, outside the main thread (a
    timer signal is the only way to interrupt SymPy, which bounds none of its work)."""
    if threading.current_thread() is not threading.main_thread():
        yield False
        return

    def out_of_time(signum, frame):
        # again soon, should this one land where Python swallows exceptions (a gc callback, a __del__)
        signal.setitimer(signal.ITIMER_REAL, 0.05)
        raise _OutOfTime
    outer = signal.getitimer(signal.ITIMER_REAL)[0]
    started = time.monotonic()
    previous = signal.signal(signal.SIGALRM, out_of_time)
    signal.setitimer(signal.ITIMER_REAL, min(seconds, outer) if outer > 0 else seconds)
    try:
        yield True
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        if outer > 0:
            signal.setitimer(signal.ITIMER_REAL, max(1e-3, outer - (time.monotonic() - started)))


def readable(expressions: list, seconds: float = SIMPLIFY_SECONDS) -> list[sp.Expr]:
    """The expressions simplified, in order, while `seconds` last (or an enclosing time_limit); the rest
    as they are (all of them outside the main thread)."""
    expressions = [sp.sympify(e) for e in expressions]
    result = []
    with _clock(seconds) as measured:
        try:
            for expr in expressions if measured else ():
                result.append(sp.simplify(expr))
        except _OutOfTime:
            pass
    return result + expressions[len(result):]


@contextmanager
def time_limit(seconds: float, message: str):
    """Raises ObjectFileError(message) when the block takes longer than `seconds` (main thread only)."""
    with _clock(seconds):
        try:
            yield
        except _OutOfTime:
            raise ObjectFileError(message) from None


def vanishes(expr, spec: ObjectSpec) -> bool:
    """expr is zero for all values of its symbols, tested by evaluation at the sample points: an
    analytic expression that is not identically zero vanishes at such points with probability zero.
    Where it cannot be evaluated: False."""
    expr = sp.sympify(expr)
    if expr == 0:
        return True
    symbols = sorted(expr.free_symbols, key=str)
    evaluate = sp.lambdify(symbols, [expr, *sp.Add.make_args(expr)], "math")
    for values in sample_points(spec, symbols):
        try:
            value, *terms = (complex(x) for x in evaluate(*values))
        except (ValueError, ZeroDivisionError, OverflowError, TypeError):
            return False
        if not abs(value) <= 1e-9 * max(1.0, sum(abs(x) for x in terms)):
            return False
    return True


def sample_points(spec: ObjectSpec, symbols: list[sp.Symbol]) -> list[np.ndarray]:
    """Values of `symbols` for zero tests by evaluation: the start values (0.5 for a symbol without one,
    an input say), then random points about them."""
    start = _start_values(spec)
    center = np.array([float(start.get(symbol, 0.5)) for symbol in symbols])
    generator = np.random.default_rng(20261123)
    points = [center]
    for _ in range(ZERO_TEST_POINTS - 1):
        points.append(center * (1 + 0.3 * generator.uniform(-1, 1, center.size))
                      + 0.1 * generator.uniform(-1, 1, center.size))
    return points


def _start_values(spec: ObjectSpec) -> dict[sp.Symbol, float]:
    values = {spec.symbols[p.name]: p.start for p in spec.parameters if p.name not in FRAMEWORK_PARAMETERS}
    values.update({spec.symbols[c.name]: c.start for c in spec.coordinates})
    values.update({spec.symbols[c.velocity]: c.velocity_start for c in spec.coordinates})
    values[spec.time] = 0.0
    return values


def _numeric(matrix: sp.Matrix, values: dict) -> np.ndarray:
    return np.array(matrix.subs(values).evalf(), dtype=float)


def _check_real(spec: ObjectSpec, T: sp.Expr, U: sp.Expr) -> None:
    """T and U are finite real numbers at the start values (sqrt(-1 - phi**2) is not, anywhere)."""
    values = _start_values(spec)
    for key, energy in (("energy.T", T), ("energy.U", U)):
        try:
            number = complex(energy.subs(values).evalf())
        except (TypeError, ValueError):
            number = complex("nan")
        if not (np.isfinite(number.real) and abs(number.imag) <= 1e-12 * max(1.0, abs(number.real))):
            raise ObjectFileError(f"{spec.path}: {key}: not a finite real number at the start values")


def _check_positive(spec: ObjectSpec, M: sp.Matrix) -> None:
    """T must be positive in the velocities: M positive definite at the start values."""
    try:
        numeric = _numeric(M, _start_values(spec))
    except (TypeError, ValueError):
        raise ObjectFileError(f"{spec.path}: energy.T: the mass matrix d2T/dv2 is not a finite real matrix at the "
                              f"start values") from None
    if not np.all(np.isfinite(numeric)):
        raise ObjectFileError(f"{spec.path}: energy.T: the mass matrix d2T/dv2 is not finite at the start values")
    eigenvalues = np.linalg.eigvalsh(0.5 * (numeric + numeric.T))
    if eigenvalues.min() <= 1e-12 * max(1.0, abs(eigenvalues).max()):
        raise ObjectFileError(f"{spec.path}: energy.T: T is not positive in the velocities at the start values (the "
                              f"mass matrix d2T/dv2 has eigenvalue {eigenvalues.min():.3g})")


def _linearize(spec: ObjectSpec, M: sp.Matrix, T: sp.Expr, U: sp.Expr, Q: list[sp.Expr],
               inputs: list[sp.Symbol]) -> tuple[LinearModel | None, str]:
    q, v = spec.q, spec.v
    if spec.constraints:
        return None, "the object has constraints (its motion switches at contacts)"
    if spec.rheonomic:
        return None, "the object is driven (t appears in its energies or points)"
    at_rest = {qj: spec.rest[c.name] for qj, c in zip(q, spec.coordinates)}
    zero_v = {vj: 0 for vj in v}
    if not all(vanishes(sp.diff(U, qj).subs(at_rest), spec) for qj in q):
        return None, "the rest state is not an equilibrium (dU/dq is not zero there)"
    if not all(vanishes(sp.diff(T, vj).subs(zero_v), spec) for vj in v):
        return None, "T has terms linear in the velocities"
    M0 = M.subs(at_rest)
    K0 = sp.hessian(U, q).subs(at_rest)
    values = _start_values(spec)
    try:
        inertia, stiffness = (np.linalg.eigvalsh(_numeric(M0, values)), np.linalg.eigvalsh(_numeric(K0, values)))
    except (TypeError, ValueError, np.linalg.LinAlgError):  # Abs(q) at q = 0, say: no second derivative there
        return None, "T or U has no finite real second derivatives at the rest state"
    if not (np.all(np.isfinite(inertia)) and np.all(np.isfinite(stiffness))):
        return None, "T or U has no finite second derivatives at the rest state"
    if inertia.min() <= 1e-12 * max(1.0, abs(inertia).max()):
        return None, "the mass matrix is singular at the rest state (a coordinate singularity)"
    if stiffness.min() < -1e-12 * max(1.0, abs(stiffness).max()):
        return None, f"the rest state is unstable (a stiffness eigenvalue is {stiffness.min():.3g})"
    B0 = sp.Matrix(len(q), len(inputs), lambda j, k: sp.diff(Q[j], inputs[k]).subs(at_rest))
    U0 = U.subs(at_rest)
    return LinearModel([spec.rest[c.name] for c in spec.coordinates], sp.Matrix(M0), sp.Matrix(K0), B0, U0), ""
