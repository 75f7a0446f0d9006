"""The FMUs' integration methods (names, orders, kinds and descriptions, in the order of the `Solver`
enumeration: item values 1, 2, ...) and the counters the FMUs report. The generated model
descriptions take them from here."""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Method:
    name: str
    order: int
    fixed_step: bool
    description: str
    symmetric: bool = False  # time-reversible: bounded energy error over long runs
    implicit: bool = False   # solved per step by Newton's method with the exact Jacobian
    needs_constant_mass: bool = False  # only for objects whose mass matrix is constant
    adaptive: bool = False   # its step (and order) controlled by tol > 0 alone
    # built on the free equations' structure (their Taylor series, their split into a(q) - d v): on an object
    # with constraints, only while no rigid constraint acts
    free_motion_only: bool = False
    family: str = field(kw_only=True)  # one of FAMILIES: the charts draw each family in its own panels


# The methods' families, in the order the charts draw them: (key, what a chart calls it)
FAMILIES = (
    ("runge-kutta", "one-step Runge-Kutta"),
    ("adams-bashforth", "Adams-Bashforth (multistep)"),
    ("adams-bashforth-moulton", "Adams-Bashforth-Moulton (multistep)"),
    ("symmetric", "symmetric (implicit, Stormer-Verlet)"),
    ("series", "Taylor and extrapolation"),
)


TAYLOR_ORDERS = (2, 30)    # the range of taylor_order (the generated physics.h sizes its series for the last)
TAYLOR_DEFAULT_ORDER = 20  # its start value
# gbs's extrapolation table: column k from the modified midpoint rule with 2, 4, ..., 2k substeps, of order 2k;
# the order control aims at a column below the last, so that one more can decide a step
GBS_COLUMNS = 8
# gbs's least tol > 0: below it the columns agree to rounding before the error test can pass, and the step
# shrinks without gaining accuracy until the work bound (about ten rounding units, as Hairer and Wanner's ODEX)
GBS_SMALLEST_TOL = 1e-15

METHODS = (
    Method("euler", 1, True, "explicit Euler, order 1", family="runge-kutta"),
    Method("midpoint", 2, True, "improved polygon (explicit midpoint), order 2", family="runge-kutta"),
    Method("heun", 2, True, "Heun, order 2", family="runge-kutta"),
    Method("rk3", 3, True, "Runge-Kutta 3 (thesis 4.38, corrected)", family="runge-kutta"),
    Method("rk4", 4, True, "classic Runge-Kutta 4", family="runge-kutta"),
    Method("rkf45", 4, False, "Runge-Kutta-Fehlberg 4(5) with step-size control on tol", adaptive=True,
           family="runge-kutta"),
    Method("nystrom5", 5, True, "Kutta-Nystrom, order 5 (thesis 4.36, corrected)", family="runge-kutta"),
    Method("ab2", 2, True, "Adams-Bashforth 2-step", family="adams-bashforth"),
    Method("ab3", 3, True, "Adams-Bashforth 3-step", family="adams-bashforth"),
    Method("ab4", 4, True, "Adams-Bashforth 4-step", family="adams-bashforth"),
    Method("ab5", 5, True, "Adams-Bashforth 5-step", family="adams-bashforth"),
    Method("ab6", 6, True, "Adams-Bashforth 6-step (nystrom5 start)", family="adams-bashforth"),
    Method("implicit_midpoint", 2, True, "implicit midpoint rule, symmetric, order 2 (Newton per step)",
           symmetric=True, implicit=True, family="symmetric"),
    Method("gauss_legendre4", 4, True, "2-stage Gauss-Legendre, symmetric, order 4 (Newton per step)",
           symmetric=True, implicit=True, family="symmetric"),
    Method("stormer_verlet", 2, True, "Stormer-Verlet, symmetric, order 2 (objects with a constant mass matrix)",
           symmetric=True, needs_constant_mass=True, free_motion_only=True, family="symmetric"),
    # appended: the items before keep their values
    Method("abm2", 2, True, "Adams-Bashforth-Moulton 2, predictor-corrector (PECE: ab2, trapezoid)",
           family="adams-bashforth-moulton"),
    Method("abm3", 3, True, "Adams-Bashforth-Moulton 3, predictor-corrector (PECE)", family="adams-bashforth-moulton"),
    Method("abm4", 4, True, "Adams-Bashforth-Moulton 4, predictor-corrector (PECE)", family="adams-bashforth-moulton"),
    Method("abm5", 5, True, "Adams-Bashforth-Moulton 5, predictor-corrector (PECE, nystrom5 start)",
           family="adams-bashforth-moulton"),
    Method("abm6", 6, True, "Adams-Bashforth-Moulton 6, predictor-corrector (PECE, nystrom5 start)",
           family="adams-bashforth-moulton"),
    Method("trapezoid", 2, True, "implicit trapezoid rule (thesis 4.9), symmetric, A-stable, order 2 (Newton per step)",
           symmetric=True, implicit=True, family="symmetric"),
    Method("taylor", TAYLOR_DEFAULT_ORDER, False,
           f"Taylor method of order taylor_order ({TAYLOR_ORDERS[0]} to {TAYLOR_ORDERS[1]}), its coefficients by Taylor "
           "arithmetic on the generated equations; fixed step h with tol = 0, else the step from its last "
           "coefficients (after Jorba and Zou, the radius of convergence from the last four)", free_motion_only=True,
           family="series"),
    Method("gbs", 2 * GBS_COLUMNS, False,
           f"Gragg-Bulirsch-Stoer extrapolation: the modified midpoint rule with 2, 4, ..., 2 k substeps extrapolated "
           f"in h^2 (order 2 k, k = 2 ... gbs_columns <= {GBS_COLUMNS}); order and step chosen for tol, or column "
           f"gbs_columns with the fixed step h at tol = 0", adaptive=True, family="series"),
)
SOLVERS = tuple(m.name for m in METHODS)
FIXED_STEP = tuple(m.name for m in METHODS if m.fixed_step)
ADAPTIVE = tuple(m.name for m in METHODS if m.adaptive)  # rkf45 and gbs: their step (and order) from tol > 0
ORDER = {m.name: m.order for m in METHODS}
SYMMETRIC = tuple(m.name for m in METHODS if m.symmetric)
IMPLICIT = tuple(m.name for m in METHODS if m.implicit)
FREE_MOTION_ONLY = tuple(m.name for m in METHODS if m.free_motion_only)
METHOD = {m.name: m for m in METHODS}

# The methods that choose their own step unless tol = 0, and the settings that give their fixed step one order
# (for gbs an even one): the object proof, the stability atlas and the planner run them so.
VARIABLE_ORDER = ("taylor", "gbs")
# the Integer parameter that sets each one's order: taylor's order itself, gbs's columns (order 2 k)
ORDER_SETTING = {"taylor": "taylor_order", "gbs": "gbs_columns"}


def fixed_step_settings(method: str, order: int) -> dict:
    """The start values (but h) that run taylor or gbs with the fixed step at this order."""
    return {"solver": method, "tol": 0.0, ORDER_SETTING[method]: order if method == "taylor" else order // 2}

# What a plan (a method and its step, harness.studies.planner) may name: every fixed-step method, and taylor and
# gbs with their fixed step (tol = 0) at a few orders, named taylor<order> and gbs<order>.
PLAN_TAYLOR_ORDERS = (6, 10, 16)
PLAN_GBS_ORDERS = (6, 10)
_FIXED_SETTINGS = {f"{method}{order}": fixed_step_settings(method, order)
                   for method, orders in (("taylor", PLAN_TAYLOR_ORDERS), ("gbs", PLAN_GBS_ORDERS)) for order in orders}
PLANNABLE = (*FIXED_STEP, *_FIXED_SETTINGS)


def plan_solver(choice: str) -> str:
    """The solver a plan's method runs."""
    return _FIXED_SETTINGS[choice]["solver"] if choice in _FIXED_SETTINGS else choice


def plan_order(choice: str) -> int:
    """A plan's method's order of convergence."""
    if choice in _FIXED_SETTINGS:
        settings = _FIXED_SETTINGS[choice]
        return settings.get("taylor_order") or 2 * settings["gbs_columns"]
    return ORDER[choice]


def plan_settings(choice: str, h: float) -> dict:
    """The start values that run a plan's method at the internal step h."""
    return {**_FIXED_SETTINGS.get(choice, {"solver": choice}), "h": h}


# The counters every object with states reports (Integer outputs, in this order after n_rhs).
COUNTERS = (
    ("n_rhs", "right-hand-side evaluations since initialization (Model Exchange: each new state, time or input the "
              "importer evaluates)"),
    ("n_steps", "accepted internal steps (closed-form evaluations for the linear model)"),
    ("n_rejected", "steps rejected by the error test of rkf45 or gbs"),
    ("n_jacobians", "Jacobians of the right-hand side evaluated by the implicit methods (one per step, each from "
                    "one directional derivative per state)"),
    ("n_iterations", "Newton iterations of the implicit methods (each evaluates the right-hand side once per stage)"),
)
COUNTER_NAMES = tuple(name for name, _ in COUNTERS)
