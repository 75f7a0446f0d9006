#!/usr/bin/env python3
"""What a harness command pays besides the FMUs' own work, each cost beside the way it was paid
before, measured in one run:

1. A command's imports (matplotlib, SymPy, scipy, fmpy and the harness) with the environment's
   bytecode against compiling them on import (where PYTHONDONTWRITEBYTECODE is set and nothing
   compiled them, every process did that).
2. The build check of `chart`, `plan` and `demo` when nothing changed: `cmake --build` alone against
   configure and build.
3. The SimplePendulum's predicted stability limits (the quick atlas): the scan as arrays against the
   scan point by point (and that both give the same limits, to the bit).
4. Runs of the coupled scene one after another, as the planner makes them: sharing each FMU's
   extraction and library (`SharedFmus`) against extracting and loading them for every run.

Usage: python benchmarks/harness_overhead.py [--repeats N] [--runs N]
"""
from __future__ import annotations

import argparse
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from harness.cosim.master import MasterOptions, run_system  # noqa: E402
from harness.cosim.system import load_system  # noqa: E402
from harness.fmi.fmu_instance import SharedFmus  # noqa: E402
from harness.fmi.fmus import build_dir, build_fmus, configured_cmake  # noqa: E402
from harness.studies import stability  # noqa: E402

IMPORTS = "import harness.cli, harness.studies.charts, matplotlib.pyplot, sympy, scipy.integrate, fmpy"


def median_seconds(run, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def side_by_side(label: str, now, before, repeats: int) -> None:
    """Interleaved, so that the machine's load falls on both alike."""
    pairs = [(median_seconds(now, 1), median_seconds(before, 1)) for _ in range(repeats)]
    new, old = statistics.median(p[0] for p in pairs), statistics.median(p[1] for p in pairs)
    print(f"{label}: {new:.3f} s against {old:.3f} s before, {old / new:.1f} times less")


def imports(repeats: int) -> None:
    python = [sys.executable, "-c", IMPORTS]
    with tempfile.TemporaryDirectory() as empty:  # a bytecode folder with nothing in it: compiled on import
        side_by_side("1. a command's imports, bytecode against compiled on import",
                     lambda: subprocess.run(python, check=True),
                     lambda: subprocess.run([sys.executable, "-X", f"pycache_prefix={empty}", "-B", *python[1:]],
                                            check=True), repeats)


def build_check(repeats: int) -> None:
    build_fmus()  # up to date first: both then check a build that has nothing to do
    cmake, folder = configured_cmake(build_dir()), str(build_dir())
    configure = [cmake, "-S", str(ROOT), "-B", folder, "-DCMAKE_BUILD_TYPE=Release",
                 f"-DOBJECTS_PYTHON={sys.executable}"]
    build = [cmake, "--build", folder, "-j2"]

    def run(*commands):
        for command in commands:
            subprocess.run(command, check=True, capture_output=True)
    side_by_side("2. the build check when nothing changed, build alone against configure and build",
                 lambda: run(build), lambda: run(configure, build), repeats)


def scan_point_by_point(table: dict, case) -> float:
    """The predicted limit as it was computed before: the scan one point at a time."""
    def stable(y: float) -> bool:
        g = stability.largest_growth(table, [y * lam for lam in case.eigenvalues])
        return 2 * (stability.PERIODS * 2 * math.pi / y) * math.log(max(g, 1e-300)) <= math.log(stability.GROWTH_LIMIT)
    y = 1e-6
    while stable(y * 1.02):
        y *= 1.02
        if y > 50:
            return math.inf
    low, high = y, y * 1.02
    for _ in range(60):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if stable(middle) else (low, middle)
    return low


def predicted_limits(repeats: int) -> None:
    tables = stability.atlas_tables()
    cases = stability.cases(build_dir() / "fmus", quick=True, objects=["SimplePendulum"])
    jobs = [(tables[m], c) for c in cases if c.linear for m in stability.ATLAS_METHODS]
    found: dict[str, list[float]] = {}
    side_by_side(f"3. the SimplePendulum's {len(jobs)} predicted stability limits (quick atlas), arrays against "
                 "point by point",
                 lambda: found.__setitem__("now", [stability.theory_limit(t, c) for t, c in jobs]),
                 lambda: found.__setitem__("before", [scan_point_by_point(t, c) for t, c in jobs]), repeats)
    same = sum(a == b for a, b in zip(found["now"], found["before"]))
    print(f"   the same limit to the bit: {same} of {len(jobs)}")


def shared_runs(runs: int, repeats: int) -> None:
    system = load_system(ROOT / "scenes" / "coupled_pendulums.json")
    options = MasterOptions(stop=1.0, step=0.01, algorithm="gauss-seidel", extrapolation="linear")

    def shared():
        with SharedFmus() as fmus:
            for _ in range(runs):
                run_system(system, options, fmus)

    def fresh():
        for _ in range(runs):
            run_system(system, options)
    side_by_side(f"4. {runs} runs of the coupled scene (3 FMUs, 1 s), sharing the FMUs against loading them each run",
                 shared, fresh, repeats)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5, help="interleaved pairs of measurements per cost")
    parser.add_argument("--runs", type=int, default=50, help="coupled runs per measurement (part 4)")
    args = parser.parse_args(argv)
    if args.repeats < 1 or args.runs < 1:
        parser.error("--repeats and --runs must be at least 1")
    imports(args.repeats)
    build_check(args.repeats)
    predicted_limits(args.repeats)
    shared_runs(args.runs, args.repeats)
    return 0


if __name__ == "__main__":
    sys.exit(main())
