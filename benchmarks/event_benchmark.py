#!/usr/bin/env python3
"""What an event costs, and the rigid Newton's cradle against scipy's solve_ivp with event functions.

1. The cost of an event in steps of its method: the pendulum striking a wall (modelDescription/
   WallPendulum.toml, restitution 1) run for 10 s with the wall at 0.3 rad and again with it out of reach
   (3.2 rad), one fmi2DoStep each; the extra right-hand-side evaluations (indicator forces included)
   per impact, divided by the method's evaluations per step. Machine-independent counts.
2. One full period of the cradle (modelDescription/NewtonsCradle.toml: ball 1 let go from
   0.5 rad, one ball out, back, one ball out the other side, back): its state after the period against
   the exact one (ball 1 at -0.5 rad at rest, the others at rest), for the FMU's taylor (order 12), gbs, rkf45,
   nystrom5 and rk4 and for scipy's solve_ivp (DOP853, its fastest method here) on the same physics written here in
   Python: five pendulum equations, the four gaps as terminal event functions, and at each impact the
   exchange of the touching balls' velocities passed along the row. Each at the cheapest setting found
   that reaches the target error, then timed side by side (median of interleaved repeats, each the mean of a burst of
   five back-to-back runs), as ratios to
   the FMU's fastest. The FMU's time is its one fmi2DoStep over the period; setting it up (reset,
   parameters, initialization) is reported beside it, like a compiler's time, and in a second ratio.

Usage: python benchmarks/event_benchmark.py [--targets 1e-6,1e-9,1e-12] [--repeats 5]
"""
from __future__ import annotations

import argparse
import ctypes
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from scipy.integrate import solve_ivp  # noqa: E402
from scipy.special import ellipk  # noqa: E402

from harness.fmi.fmu_instance import FmuInstance  # noqa: E402
from harness.fmi.methods import FIXED_STEP, METHOD, SOLVERS  # noqa: E402
from harness.fmi.fmus import build_fmus, locate_fmu  # noqa: E402

G, L, R, PHI0 = 9.81, 0.3, 0.02, 0.5  # the cradle's defaults
BURST = 5  # runs timed back to back, so that each finds its code and data in the caches as a loop would
PERIOD = 4 * ellipk(math.sin(PHI0 / 2) ** 2) * math.sqrt(L / G)
TAYLOR_ORDER = 12  # taylor's order on the cradle (orders 10 to 16 cost about the same)
# The longest step of the methods that compare the gaps at step ends only (taylor, and scipy's solve_ivp): below
# the 0.16 s a ball takes to pass through its neighbour, so that no impact falls between two comparisons.
MAX_STEP = 0.1
EVENT_BOUND = 16  # solve_ivp calls per period, which holds two impacts; an event that exchanged nothing recurs


# ---------------------------------------------------------------- 1. the cost of an event

def event_cost(fmu: Path, methods: list[str], h: float = 1e-3) -> list[tuple[str, float, float, float]]:
    """(method, impacts, evaluations per step, extra evaluations per impact) on the wall pendulum."""
    def run(method: str, wall: float) -> tuple[float, float, float]:
        with FmuInstance(fmu) as instance:
            instance.initialize(solver=SOLVERS.index(method) + 1, h=h, phi_wall=wall, e=1.0)
            instance.do_step(0.0, 10.0)
            return tuple(instance.get("n_rhs", "n_steps", "n_events"))
    rows = []
    for method in methods:
        with_wall, without = run(method, 0.3), run(method, 3.2)
        # the same fixed steps in both runs: the difference is the events' work
        rows.append((method, with_wall[2], without[0] / without[1], (with_wall[0] - without[0]) / with_wall[2]))
    return rows


# ---------------------------------------------------------------- 2. the cradle against solve_ivp

def gaps(phi: np.ndarray) -> np.ndarray:
    """The surface distances of neighbouring balls, pivots 2 R apart."""
    x = 2 * R * (np.arange(5) - 2) + L * np.sin(phi)
    y = -L * np.cos(phi)
    return np.hypot(np.diff(x), np.diff(y)) - 2 * R


def scipy_cradle(rtol: float) -> np.ndarray:
    """One period of the cradle by solve_ivp: free swings between impacts, located by the gap events; an
    impact of equal balls with restitution 1 exchanges their velocities, passed on along touching balls."""
    def rhs(t, y):
        return np.concatenate([y[5:], -G / L * np.sin(y[:5])])

    def event(i):
        def gap(t, y):  # just past contact: touching balls at rest (gap 0 to rounding) are no event
            return gaps(y[:5])[i] + 1e-12
        gap.terminal, gap.direction = True, -1
        return gap
    events = [event(i) for i in range(4)]
    t, y = 0.0, np.array([-PHI0, 0, 0, 0, 0, 0, 0, 0, 0, 0], dtype=float)
    for _ in range(EVENT_BOUND):
        solution = solve_ivp(rhs, (t, PERIOD), y, method="DOP853", rtol=rtol, atol=rtol, events=events,
                             max_step=MAX_STEP)
        t, y = solution.t[-1], solution.y[:, -1].copy()
        if solution.status != 1:
            return y
        # the impact: exchanges along the row until no touching pair approaches
        for _ in range(16):
            touching = gaps(y[:5]) < 1e-9
            approaching = [i for i in range(4) if touching[i] and y[5 + i] > y[6 + i]]
            if not approaching:
                break
            i = approaching[0]
            y[5 + i], y[6 + i] = y[6 + i], y[5 + i]
    raise RuntimeError(f"solve_ivp at rtol {rtol:g}: {EVENT_BOUND} events in one period of the cradle, which has two "
                       f"impacts; stopped at t = {t:.6f} s")


def fmu_cradle(fmu: FmuInstance, settings: dict) -> np.ndarray:
    set_up(fmu, settings)
    return period(fmu)


def set_up(fmu: FmuInstance, settings: dict) -> None:
    fmu.reset()
    fmu.initialize(**settings)


STATE = [f"phi{i}" for i in range(1, 6)] + [f"omega{i}" for i in range(1, 6)]


def period(fmu: FmuInstance) -> np.ndarray:
    """The period in one fmi2DoStep, and the state after it (one prepared fmi2GetReal, as an importer reads)."""
    fmu.do_step(0.0, PERIOD)
    values = np.empty(len(STATE))
    if fmu.state_reader(values.ctypes.data) != 0:
        raise RuntimeError(f"reading the cradle's state failed: {fmu.last_message()}")
    return values


def prepare_reader(fmu: FmuInstance) -> None:
    vrs = (ctypes.c_uint * len(STATE))(*(fmu.reference(name) for name in STATE))
    fmu.state_reader = fmu.raw.reader(fmu.raw.float_type, vrs, len(STATE))


def error(state: np.ndarray) -> float:
    exact = np.array([-PHI0, 0, 0, 0, 0, 0, 0, 0, 0, 0])
    return float(np.max(np.abs(state - exact)))


def candidates(method: str) -> list[dict]:
    """The settings tried, cheapest first: a tolerance for the adaptive methods (their steps at most 0.05 s
    apart, taylor's 0.1 s, where the indicators are compared), a step for the fixed-step ones."""
    solver = SOLVERS.index(method) + 1
    if method in ("gbs", "rkf45", "taylor"):
        step = {"h": MAX_STEP, "taylor_order": TAYLOR_ORDER} if method == "taylor" else {"h": 0.05}
        return [{"solver": solver, "tol": tol, **step} for tol in (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13)]
    return [{"solver": solver, "h": PERIOD / n} for n in (25, 50, 100, 150, 200, 300, 400, 800, 1600, 3200)]


def cheapest_fmu(fmu: FmuInstance, method: str, target: float) -> dict | None:
    """The first setting of the method (largest step, loosest tolerance) that reaches the target after one period."""
    for settings in candidates(method):
        if error(fmu_cradle(fmu, settings)) <= target:
            return settings
    return None


def cheapest_scipy(target: float) -> float | None:
    for rtol in (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13):
        if error(scipy_cradle(rtol)) <= target:
            return rtol
    return None


def timed(run) -> float:
    start = time.perf_counter()
    run()
    return time.perf_counter() - start


def describe(method: str, settings: dict) -> str:
    return f"FMU {method} " + (f"tol {settings['tol']:g}" if "tol" in settings else f"h = {settings['h']:.3g}")


def compare(fmu: FmuInstance, target: float, repeats: int) -> None:
    """Section 2 at one target error."""
    chosen = {method: cheapest_fmu(fmu, method, target) for method in ("taylor", "gbs", "rkf45", "nystrom5", "rk4")}
    chosen = {method: settings for method, settings in chosen.items() if settings is not None}
    rtol = cheapest_scipy(target)
    errors = {describe(m, s): error(fmu_cradle(fmu, s)) for m, s in chosen.items()}
    times: dict[str, list[float]] = {name: [] for name in errors}
    setups: dict[str, list[float]] = {name: [] for name in errors}
    scipy_name = f"scipy DOP853 rtol {rtol:g}" if rtol is not None else None
    if scipy_name:
        errors[scipy_name] = error(scipy_cradle(rtol))
        times[scipy_name] = []
    for _ in range(repeats):  # interleaved (a noisy machine slows all alike), each a burst of BURST runs
        for method, settings in chosen.items():
            name = describe(method, settings)
            burst = [(timed(lambda: set_up(fmu, settings)), timed(lambda: period(fmu))) for _ in range(BURST)]
            setups[name].append(statistics.mean(setup for setup, _ in burst))
            times[name].append(statistics.mean(run for _, run in burst))
        if scipy_name:
            times[scipy_name].append(statistics.mean(timed(lambda: scipy_cradle(rtol)) for _ in range(BURST)))
    median = {name: statistics.median(t) for name, t in times.items()}
    fmu_names = [name for name in median if name.startswith("FMU")]
    if not fmu_names:
        print(f"no FMU method tried reaches {target:g}")
        return
    best = min(fmu_names, key=median.get)
    best_with_setup = median[best] + statistics.median(setups[best])
    print(f"\nstate error <= {target:g}")
    print(f"{'run':28s} {'error':>9s} {'seconds':>10s} {'set-up s':>10s} {'x fastest FMU':>14s}")
    for name in median:
        setup = f"{statistics.median(setups[name]):10.2e}" if name in setups else f"{'':10s}"
        print(f"{name:28s} {errors[name]:9.1e} {median[name]:10.2e} {setup} {median[name] / median[best]:14.1f}")
    if scipy_name:
        print(f"scipy / fastest FMU ({best}): {median[scipy_name] / median[best]:.0f} times the FMU's period, "
              f"{median[scipy_name] / best_with_setup:.0f} times with its set-up")
    else:
        print(f"scipy: no rtol tried reaches {target:g}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=lambda text: [float(v) for v in text.split(",")], default=[1e-6, 1e-9, 1e-12],
                        help="errors of the cradle's state after one period, comma-separated")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    build_fmus()
    wall, cradle = locate_fmu("WallPendulum"), locate_fmu("NewtonsCradle")
    print("1. The cost of an impact (wall pendulum, h = 1e-3 s, 10 s): extra evaluations per impact, in steps")
    print(f"{'method':18s} {'impacts':>7s} {'evals/step':>10s} {'extra evals':>11s} {'in steps':>8s}")
    methods = [m for m in FIXED_STEP if m != "gbs"]
    for method, impacts, per_step, extra in event_cost(wall, methods):
        note = ("  (history restarted)" if METHOD[method].family.startswith("adams") else
                "  (Newton's iterations vary with the state)" if METHOD[method].implicit else "")
        print(f"{method:18s} {impacts:7.0f} {per_step:10.2f} {extra:11.1f} {extra / per_step:8.1f}{note}")
    print(f"\n2. One period of the rigid cradle ({PERIOD:.4f} s) against scipy's solve_ivp with event functions")
    with FmuInstance(cradle) as fmu:
        prepare_reader(fmu)
        for target in args.targets:
            compare(fmu, target, args.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
