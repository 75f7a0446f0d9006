#!/usr/bin/env python3
"""Time to keep the simple pendulum's bob within 1e-11 m of the exact elliptic solution at t = 10 s
in one fmi2DoStep, each method at its cheapest setting, measured side by side.

For each fixed-step method the setting that meets the target with the fewest right-hand-side
evaluations (n_rhs plus the implicit methods' Jacobian columns) is searched first, among internal
steps 10 s / n and, for rkf45 and gbs, tolerances (gbs also with its fixed step at every column);
for taylor every even order from 6 to 30 with its fixed step (tol = 0) and with its step chosen for
tol, the fastest of those that meet the target (its cost per step grows with the square of the
order, its evaluations, one per coefficient order, only with the order). Then all are timed,
interleaved, median of repeats. scipy's DOP853 on the same equations in Python
(harness.objects.thesis.equations) is timed beside them at its loosest rtol = atol
that meets the target.

Prints the table, each method's time as a multiple of the Taylor method's, and the evaluations.
"""
from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from scipy.integrate import solve_ivp  # noqa: E402

from harness.fmi.fmu_instance import FmuInstance  # noqa: E402
from harness.fmi.fmus import build_dir, build_fmus  # noqa: E402
from harness.fmi.methods import ADAPTIVE, FIXED_STEP, GBS_COLUMNS, SOLVERS, TAYLOR_ORDERS  # noqa: E402
from harness.objects.thesis.equations import Pendulum  # noqa: E402
from harness.objects.thesis.reference import exact_simple_pendulum  # noqa: E402

STOP = 10.0
TARGET = 1e-11  # metres
PHI0 = 0.5      # the FMU's default start (rad)
# the methods the FMUs had before the Taylor method and its companions, whose items were appended after them
EARLIER = SOLVERS[:SOLVERS.index("abm2")]


@dataclass
class Setting:
    method: str
    settings: dict
    error: float
    evaluations: int
    seconds: float = math.nan

    def label(self) -> str:
        return ", ".join(f"{k} = {v:g}" for k, v in self.settings.items() if k != "solver")


def exact_bob() -> np.ndarray:
    phi, _ = exact_simple_pendulum(PHI0, np.array([STOP]))
    return np.array([math.sin(phi[0]), -math.cos(phi[0])])  # L = 1 m, pivot at the origin


def run_once(fmu: FmuInstance, settings: dict) -> tuple[float, int]:
    fmu.reset()
    fmu.initialize(**settings)
    if fmu.do_step(0.0, STOP) != 0:
        return math.inf, 0
    error = float(np.hypot(*(np.array(fmu.get("x", "y")) - exact_bob())))
    return error, fmu.work()


def cheapest(fmu: FmuInstance, method: str) -> Setting | None:
    candidates = []
    if method == "taylor":
        for order in range(6, TAYLOR_ORDERS[1] + 1, 2):
            candidates += [{"solver": "taylor", "taylor_order": order, "tol": 0.0, "h": STOP / n}
                           for n in np.unique(np.geomspace(1, 4000, 60).astype(int))]
            candidates += [{"solver": "taylor", "taylor_order": order, "tol": tol}
                           for tol in np.geomspace(1e-6, 1e-16, 41)]
    elif method in ADAPTIVE:
        candidates = [{"solver": method, "tol": tol} for tol in np.geomspace(1e-6, 1e-14, 33)]
        if method == "gbs":  # and its fixed step at every column
            candidates += [{"solver": "gbs", "gbs_columns": columns, "tol": 0.0, "h": STOP / n}
                           for columns in range(2, GBS_COLUMNS + 1)
                           for n in np.unique(np.geomspace(1, 4000, 60).astype(int))]
    else:
        candidates = [{"solver": method, "h": STOP / n} for n in np.unique(np.geomspace(10, 2e5, 120).astype(int))]
    meeting = []
    for settings in candidates:
        error, evaluations = run_once(fmu, settings)
        if error <= TARGET:
            meeting.append(Setting(method, settings, error, evaluations))
    if not meeting or method != "taylor":
        return min(meeting, key=lambda s: s.evaluations, default=None)
    # a Taylor step of order p costs about p^2 / 2 operations for its p "evaluations": the fastest
    # setting, not the one with fewest evaluations, is its cheapest
    return min(meeting, key=lambda s: quick_time(fmu, s.settings))


def quick_time(fmu: FmuInstance, settings: dict, repeats: int = 5) -> float:
    times = []
    for _ in range(repeats):
        fmu.reset()
        fmu.initialize(**settings)
        start = time.perf_counter()
        fmu.do_step(0.0, STOP)
        times.append(time.perf_counter() - start)
    return min(times)


def dop853() -> Setting:
    pendulum = Pendulum.from_fmu(str(build_dir() / "fmus" / "SimplePendulum.fmu"))
    counter = {"n": 0}

    def rhs(t, y):
        counter["n"] += 1
        return pendulum.rhs(t, y)
    best = None
    for tol in np.geomspace(1e-8, 1e-15, 29):
        counter["n"] = 0
        solution = solve_ivp(rhs, (0.0, STOP), pendulum.start, method="DOP853", rtol=tol, atol=tol)
        phi = solution.y[0, -1]
        error = float(np.hypot(math.sin(phi) - exact_bob()[0], -math.cos(phi) - exact_bob()[1]))
        if error <= TARGET:
            best = Setting("scipy-DOP853", {"rtol = atol": tol}, error, counter["n"])
            best.run = lambda tol=tol: solve_ivp(pendulum.rhs, (0.0, STOP), pendulum.start, method="DOP853",
                                                 rtol=tol, atol=tol)
            break
    return best


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    build_fmus()
    path = build_dir() / "fmus" / "SimplePendulum.fmu"
    methods = [*FIXED_STEP, *ADAPTIVE, "taylor"]
    with FmuInstance(path) as fmu:
        found = [s for s in (cheapest(fmu, m) for m in methods) if s is not None]
        timings = {id(s): [] for s in found}
        for _ in range(args.repeats):  # interleaved: the machine's load falls on every method alike
            for s in found:
                fmu.reset()
                fmu.initialize(**s.settings)
                start = time.perf_counter()
                fmu.do_step(0.0, STOP)
                timings[id(s)].append(time.perf_counter() - start)
    for s in found:
        s.seconds = statistics.median(timings[id(s)])
    peer = dop853()
    peer_times = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        peer.run()
        peer_times.append(time.perf_counter() - start)
    peer.seconds = statistics.median(peer_times)
    taylor = next(s for s in found if s.method == "taylor")
    print(f"Bob within {TARGET:g} m of the exact solution at t = {STOP:g} s, one fmi2DoStep "
          f"(median of {args.repeats}, interleaved)")
    print(f"{'method':>18} {'cheapest setting':>38} {'error [m]':>10} {'evaluations':>12} {'time':>10} {'/ taylor':>9}")
    for s in sorted(found + [peer], key=lambda s: s.seconds):
        print(f"{s.method:>18} {s.label():>38} {s.error:10.1e} {s.evaluations:12d} {s.seconds * 1e6:8.1f} us"
              f" {s.seconds / taylor.seconds:9.1f}")
    missing = [m for m in methods if m not in {s.method for s in found}]
    if missing:
        print(f"not within {TARGET:g} m at any searched setting: {', '.join(missing)}")
    fastest_other = min((s for s in found if s.method != "taylor"), key=lambda s: s.seconds)
    fastest_earlier = min((s for s in found if s.method in EARLIER), key=lambda s: s.seconds)
    print(f"taylor is {fastest_earlier.seconds / taylor.seconds:.1f} times faster than the fastest of the earlier "
          f"methods ({fastest_earlier.method}), {fastest_other.seconds / taylor.seconds:.1f} times faster than the "
          f"fastest other method ({fastest_other.method}) and {peer.seconds / taylor.seconds:.0f} times faster than "
          f"scipy's DOP853")
    return 0


if __name__ == "__main__":
    sys.exit(main())
