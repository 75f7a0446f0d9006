#!/usr/bin/env python3
"""Benchmarks of the FMUs, as ratios measured side by side in one run, plus machine-independent
counts (instructions under callgrind, right-hand-side evaluations).

1. Cost of one internal RK4 step inside fmi2DoStep (all steps in one call) against textbook RK4
   loops in plain C (benchmarks/rk4_overhead.c): over the generated right-hand side, and over a
   hand-written one (benchmarks/handwritten_rhs.h). Time ratios are medians of interleaved repeats;
   instructions per step come from callgrind, for every object against the generated loop and for
   the thesis pendulums against the hand-written one. The goal: at most 1.05 times the instructions
   of the hand-written loop.
2. Right-hand-side evaluations per accepted step for every method.
3. Agreement of the generated thesis pendulums with the hand-written FMUs they replaced
   (benchmarks/agreement_with_handwritten.py).
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from harness.fmi.fmu_instance import FmuInstance, accepted_methods  # noqa: E402
from harness.fmi.fmus import build_dir, build_fmus  # noqa: E402
from harness.objects.registry import constrained_names, object_names  # noqa: E402

import agreement_with_handwritten  # noqa: E402  (beside this file)

# The objects with a hand-written right-hand side in benchmarks/handwritten_rhs.h.
PENDULUMS = ("SimplePendulum", "DoublePendulum", "SpringPendulum")
INSTRUCTION_GOAL = 1.05  # FMU instructions per internal step / hand-written loop's
MODES = ("fmu", "generated", "bare")  # bare: the hand-written right-hand side


def bench_command(model: str, mode: str, count: int) -> list[str]:
    return [str(build_dir() / "bin" / f"bench_{model}"), str(build_dir() / "lib" / model / f"{model}.so"), mode,
            str(count)]


def run_bench(model: str, mode: str, count: int) -> str:
    result = subprocess.run(bench_command(model, mode, count), capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(f"bench_{model} {mode} {count} failed (exit code {result.returncode}): "
                         f"{result.stderr.strip() or result.stdout.strip()}")
    return result.stdout


def instructions(model: str, mode: str, steps: int) -> int:
    """Instructions of one whole run of the bench program under callgrind."""
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "callgrind.out"
        subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}"]
                       + bench_command(model, mode, steps), check=True, capture_output=True)
        summary = next(line for line in out.read_text().splitlines() if line.startswith(("summary:", "totals:")))
    return int(summary.split()[1])


def instructions_per_step(model: str, mode: str, steps: int) -> float:
    """Difference of two runs (steps and 2 steps) removes the setup's instructions."""
    return (instructions(model, mode, 2 * steps) - instructions(model, mode, steps)) / steps


def step_cost(args: argparse.Namespace) -> None:
    print("1. One internal RK4 step: the FMU (fmi2DoStep, all steps in one call) against textbook RK4 loops in C\n"
          "   over the generated right-hand side (generated) and over a hand-written one (hand); no force acts")
    for model in PENDULUMS:
        print(f"   {model}: {run_bench(model, 'check', 10_000).split(': ', 1)[1].strip()}")
    print(f"\n{'model':16s} {'FMU ns':>8s} {'gen ns':>8s} {'hand ns':>8s} {'FMU/gen':>8s} {'FMU/hand':>9s}"
          "   (time per step: medians of 9 interleaved repeats)")
    for model in PENDULUMS:
        timing = json.loads(run_bench(model, "both", args.steps))
        print(f"{model:16s} {timing['fmu_ns_per_step']:8.1f} {timing['generated_ns_per_step']:8.1f} "
              f"{timing['bare_ns_per_step']:8.1f} {timing['fmu_to_generated']:8.3f} {timing['fmu_to_bare']:9.3f}")

    if shutil.which("valgrind") is None:
        print("(valgrind not found: instruction counts skipped)")
        return
    print(f"\n{'model':22s} {'FMU instr':>10s} {'gen instr':>10s} {'hand instr':>11s} {'FMU/gen':>8s} {'FMU/hand':>9s}"
          f"   (instructions per step, callgrind; goal FMU/hand <= {INSTRUCTION_GOAL:.2f})")
    # the hand-written loop exists for the thesis pendulums only; objects with constraints are left out: the
    # textbook loops locate no events, so they would not do the FMU's work (benchmarks/event_benchmark.py)
    for model in args.callgrind_objects or [m for m in object_names() if m not in constrained_names()]:
        fmu, generated = (instructions_per_step(model, mode, args.callgrind_steps) for mode in MODES[:2])
        if model in PENDULUMS:
            hand = instructions_per_step(model, "bare", args.callgrind_steps)
            ratio = fmu / hand
            verdict = "PASS" if ratio <= INSTRUCTION_GOAL else "over"
            print(f"{model:22s} {fmu:10.1f} {generated:10.1f} {hand:11.1f} {fmu / generated:8.3f} {ratio:9.3f}   "
                  f"{verdict}")
        else:
            print(f"{model:22s} {fmu:10.1f} {generated:10.1f} {'-':>11s} {fmu / generated:8.3f} {'-':>9s}")


def evaluations_per_step() -> None:
    print("\n2. Right-hand-side evaluations per accepted step (DoublePendulum, 10 s, h = 0.01, tol = 1e-6)")
    print(f"{'solver':18s} {'n_rhs':>8s} {'n_steps':>8s} {'n_rejected':>10s} {'n_jacobians':>11s} "
          f"{'n_iterations':>12s} {'rhs/step':>9s}")
    fmu_path = build_dir() / "fmus" / "DoublePendulum.fmu"
    for solver in accepted_methods(str(fmu_path)):  # stormer_verlet: the simple pendulum's only
        with FmuInstance(fmu_path) as fmu:
            fmu.initialize(solver=solver, h=0.01, tol=1e-6)
            for i in range(100):
                fmu.do_step(i * 0.1, 0.1)
            counts = fmu.get("n_rhs", "n_steps", "n_rejected", "n_jacobians", "n_iterations")
        print(f"{solver:18s} {counts[0]:8d} {counts[1]:8d} {counts[2]:10d} {counts[3]:11d} {counts[4]:12d} "
              f"{counts[0] / counts[1]:9.3f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2_000_000, help="internal steps per timed run")
    parser.add_argument("--callgrind-steps", type=int, default=100_000)
    parser.add_argument("--no-agreement", action="store_true", help="skip section 3 (it rebuilds the old FMUs)")
    parser.add_argument("--callgrind-objects", type=lambda text: text.split(","), default=None,
                        help="the objects counted under callgrind, comma-separated (default: every object without "
                             "constraints)")
    args = parser.parse_args()
    countable = [m for m in object_names() if m not in constrained_names()]
    for name in args.callgrind_objects or []:
        if name not in countable:
            parser.error(f"--callgrind-objects: {name!r} is not one of {', '.join(countable)}")
    build_fmus()
    step_cost(args)
    evaluations_per_step()
    if not args.no_agreement:
        print("\n3. ", end="")
        return agreement_with_handwritten.agreement()
    return 0


if __name__ == "__main__":
    sys.exit(main())
