#!/usr/bin/env python3
"""The FMUs' Taylor method (and gbs) against heyoka, the field's fastest Taylor integrator (Taylor's
method compiled through LLVM for this machine), on every object of the registry without contacts, at
the same accuracy, measured side by side in one run.

Accuracy: every point of the object (its [points]) within TARGET metres of the reference at t = 10 s, from
the object's default start. The reference is heyoka's own integration in 80-bit extended precision at
tol = 1e-19 (its spread against tol = 1e-18 is printed; it must be far below the targets).

heyoka integrates the object's equations as the registry derives them from its energies (M a = f,
default parameters), given to heyoka in explicit form both ways heyoka offers: its own Euler-Lagrange
formulation of L = T - U (heyoka.lagrangian) and the linear solve a = M^-1 f written out by SymPy; the
faster of the two is heyoka's entry. For each target, heyoka runs at the loosest tolerance (four per
decade, from 1e-6 down) that meets it, compact mode off; the time of its construction (LLVM compilation)
is printed beside and not counted. The FMU's `taylor` runs at its fastest setting that meets the target
among every order from 6 with a fixed step and with the step chosen for tol (eight per decade), and
`gbs` at its fastest among tolerances and fixed columns; both in one fmi2DoStep over 10 s. Times are
medians of interleaved repeats.

    python benchmarks/heyoka_benchmark.py [--objects DoublePendulum,Chain5] [--targets 1e-9,1e-11]

heyoka is a benchmark-only dependency (pip install -e ".[bench]"; ./run bench installs it).
"""
from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sympy as sp

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from harness.fmi.fmu_instance import FmuInstance  # noqa: E402
from harness.fmi.fmus import build_dir, build_fmus  # noqa: E402
from harness.fmi.methods import GBS_COLUMNS, TAYLOR_ORDERS  # noqa: E402
from harness.objects.derivation import derive  # noqa: E402
from harness.objects.object_file import read_object_file  # noqa: E402
from harness.objects.registry import constrained_names, object_file, object_names  # noqa: E402

STOP = 10.0
TARGETS = (1e-9, 1e-11)
GOAL = 1.3  # heyoka's time / the FMU taylor's, on every object but the simple pendulum (there: 1.0)


@dataclass
class Run:
    who: str                 # "taylor", "gbs" or "heyoka"
    setting: str
    error: float
    steps: int
    seconds: float = math.nan
    compile_seconds: float = 0.0
    samples: list[float] = field(default_factory=list)


@dataclass
class Equations:
    """An object's motion with its default parameters: x = (q, v), x' = (v, a(q, v, t))."""
    name: str
    start: list[float]
    coordinates: list[str]
    q: list[sp.Symbol]
    v: list[sp.Symbol]
    t: sp.Symbol
    accelerations: list[sp.Expr]    # explicit, by SymPy's LU solve
    lagrangian: sp.Expr | None      # L = T - U where heyoka.lagrangian can take it (no time, no damping)
    points: object                  # q -> array of point positions

    @classmethod
    def of(cls, name: str) -> "Equations":
        spec = read_object_file(object_file(name))
        derivation = derive(spec)
        values = {spec.symbols[p.name]: p.start for p in spec.parameters if p.name in spec.symbols}
        M, f = derivation.M.subs(values), derivation.f.subs(values)
        damping = values.get(spec.symbols.get("d"), 0.0) if "d" in spec.symbols else 0.0
        a = M.LUsolve(f)
        accelerations = [a[j] - damping * spec.v[j] for j in range(derivation.n)]
        L = (spec.T - spec.U).subs(values)
        lagrangian = L if damping == 0 and spec.time not in L.free_symbols else None
        positions = [[x.subs(values) for x in point] for point in derivation.positions]
        points = sp.lambdify(spec.q + [spec.time], positions, "numpy")
        start = [c.start for c in spec.coordinates] + [c.velocity_start for c in spec.coordinates]
        return cls(name, start, [c.name for c in spec.coordinates], spec.q, spec.v, spec.time, accelerations,
                   lagrangian, lambda q: np.array(points(*q, STOP), dtype=float))


class Heyoka:
    """heyoka's integrator for one object: its systems (both explicit forms), its reference."""

    def __init__(self, equations: Equations):
        import heyoka as hy
        self.hy = hy
        # compile times as a new user sees them: not from heyoka's cache on disk of earlier runs' code
        hy.llvm_state.set_diskcache_enabled(False)
        self.equations = equations
        n = len(equations.q)
        qs = [hy.make_vars(str(s)) for s in equations.q]
        vs = [hy.make_vars(str(s)) for s in equations.v]
        symbols = dict(zip(equations.q + equations.v, qs + vs))
        symbols[equations.t] = hy.time
        self.last_steps = 0
        self.systems = {"LU solve": [(qs[j], vs[j]) for j in range(n)]
                        + [(vs[j], hy.from_sympy(equations.accelerations[j], symbols)) for j in range(n)]}
        if equations.lagrangian is not None:
            self.systems["heyoka.lagrangian"] = hy.lagrangian(hy.from_sympy(equations.lagrangian, symbols), qs, vs)

    def reference(self) -> tuple[np.ndarray, float]:
        """The state at STOP in extended precision, and its spread against a looser tolerance."""
        hy = self.hy
        system = self.systems["LU solve"]
        states = []
        for tol in (1e-19, 1e-18):
            ta = hy.taylor_adaptive(system, np.array(self.equations.start, dtype=np.longdouble),
                                    tol=np.longdouble(tol), fp_type=np.longdouble, compact_mode=True)
            ta.propagate_until(np.longdouble(STOP))
            states.append(np.array(ta.state, dtype=np.longdouble))
        n = len(self.equations.q)
        spread = float(np.max(np.linalg.norm(self.equations.points(states[0][:n].astype(float))
                                             - self.equations.points(states[1][:n].astype(float)), axis=-1)))
        return states[0].astype(float), spread

    def integrator(self, system: str, tol: float):
        start = time.perf_counter()
        ta = self.hy.taylor_adaptive(self.systems[system], self.equations.start, tol=tol, compact_mode=False)
        return ta, time.perf_counter() - start

    def run(self, ta, most_steps: int = 200_000) -> tuple[np.ndarray, int]:
        """The state at STOP and the steps taken (NaN where it took more than most_steps: heyoka's step
        at orders divisible by 4 on the double pendulum, its series there every fourth power)."""
        ta.time = 0.0
        ta.state[:] = self.equations.start
        steps = [0]

        def bounded(_):
            steps[0] += 1
            return steps[0] < most_steps
        ta.propagate_until(STOP, callback=bounded)
        return (np.array(ta.state) if ta.time == STOP else np.full(len(ta.state), np.nan)), steps[0]

    def timed(self, ta) -> float:
        """Seconds of one run from the start to STOP (the reset before it not counted)."""
        ta.time = 0.0
        ta.state[:] = self.equations.start
        start = time.perf_counter()
        outcome = ta.propagate_until(STOP)
        seconds = time.perf_counter() - start
        self.last_steps = int(outcome[3])
        return seconds


def point_error(equations: Equations, state: np.ndarray, reference: np.ndarray) -> float:
    n = len(equations.q)
    if not np.all(np.isfinite(state[:n])):
        return math.inf
    return float(np.max(np.linalg.norm(equations.points(state[:n]) - equations.points(reference[:n]), axis=-1)))


def heyoka_loosest(heyoka: Heyoka, reference: np.ndarray, target: float) -> tuple[Run, object] | None:
    """heyoka at the loosest tolerance that meets the target, with the faster of its two forms there."""
    for tol in 10.0 ** -(6 + np.arange(0, 13, 0.25)):
        best = None
        for system in heyoka.systems:
            ta, compile_seconds = heyoka.integrator(system, tol)
            state, steps = heyoka.run(ta)
            error = point_error(heyoka.equations, state, reference)
            if error > target:
                continue
            seconds = min(heyoka.timed(ta) for _ in range(3))
            if best is None or seconds < best[2]:
                best = (Run("heyoka", f"tol = {tol:.3g}, order {ta.order}, {system}", error, steps,
                            compile_seconds=compile_seconds), ta, seconds)
        if best is not None:
            run, ta, _ = best
            # its compile time without heyoka's cache of compiled code, which the search has filled
            heyoka.hy.llvm_state.clear_memcache()
            _, run.compile_seconds = heyoka.integrator(run.setting.rsplit(", ", 1)[1], ta.tol)
            return run, ta
    return None


def fmu_run(fmu: FmuInstance, equations: Equations, settings: dict, reference: np.ndarray) -> tuple[float, int]:
    fmu.reset()
    fmu.initialize(**settings)
    if fmu.do_step(0.0, STOP) != 0:
        return math.inf, 0
    n = len(equations.q)
    state = np.array(fmu.get(*equations.coordinates) + [0.0] * n)
    return point_error(equations, state, reference), int(fmu.get("n_steps")[0])


def fmu_timed(fmu: FmuInstance, settings: dict) -> float:
    """Seconds of one fmi2DoStep from the start to STOP (the reset and initialization not counted)."""
    fmu.reset()
    fmu.initialize(**settings)
    start = time.perf_counter()
    fmu.do_step(0.0, STOP)
    return time.perf_counter() - start


def fmu_candidates(method: str) -> list[dict]:
    steps = np.unique(np.geomspace(10, 4000, 40).astype(int))
    if method == "taylor":
        return [{"solver": "taylor", "taylor_order": order, **extra}
                for order in range(6, TAYLOR_ORDERS[1] + 1)
                for extra in ([{"tol": tol} for tol in 10.0 ** -(6 + np.arange(0, 11, 0.125))]
                              + [{"tol": 0.0, "h": STOP / n} for n in steps])]
    return ([{"solver": "gbs", "tol": tol} for tol in 10.0 ** -(6 + np.arange(0, 9, 0.25))]
            + [{"solver": "gbs", "gbs_columns": columns, "tol": 0.0, "h": STOP / n}
               for columns in range(2, GBS_COLUMNS + 1) for n in steps])


def fmu_fastest(fmu: FmuInstance, equations: Equations, method: str, reference: np.ndarray,
                target: float) -> tuple[Run, dict] | None:
    """The fastest setting that meets the target: of each order's (columns') cheapest in steps, timed."""
    cheapest: dict[object, tuple[int, dict, float]] = {}
    for settings in fmu_candidates(method):
        error, steps = fmu_run(fmu, equations, settings, reference)
        key = settings.get("taylor_order", settings.get("gbs_columns", "tol"))
        if error <= target and (key not in cheapest or steps < cheapest[key][0]):
            cheapest[key] = (steps, settings, error)
    best = None
    for steps, settings, error in cheapest.values():
        seconds = min(fmu_timed(fmu, settings) for _ in range(3))
        if best is None or seconds < best[2]:
            label = ", ".join(f"{k} = {v:.3g}" for k, v in settings.items() if k != "solver")
            best = (Run(method, label, error, steps), settings, seconds)
    return None if best is None else (best[0], best[1])


def compare(name: str, targets: tuple[float, ...], repeats: int) -> list[tuple[float, list[Run]]]:
    equations = Equations.of(name)
    heyoka = Heyoka(equations)
    reference, spread = heyoka.reference()
    print(f"{name}: reference spread {spread:.1e} m", flush=True)
    results = []
    with FmuInstance(build_dir() / "fmus" / f"{name}.fmu") as fmu:
        for target in targets:
            entries = []  # (run, one timed run)
            found = heyoka_loosest(heyoka, reference, target)
            if found:
                run, ta = found
                entries.append((run, lambda ta=ta: heyoka.timed(ta)))
            for method in ("taylor", "gbs"):
                found = fmu_fastest(fmu, equations, method, reference, target)
                if found:
                    run, settings = found
                    entries.append((run, lambda settings=settings: fmu_timed(fmu, settings)))
            for _ in range(repeats):  # interleaved: the machine's load falls on each alike
                for run, timed in entries:
                    run.samples.append(timed())
            for run, _ in entries:
                run.seconds = statistics.median(run.samples)
            results.append((target, [run for run, _ in entries]))
    return results


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", help="comma-separated object names (default: every object without contacts)")
    parser.add_argument("--targets", default=",".join(f"{t:g}" for t in TARGETS))
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args(argv)
    try:
        import heyoka
    except ImportError:
        print("heyoka is not installed (pip install heyoka): nothing to compare")
        return 0
    free = [n for n in object_names() if n not in constrained_names()]
    names = args.objects.split(",") if args.objects else free
    unknown = [n for n in names if n not in free]
    if unknown:
        print(f"heyoka_benchmark: {', '.join(unknown)}: not an object of the registry without contacts "
              f"(these are: {', '.join(free)})", file=sys.stderr)
        return 2
    try:
        targets = tuple(float(t) for t in args.targets.split(","))
    except ValueError:
        print(f"heyoka_benchmark: --targets {args.targets}: expected numbers in metres, such as 1e-9,1e-11",
              file=sys.stderr)
        return 2
    build_fmus()
    skipped = [n for n in object_names() if n in constrained_names()] if not args.objects else []
    print(f"heyoka {heyoka.__version__}; every point within the target at t = {STOP:g} s; "
          f"median of {args.repeats} interleaved runs")
    table = []
    for name in names:
        for target, runs in compare(name, targets, args.repeats):
            by = {run.who: run for run in runs}
            for run in runs:
                print(f"  {target:7.0e} {run.who:>7} {run.setting:>52} error {run.error:8.1e} steps {run.steps:7d} "
                      f"{run.seconds * 1e3:9.3f} ms" + (f"  (compiled in {run.compile_seconds:.2f} s)"
                                                         if run.who == "heyoka" else ""), flush=True)
            table.append((name, target, by))
    print("\nheyoka's time / the FMU's (above 1: the FMU is faster)")
    print(f"{'object':>22} {'target [m]':>10} {'taylor':>8} {'gbs':>8}   goal")
    met = True
    for name, target, by in table:
        peer = by.get("heyoka")
        ratios = [peer.seconds / by[m].seconds if peer and m in by else math.nan for m in ("taylor", "gbs")]
        goal = 1.0 if name == "SimplePendulum" else GOAL
        ok = ratios[0] >= goal
        met &= ok
        print(f"{name:>22} {target:10.0e} {ratios[0]:8.2f} {ratios[1]:8.2f}   {goal:.1f} {'met' if ok else 'NOT met'}")
    if skipped:
        print(f"not compared (contacts, which need heyoka's event detection): {', '.join(skipped)}")
    print("goal met on every object" if met else "goal not met on every object")
    return 0


if __name__ == "__main__":
    sys.exit(main())
