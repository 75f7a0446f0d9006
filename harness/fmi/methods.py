"""The FMUs' integration methods (names, orders, kinds and descriptions, in the order of the `Solver`
enumeration: item values 1, 2, ...) and the counters the FMUs report. The generated model
descriptions take them from here."""
from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Engine:
    """How the C core (fmus/framework/integrators.c) takes a method's steps. The framework's dispatch (the
    switches over the methods and the adaptive test) is generated from these: a method of an engine with a
    `table` needs only its entry below and its coefficients in integrators.c."""
    what: str
    # the C name of a method's coefficients ({NAME}: the method's name in capitals): a ButcherTableau or an
    # AdamsBashforth in integrators.c; None for an engine of its own
    table: str | None
    # "h": fixed steps of at most h; "tol": its own steps for tol (> 0); "tol or h": its own steps for tol > 0,
    # fixed steps of h at tol = 0
    step_control: str


ENGINES = {
    "explicit": Engine("an explicit Runge-Kutta tableau", "TABLEAU_{NAME}", "h"),
    "embedded": Engine("a Runge-Kutta tableau with an embedded error estimate", "TABLEAU_{NAME}", "tol"),
    "implicit": Engine("an implicit Runge-Kutta tableau, solved per step by Newton's method with the exact Jacobian",
                       "TABLEAU_{NAME}", "h"),
    "adams": Engine("Adams-Bashforth coefficients (with Adams-Moulton's corrector where given) and a Runge-Kutta "
                    "starter", "{NAME}", "h"),
    "stormer_verlet": Engine("Stormer-Verlet on the split a(q) - d v", None, "h"),
    "taylor": Engine("Taylor series by Taylor arithmetic on the generated equations", None, "tol or h"),
    "gbs": Engine("Gragg-Bulirsch-Stoer extrapolation of the modified midpoint rule", None, "tol or h"),
}


@dataclass(frozen=True)
class Method:
    name: str
    order: int
    description: str
    symmetric: bool = False  # time-reversible: bounded energy error over long runs
    needs_constant_mass: bool = False  # only for objects whose mass matrix is constant
    # the studies sweep its tol: its step (and, for gbs, its order) from tol > 0 alone (taylor's order is its own
    # setting, so the studies run it by order)
    adaptive: bool = False
    # built on the free equations' structure (their Taylor series, their split into a(q) - d v): on an object
    # with constraints, only while no rigid constraint acts
    free_motion_only: bool = False
    family: str = field(kw_only=True)  # one of FAMILIES: the charts draw each family in its own panels
    engine: str = field(kw_only=True)  # one of ENGINES

    @property
    def fixed_step(self) -> bool:
        """Fixed steps of h whatever tol is."""
        return ENGINES[self.engine].step_control == "h"

    @property
    def implicit(self) -> bool:
        """Solved per step by Newton's method with the exact Jacobian."""
        return self.engine == "implicit"

    @property
    def c_table(self) -> str | None:
        """The C name of its coefficients in integrators.c, for an engine with tables."""
        table = ENGINES[self.engine].table
        return table.format(NAME=self.name.upper()) if table else None


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
    Method("euler", 1, "explicit Euler, order 1", family="runge-kutta", engine="explicit"),
    Method("midpoint", 2, "improved polygon (explicit midpoint), order 2", family="runge-kutta", engine="explicit"),
    Method("heun", 2, "Heun, order 2", family="runge-kutta", engine="explicit"),
    Method("rk3", 3, "Runge-Kutta 3 (thesis 4.38, corrected)", family="runge-kutta", engine="explicit"),
    Method("rk4", 4, "classic Runge-Kutta 4", family="runge-kutta", engine="explicit"),
    Method("rkf45", 4, "Runge-Kutta-Fehlberg 4(5) with step-size control on tol", adaptive=True,
           family="runge-kutta", engine="embedded"),
    Method("nystrom5", 5, "Kutta-Nystrom, order 5 (thesis 4.36, corrected)", family="runge-kutta", engine="explicit"),
    Method("ab2", 2, "Adams-Bashforth 2-step", family="adams-bashforth", engine="adams"),
    Method("ab3", 3, "Adams-Bashforth 3-step", family="adams-bashforth", engine="adams"),
    Method("ab4", 4, "Adams-Bashforth 4-step", family="adams-bashforth", engine="adams"),
    Method("ab5", 5, "Adams-Bashforth 5-step", family="adams-bashforth", engine="adams"),
    Method("ab6", 6, "Adams-Bashforth 6-step (nystrom5 start)", family="adams-bashforth", engine="adams"),
    Method("implicit_midpoint", 2, "implicit midpoint rule, symmetric, order 2 (Newton per step)",
           symmetric=True, family="symmetric", engine="implicit"),
    Method("gauss_legendre4", 4, "2-stage Gauss-Legendre, symmetric, order 4 (Newton per step)",
           symmetric=True, family="symmetric", engine="implicit"),
    Method("stormer_verlet", 2, "Stormer-Verlet, symmetric, order 2 (objects with a constant mass matrix)",
           symmetric=True, needs_constant_mass=True, free_motion_only=True, family="symmetric",
           engine="stormer_verlet"),
    # appended: the items before keep their values
    Method("abm2", 2, "Adams-Bashforth-Moulton 2, predictor-corrector (PECE: ab2, trapezoid)",
           family="adams-bashforth-moulton", engine="adams"),
    Method("abm3", 3, "Adams-Bashforth-Moulton 3, predictor-corrector (PECE)", family="adams-bashforth-moulton",
           engine="adams"),
    Method("abm4", 4, "Adams-Bashforth-Moulton 4, predictor-corrector (PECE)", family="adams-bashforth-moulton",
           engine="adams"),
    Method("abm5", 5, "Adams-Bashforth-Moulton 5, predictor-corrector (PECE, nystrom5 start)",
           family="adams-bashforth-moulton", engine="adams"),
    Method("abm6", 6, "Adams-Bashforth-Moulton 6, predictor-corrector (PECE, nystrom5 start)",
           family="adams-bashforth-moulton", engine="adams"),
    Method("trapezoid", 2, "implicit trapezoid rule (thesis 4.9), symmetric, A-stable, order 2 (Newton per step)",
           symmetric=True, family="symmetric", engine="implicit"),
    Method("taylor", TAYLOR_DEFAULT_ORDER,
           f"Taylor method of order taylor_order ({TAYLOR_ORDERS[0]} to {TAYLOR_ORDERS[1]}), its coefficients by "
           "Taylor arithmetic on the generated equations; fixed step h with tol = 0, else the step from its last "
           "coefficients (after Jorba and Zou, the radius of convergence from the last four)", free_motion_only=True,
           family="series", engine="taylor"),
    Method("gbs", 2 * GBS_COLUMNS,
           f"Gragg-Bulirsch-Stoer extrapolation: the modified midpoint rule with 2, 4, ..., 2 k substeps extrapolated "
           f"in h^2 (order 2 k, k = 2 ... gbs_columns <= {GBS_COLUMNS}); order and step chosen for tol, or column "
           f"gbs_columns with the fixed step h at tol = 0", adaptive=True, family="series", engine="gbs"),
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
