#!/usr/bin/env python3
"""Benchmarks of the FMUs, as ratios measured side by side in one run, plus machine-independent
counts (instructions under callgrind, right-hand-side evaluations).

1. Cost of one internal RK4 step inside fmi2DoStep against a bare C loop of the same right-hand side
   (benchmarks/rk4_overhead.c): time ratio (median of interleaved repeats) and instruction ratio.
2. Right-hand-side evaluations per accepted step for every method.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from harness.fmu_instance import FmuInstance  # noqa: E402
from harness.fmus import build_dir, build_fmus  # noqa: E402

PENDULUMS = ("SimplePendulum", "DoublePendulum", "SpringPendulum")
SOLVERS = ("euler", "midpoint", "heun", "rk3", "rk4", "rkf45", "nystrom5", "ab2", "ab3", "ab4", "ab5", "ab6")


def bench(model: str, mode: str, steps: int, valgrind: bool = False) -> str:
    command = [str(build_dir() / "bin" / f"bench_{model}"), str(build_dir() / "lib" / model / f"{model}.so"), mode,
               str(steps)]
    if valgrind:
        out = Path(f"/tmp/callgrind.{model}.{mode}.{steps}")
        subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}"] + command, check=True,
                       capture_output=True)
        summary = next(line for line in out.read_text().splitlines() if line.startswith(("summary:", "totals:")))
        out.unlink()
        return summary.split()[1]
    return subprocess.run(command, check=True, capture_output=True, text=True).stdout


def instructions_per_step(model: str, mode: str, steps: int) -> float:
    """Difference of two runs (steps and 2 steps) removes the setup's instructions."""
    return (int(bench(model, mode, 2 * steps, True)) - int(bench(model, mode, steps, True))) / steps


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2_000_000, help="internal steps per timed run")
    parser.add_argument("--callgrind-steps", type=int, default=100_000)
    args = parser.parse_args()
    build_fmus()

    print("1. One internal RK4 step inside fmi2DoStep vs a bare C loop of the same right-hand side")
    use_valgrind = shutil.which("valgrind") is not None
    print(f"{'model':16s} {'FMU ns/step':>12s} {'bare ns/step':>13s} {'time ratio':>11s}"
          + (f" {'FMU instr':>10s} {'bare instr':>11s} {'instr ratio':>12s}" if use_valgrind else ""))
    for model in PENDULUMS:
        timing = json.loads(bench(model, "both", args.steps))
        line = (f"{model:16s} {timing['fmu_ns_per_step']:12.1f} {timing['bare_ns_per_step']:13.1f} "
                f"{timing['median_ratio']:11.3f}")
        if use_valgrind:
            fmu = instructions_per_step(model, "fmu", args.callgrind_steps)
            bare = instructions_per_step(model, "bare", args.callgrind_steps)
            line += f" {fmu:10.1f} {bare:11.1f} {fmu / bare:12.3f}"
        print(line)
    if not use_valgrind:
        print("(valgrind not found: instruction counts skipped)")

    print("\n2. Right-hand-side evaluations per accepted step (DoublePendulum, 10 s, h = 0.01, tol = 1e-6)")
    print(f"{'solver':10s} {'n_rhs':>8s} {'n_steps':>8s} {'n_rejected':>10s} {'rhs/step':>9s}")
    fmu_path = build_dir() / "fmus" / "DoublePendulum.fmu"
    for solver in SOLVERS:
        with FmuInstance(fmu_path) as fmu:
            fmu.initialize(solver=solver, h=0.01, tol=1e-6)
            for i in range(100):
                fmu.do_step(i * 0.1, 0.1)
            n_rhs, n_steps, n_rejected = fmu.get("n_rhs", "n_steps", "n_rejected")
        print(f"{solver:10s} {n_rhs:8d} {n_steps:8d} {n_rejected:10d} {n_rhs / n_steps:9.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
