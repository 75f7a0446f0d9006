"""The stability atlas: where each fixed-step method stops working, measured on the FMUs and
predicted from the method's amplification.

A setting is stable when, after the window (100 periods of the case's reference frequency omega),
the energy above the rest position is at most 1.5 times its start and the run returned fmi2OK
(no fmi2Discard). The run is one fmi2DoStep over the whole window with h = window / n, so the
scanned values h*omega = 2*pi*100/n are exact. `measured_limit` is the largest stable h*omega below
the first unstable one: a coarse scan upward from a quarter of the predicted limit, then bisection
on n. `theory_limit` is the same criterion applied to the linear test equation y' = lambda y over
the same window: growth^(2N) <= 1.5 with N = window / h steps, where growth is max |R(h lambda)|
for Runge-Kutta methods and the spectral radius of the recursion for Adams-Bashforth methods, over
the eigenvalues lambda of the linearized case.

Cases (`release` is the start amplitude, rad or m):
  * SimplePendulum from rest at 0.01 rad, damping d = zeta * 2 * omega0 for a set of damping ratios
    (0: the imaginary axis; d = 20 omega0: the real axis; between: rays into the left half-plane);
  * SimplePendulum from rest at 3 rad, undamped: nonlinear, no linear prediction;
  * every other object with a linear model (harness.objects.modes: normal modes from its energies)
    released at rest in its fastest mode (largest coordinate 0.01), omega = that mode's frequency;
    objects without one (driven, or singular at rest) have no case.
"""
from __future__ import annotations

import json
import math
import subprocess
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from harness.errors import HarnessError
from harness.fmi.methods import (FIXED_STEP, PLANNABLE, TAYLOR_DEFAULT_ORDER, VARIABLE_ORDER, fixed_step_settings,
                                 plan_order, plan_solver)
from harness.objects.derivation import derive
from harness.objects.modes import normal_modes
from harness.objects.object_file import ObjectSpec, read_object_file
from harness.objects.proof import object_file_in
from harness.objects.registry import object_file, object_names
from harness.studies.records import read_records, write_records
from harness.studies.sweep import run_sweep

PERIODS = 100
GROWTH_LIMIT = 1.5
DAMPING_RATIOS = (0.0, 0.1, 0.25, 0.5, 0.75, 0.95, 2.0, 10.0)  # zeta = d / (2 omega0); 10 is d = 20 omega0
FULL_DAMPING_RATIOS = (0.0, 0.05, 0.1, 0.175, 0.25, 0.375, 0.5, 0.625, 0.75, 0.85, 0.95, 1.0, 1.25, 1.5, 2.0, 3.0,
                       5.0, 10.0, 20.0)


# The atlas's methods: every fixed-step method, and taylor with its fixed step (tol = 0) at order 6. At
# order 6 its linear limits (h omega = 1.1 undamped, up to 3.6 on the damping rays) lie well within the
# radius of convergence of the released object's own series (for the pendulum about 6.7 in h omega at
# 0.01 rad: the pole of its elliptic functions in imaginary time). At order 20 that radius, not the
# stability polynomial, ends the stable steps (measured 5.6 where the polynomial allows 8.9), and at
# order 8 the three-link chain's fastest mode falls 6% short of the polynomial's 3.4.
# gbs with its fixed step at column 3 (order 6, as taylor's): R(z) is the extrapolated midpoint polynomial.
ATLAS_TAYLOR_ORDER = 6
ATLAS_GBS_COLUMNS = 3
ATLAS_METHODS = (*FIXED_STEP, *VARIABLE_ORDER)
FIXED_STEP_SETTINGS = {"taylor": fixed_step_settings("taylor", ATLAS_TAYLOR_ORDER),  # what else a method needs
                       "gbs": fixed_step_settings("gbs", 2 * ATLAS_GBS_COLUMNS)}


def truncated_exponential(z, order: int = TAYLOR_DEFAULT_ORDER):
    """R(z) of the Taylor method of that order: 1 + z + ... + z^order / order!."""
    term, total = np.ones_like(z), np.ones_like(z)
    for k in range(1, order + 1):
        term = term * z / k
        total = total + term
    return total


def extrapolated_midpoint(z, columns: int):
    """R(z) of gbs at column k = columns with its fixed step: on y' = lambda y (z = h lambda) the modified
    midpoint rule with n = 2, 4, ..., 2k substeps (w = z / n: y_1 = 1 + w, y_(m+1) = y_(m-1) + 2 w y_m), the
    results extrapolated in h^2 (Aitken-Neville); a polynomial of degree 2k agreeing with exp(z) to z^(2k)."""
    z = np.asarray(z, dtype=complex)
    above: list = []
    for j in range(1, columns + 1):
        w = z / (2 * j)
        previous, current = np.ones_like(z), 1 + w
        for _ in range(2 * j - 1):
            previous, current = current, previous + 2 * w * current
        row = [current]
        for i in range(1, j):
            ratio = (j / (j - i)) ** 2 - 1
            row.append(row[i - 1] + (row[i - 1] - above[i - 1]) / ratio)
        above = row
    return above[-1]


@lru_cache(maxsize=None)
def method_tables(program: str | None = None) -> dict:
    """The Butcher tableaux and Adams-Bashforth coefficients as the FMUs hold them (printed by the
    build's `integrator_tables`; read once per process, built only where missing: the commands that
    use the tables have built the FMUs already, which costs seconds even when nothing changed)."""
    from harness.fmi.fmus import build_dir, build_fmus
    if program is None:
        program = str(build_dir() / "bin" / "integrator_tables")
        if not Path(program).is_file():
            build_fmus(programs=["integrator_tables"])
    return json.loads(subprocess.run([program], check=True, capture_output=True, text=True).stdout)


def verlet_matrix(w, c) -> np.ndarray:
    """Stormer-Verlet's step on q'' = -omega^2 q - d q' (its form with damping, integrators.c) as a
    matrix on (q, h q'), with w = (h omega)^2 and c = h d (arrays of them: a matrix per element, on the
    last two axes)."""
    w, c = np.asarray(w, dtype=float), np.asarray(c, dtype=float)
    shrink = 1.0 / (1.0 + c / 2)
    # u+ = (u - w/2 q) shrink;  q1 = q + u+;  u1 = (1 - c/2) u+ - w/2 q1
    u_half = np.stack([-w / 2 * shrink, shrink * np.ones_like(w)], axis=-1)
    q1 = np.array([1.0, 0.0]) + u_half
    u1 = (1 - c / 2)[..., None] * u_half - (w / 2)[..., None] * q1
    return np.stack([q1, u1], axis=-2)


def pair_growth(z1: complex, z2: complex) -> float:
    """Stormer-Verlet's growth on the second-order equation whose characteristic roots are h lambda =
    z1, z2 (w = z1 z2, c = -(z1 + z2))."""
    return float(np.max(np.abs(np.linalg.eigvals(verlet_matrix((z1 * z2).real, -(z1 + z2).real)))))


def largest_growth(table: dict, zs) -> float:
    """The largest growth over h*lambda = zs: per eigenvalue for a one-step or multistep method, per
    pair (an oscillator's two roots, consecutive in zs) for a partitioned one."""
    zs = list(zs)
    if table.get("partitioned"):
        return max(pair_growth(zs[k], zs[k + 1]) for k in range(0, len(zs) - 1, 2))
    return max(growth(table, z) for z in zs)


def multistep_weights(table: dict, z) -> np.ndarray:
    """a_j(z) of the recursion zeta^k = sum_j a_j zeta^(k-1-j) that an Adams method follows on
    y' = lambda y, z = h lambda (z scalar or array: the weights along a last axis). Adams-Bashforth:
    a_j = [j = 0] + z beta_j. PECE with the Adams-Moulton weights m (m_0 on the predicted point's f):
    y(k+1) = y(k) + z (m_0 p + sum_j m_(j+1) y(k-j)) with p = y(k) + z sum_j beta_j y(k-j), so
    a_j = [j = 0] (1 + z m_0) + z^2 m_0 beta_j + z m_(j+1)."""
    z = np.asarray(z, dtype=complex)[..., None]
    beta = np.asarray(table["beta"], dtype=float)
    first = (np.arange(len(beta)) == 0).astype(float)
    if "moulton" not in table:
        return first + z * beta
    m = np.asarray(table["moulton"], dtype=float)
    corrector = np.zeros(len(beta))
    corrector[:len(beta) - 1] = m[1:]
    return first * (1 + z * m[0]) + z * z * m[0] * beta + z * corrector


def growth(table: dict, z: complex) -> float:
    """|R(z)| for a Runge-Kutta method (explicit or implicit), the spectral radius of the k-step
    recursion for Adams-Bashforth and Adams-Bashforth-Moulton (PECE), Stormer-Verlet's growth on an
    underdamped oscillator with roots z and conj(z) (`table`: one entry of method_tables())."""
    if table.get("partitioned"):
        return pair_growth(z, z.conjugate() if z.imag else z)
    if table.get("taylor"):
        return float(abs(truncated_exponential(complex(z), table.get("order", TAYLOR_DEFAULT_ORDER))))
    if table.get("extrapolation"):
        return float(abs(extrapolated_midpoint(complex(z), table["columns"])))
    if "beta" in table:
        return float(np.max(np.abs(np.roots(np.concatenate([[1.0], -multistep_weights(table, z)])))))
    a, b = np.asarray(table["a"], dtype=float), np.asarray(table["b"], dtype=float)
    stages = len(b)
    return float(abs(1 + z * b @ np.linalg.solve(np.eye(stages) - z * a, np.ones(stages))))


@dataclass(frozen=True)
class Case:
    """One column of the atlas: an object released from rest, with the eigenvalues of its
    linearization as multiples of omega (empty for a nonlinear case)."""
    object: str
    damping: float  # d [1/s]
    release: float
    omega: float  # the reference frequency [rad/s]: the x-axis is h * omega, the window 100 periods of it
    start: dict = field(default_factory=dict, hash=False, compare=False)
    rest: dict = field(default_factory=dict, hash=False, compare=False)
    eigenvalues: tuple = ()  # lambda / omega

    @property
    def window(self) -> float:
        return PERIODS * 2 * math.pi / self.omega

    @property
    def linear(self) -> bool:
        return bool(self.eigenvalues)


def theory_limit(table: dict, case: Case) -> float:
    """Largest h*omega below the first one whose growth over the window exceeds the limit: a scan up
    from 1e-6 in factors of 1.02 (evaluated at once, as arrays), then bisection of the bracket."""
    if not case.linear:
        return math.nan
    eigenvalues = np.asarray(case.eigenvalues, dtype=complex)

    def allowed(y, g):
        return 2 * (PERIODS * 2 * math.pi / y) * np.log(np.maximum(g, 1e-300)) <= math.log(GROWTH_LIMIT)

    def stable(y: float) -> bool:
        return bool(allowed(y, largest_growth(table, [y * lam for lam in case.eigenvalues])))
    scan = [1e-6]
    while scan[-1] <= 50:
        scan.append(scan[-1] * 1.02)
    ys = np.array(scan[1:])
    unstable = np.flatnonzero(~allowed(ys, largest_growth_on_grid(table, ys[:, None] * eigenvalues)))
    if not len(unstable):
        return math.inf
    k = int(unstable[0])  # scan[k] stable, scan[k + 1] not: checked on the scalar path, from which the
    while k > 0 and not stable(scan[k]):  # arrays can differ in the last bit at a point of the scan
        k -= 1
    while stable(scan[k + 1]):
        k += 1
        if k + 1 == len(scan):
            return math.inf
    low, high = scan[k], scan[k + 1]
    for _ in range(60):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if stable(middle) else (low, middle)
    return low


def _parameters(fmu: Path) -> dict[str, float]:
    from harness.objects.thesis.equations import Pendulum
    return Pendulum.from_fmu(fmu).parameters


def simple_cases(fmu: Path, ratios=DAMPING_RATIOS) -> list[Case]:
    p = _parameters(fmu)
    omega0 = math.sqrt(p["g"] / p["L"])
    cases = []
    for zeta in ratios:
        root = complex(zeta * zeta - 1) ** 0.5
        eigenvalues = (-zeta + root, -zeta - root)
        cases.append(Case("SimplePendulum", 2 * zeta * omega0, 0.01, omega0, {"phi": 0.01, "omega": 0.0},
                          {"phi": 0.0, "omega": 0.0}, eigenvalues))
    cases.append(Case("SimplePendulum", 0.0, 3.0, omega0, {"phi": 3.0, "omega": 0.0}, {"phi": 0.0, "omega": 0.0}))
    return cases


def mode_case(fmu: Path) -> Case | None:
    """The object released at rest in its fastest normal mode (largest coordinate 0.01), undamped;
    None for an object without a linear model (driven, or singular at rest)."""
    spec = object_file_in(fmu)
    modes = normal_modes(derive(spec)) if spec is not None else None
    if modes is None:
        return None
    omega = math.sqrt(float(np.max(modes.squares)))
    velocities = {c.velocity: 0.0 for c in spec.coordinates}
    return Case(spec.identifier, 0.0, 0.01, omega, {**modes.fastest_release(0.01), **velocities},
                {**modes.rest, **velocities}, tuple(lam / omega for lam in modes.eigenvalues()))


@dataclass
class Limit:
    object: str
    method: str
    damping: float
    measured_limit: float
    theory_limit: float
    release: float
    runs: int = 0  # FMU runs the scan took (not written to the CSV)

    @staticmethod
    def columns() -> list[str]:
        return ["object", "method", "damping", "measured_limit", "theory_limit", "release"]


class Probe:
    """One FMU instance that answers 'is this h*omega stable?' for one case and method."""

    def __init__(self, fmu: str, case: Case, method: str):
        from harness.fmi.fmu_instance import FmuInstance
        self.instance = FmuInstance(fmu, name=f"{case.object}-{method}")
        self.case, self.method = case, method
        self.runs = 0
        self.instance.initialize(0.0, d=case.damping, **case.rest)
        self.rest_energy = self.instance.get("E")[0]
        self.instance.reset()

    def stable(self, n: int) -> bool:
        from harness.fmi.fmu_instance import OK
        self.runs += 1
        case, instance = self.case, self.instance
        instance.reset()
        settings = {"solver": self.method, **FIXED_STEP_SETTINGS.get(self.method, {})}
        instance.initialize(0.0, h=case.window / n, d=case.damping, **settings, **case.start)
        start = instance.get("E")[0] - self.rest_energy
        if instance.do_step(0.0, case.window) != OK:
            return False
        end = instance.get("E")[0] - self.rest_energy
        return math.isfinite(end) and end <= GROWTH_LIMIT * start

    def close(self) -> None:
        self.instance.free()


def _steps(case: Case, y: float) -> int:
    return max(1, round(case.window * case.omega / y))


def measure(job: tuple[str, Case, str, dict]) -> Limit:
    """The measured limit for one case and method (runs in a worker)."""
    fmu, case, method, table = job
    linear_twin = case if case.linear else Case(case.object, case.damping, 0.01, case.omega,
                                                eigenvalues=(1j, -1j))
    hint = theory_limit(table, linear_twin)
    predicted = hint if case.linear else math.nan  # theory_limit(table, case): the twin is the case itself
    probe = Probe(fmu, case, method)
    try:
        y = hint / 4 if math.isfinite(hint) else 1.0  # A-stable: scanned up from h omega = 1
        while not probe.stable(_steps(case, y)):  # a nonlinear case can fail below the linear hint
            y /= 4
            if y < 1e-7:
                return Limit(case.object, method, case.damping, 0.0, predicted, case.release, probe.runs)
        stable_n = _steps(case, y)
        while True:
            y *= 1.25
            n = _steps(case, y)
            if n == stable_n:
                n -= 1
            if n < 1 or not probe.stable(n):
                unstable_n = max(n, 0)
                break
            stable_n = n
        while stable_n - unstable_n > 1:  # fewer steps = larger h*omega
            middle = (stable_n + unstable_n) // 2
            if probe.stable(middle):
                stable_n = middle
            else:
                unstable_n = middle
        measured = case.window * case.omega / stable_n
        return Limit(case.object, method, case.damping, measured, predicted, case.release, probe.runs)
    finally:
        probe.close()


QUICK_DAMPING_RATIOS = (0.0, 0.5, 10.0)


def cases(fmu_dir: Path, full: bool = False, quick: bool = False, objects: list[str] | None = None) -> list[Case]:
    """The SimplePendulum's damping rays and large swing, then every other object of the registry
    (or of `objects`) with a linear model in its fastest mode."""
    fmu_dir = Path(fmu_dir)
    ratios = FULL_DAMPING_RATIOS if full else QUICK_DAMPING_RATIOS if quick else DAMPING_RATIOS
    chosen = list(objects) if objects is not None else list(object_names())
    found = [simple_cases(fmu_dir / "SimplePendulum.fmu", ratios)] if "SimplePendulum" in chosen else []
    found += [[mode_case(fmu_dir / f"{name}.fmu")] for name in chosen if name != "SimplePendulum"]
    measured = [case for group in found for case in group if case is not None]
    if not measured:
        raise HarnessError(f"{', '.join(chosen)}: no linear model to measure a stability limit on; the atlas "
                           "takes the SimplePendulum and objects with a linear model")
    return measured


def plan_tables() -> dict:
    """method_tables() with the taylor<order> and gbs<order> a plan may name (harness.fmi.methods.PLANNABLE)."""
    tables = method_tables()
    for name in PLANNABLE:
        if plan_solver(name) == "taylor":
            tables[name] = {"taylor": True, "order": plan_order(name)}
        elif plan_solver(name) == "gbs":
            tables[name] = {"extrapolation": True, "columns": plan_order(name) // 2}
    return tables


def atlas_tables() -> dict:
    """method_tables() with taylor and gbs at the atlas's orders."""
    return {**method_tables(), "taylor": {"taylor": True, "order": ATLAS_TAYLOR_ORDER},
            "gbs": {"extrapolation": True, "columns": ATLAS_GBS_COLUMNS}}


def atlas(fmu_dir: Path, methods=ATLAS_METHODS, full: bool = False, scheduler: str | None = None,
          workers: int | None = None, quick: bool = False, objects: list[str] | None = None) -> list[Limit]:
    from harness.fmi.fmu_instance import accepted_methods
    tables = atlas_tables()
    jobs = [(fmu, case, method, tables[method]) for case in cases(fmu_dir, full, quick, objects)
            for fmu in [str(Path(fmu_dir) / f"{case.object}.fmu")] for method in methods
            if method in accepted_methods(fmu)]
    return run_sweep(measure, jobs, scheduler, workers)


def sharp_deviations(limits: list[Limit], all_cases: list[Case]) -> list[tuple[Limit, float]]:
    """(limit, measured / predicted - 1) where the prediction is sharp: the linear cases, but not an
    A-stable method's (unbounded) nor Stormer-Verlet's on an overdamped case, where the mode that
    grows first is the step's parasitic one, which a release from rest barely excites, so that the
    worst-case prediction is only a lower bound."""
    by_key = {(c.object, round(c.damping, 12), c.release): c for c in all_cases}
    sharp = []
    for limit in limits:
        case = by_key[(limit.object, round(limit.damping, 12), limit.release)]
        if not math.isfinite(limit.theory_limit):
            continue
        if limit.method == "stormer_verlet" and all(lam.imag == 0 for lam in case.eigenvalues):
            continue
        sharp.append((limit, limit.measured_limit / limit.theory_limit - 1))
    return sharp


def write_csv(limits: list[Limit], path: Path) -> None:
    write_records(limits, path, Limit.columns())


def read_csv(path: Path) -> list[Limit]:
    return read_records(path, Limit)



def largest_growth_on_grid(table: dict, zs: np.ndarray) -> np.ndarray:
    """largest_growth() for arrays: over the last axis of zs (pairs of it for a partitioned method)."""
    zs = np.asarray(zs, dtype=complex)
    if table.get("partitioned"):
        if zs.shape[-1] % 2:
            raise ValueError("a partitioned method's growth is taken over pairs of roots: an even number")
        z1, z2 = zs[..., 0::2], zs[..., 1::2]
        matrices = verlet_matrix((z1 * z2).real, -(z1 + z2).real)
        return np.max(np.abs(np.linalg.eigvals(matrices)), axis=(-1, -2))
    return np.max(growth_on_grid(table, zs), axis=-1)


def growth_on_grid(table: dict, z: np.ndarray) -> np.ndarray:
    """growth() for an array of z at once (the stability-region charts)."""
    z = np.asarray(z, dtype=complex)
    if table.get("taylor"):
        return np.abs(truncated_exponential(z, table.get("order", TAYLOR_DEFAULT_ORDER)))
    if table.get("extrapolation"):
        return np.abs(extrapolated_midpoint(z, table["columns"]))
    if table.get("partitioned"):  # the oscillator whose roots are z and its conjugate
        matrices = verlet_matrix((z * z.conjugate()).real, -(z + z.conjugate()).real)
        return np.max(np.abs(np.linalg.eigvals(matrices)), axis=-1)
    if table.get("implicit"):  # R(z) = 1 + z b (I - z A)^-1 1, a system per point
        a, b = np.asarray(table["a"], dtype=float), np.asarray(table["b"], dtype=float)
        systems = np.eye(len(b)) - z[..., None, None] * a
        stages = np.linalg.solve(systems, np.ones(z.shape + (len(b), 1), dtype=complex))[..., 0]
        return np.abs(1 + z * (stages @ b))
    if "beta" in table:
        weights = multistep_weights(table, z)
        k = weights.shape[-1]
        companion = np.zeros(z.shape + (k, k), dtype=complex)
        companion[..., 0, :] = weights
        if k > 1:
            companion[..., np.arange(1, k), np.arange(k - 1)] = 1.0
        return np.max(np.abs(np.linalg.eigvals(companion)), axis=-1)
    a, b = np.asarray(table["a"], dtype=float), np.asarray(table["b"], dtype=float)
    # explicit: R(z) = 1 + sum_k (b A^(k-1) 1) z^k
    power, value = np.ones(len(b)), np.ones_like(z)
    for k in range(1, len(b) + 1):
        value = value + (b @ power) * z ** k
        power = a @ power
    return np.abs(value)


def measured_point(limit: Limit, case: Case) -> complex:
    """Where a measured limit sits in the complex h*lambda plane: on the eigenvalue that grows first."""
    if not case.linear:
        return 1j * limit.measured_limit
    return limit.measured_limit * max(case.eigenvalues, key=lambda lam: (round(abs(lam), 9), lam.imag))


def linearized_eigenvalues(kind: str | ObjectSpec, p: dict[str, float]) -> list[complex]:
    """Eigenvalues [1/s] of an object (a registry name or an object file read) linearized about rest
    at parameters p, its damping d included (normal modes from the object file's energies)."""
    spec = kind if isinstance(kind, ObjectSpec) else read_object_file(object_file(kind))
    modes = normal_modes(derive(spec), p)
    if modes is None:
        raise ValueError(f"{spec.identifier} has no linear model")
    return modes.eigenvalues(p.get("d", 0.0))


def stable_over(table: dict, eigenvalues: list[complex], h: float, duration: float) -> bool:
    """The atlas's criterion over a scene instead of 100 periods: growth^(2N) <= 1.5 for N = duration/h."""
    g = largest_growth(table, [h * lam for lam in eigenvalues])
    return 2 * (duration / h) * math.log(max(g, 1e-300)) <= math.log(GROWTH_LIMIT)
