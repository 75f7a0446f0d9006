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
3. A recorded point against the internal step it holds, where the communication step is the internal
   step (benchmarks/record_cost.c): one fmi2DoStep and one fmi2GetReal of every Real output per point
   through the harness's C recorder, against the same steps inside one fmi2DoStep. The goal: a point at
   most twice the step's instructions. Beside it the same steps inside one fmi3DoStep, each reported
   through FMI 3.0's intermediate-update callback and its outputs read there: the standard's way to
   record every internal step without a call per step.
4. Agreement of the generated thesis pendulums with the hand-written FMUs they replaced
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

from fmpy import read_model_description  # noqa: E402

from harness.fmi.fmu_instance import FmuInstance, accepted_methods  # noqa: E402
from harness.fmi.methods import SOLVERS  # noqa: E402
from harness.fmi.fmus import build_dir, build_fmus  # noqa: E402
from harness.objects.registry import constrained_names, object_names  # noqa: E402

import agreement_with_handwritten  # noqa: E402  (beside this file)

# The objects with a hand-written right-hand side in benchmarks/handwritten_rhs.h.
PENDULUMS = ("SimplePendulum", "DoublePendulum", "SpringPendulum")
INSTRUCTION_GOAL = 1.05  # FMU instructions per internal step / hand-written loop's
MODES = ("fmu", "generated", "bare")  # bare: the hand-written right-hand side
RECORD_GOAL = 2.0  # instructions of a recorded point / of the internal step it holds
RECORDED_METHODS = ("ab5", "rk4")  # one evaluation per step, and four


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


def record_command(model: str, method: str, mode: str, count: int) -> list[str]:
    """benchmarks/record_cost.c on the object's FMI 2.0 binary (and its FMI 3.0 binary for the reported steps) at its
    default h, every Real output recorded."""
    description = read_model_description(str(build_dir() / "fmus" / f"{model}.fmu"))
    variables = {v.name: v for v in description.modelVariables}
    outputs = [v.valueReference for v in description.modelVariables if v.causality == "output" and v.type == "Real"]
    return [str(build_dir() / "bin" / "record_cost"), str(build_dir() / "lib" / model / f"{model}.so"),
            description.guid, str(variables["solver"].valueReference), str(SOLVERS.index(method) + 1),
            str(variables["h"].valueReference), variables["h"].start, ",".join(map(str, outputs)), mode, str(count),
            str(build_dir() / "lib" / "fmi3" / model / f"{model}.so")]


def record_instructions(model: str, method: str, mode: str, count: int) -> float:
    """Instructions per step or point: the difference of runs of count and 2 count removes the set-up's."""
    runs = []
    for n in (count, 2 * count):
        with tempfile.TemporaryDirectory() as folder:
            out = Path(folder) / "callgrind.out"
            subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}"]
                           + record_command(model, method, mode, n), check=True, capture_output=True)
            runs.append(int(next(line for line in out.read_text().splitlines()
                                 if line.startswith(("summary:", "totals:"))).split()[1]))
    return (runs[1] - runs[0]) / count


def recorded_points(args: argparse.Namespace) -> None:
    print("\n3. A recorded point (one fmi2DoStep of one internal step and one fmi2GetReal of every Real output, "
          "through the\n   harness's C recorder) and a reported step (one fmi3DoStep of many internal steps, each "
          "reported through the\n   intermediate-update callback, which reads every Real output with fmi3GetFloat64) "
          "against the internal step\n   (inside one fmi2DoStep); default h. Ratios to the step; goal: a recorded "
          f"point <= {RECORD_GOAL:.0f} steps in instructions")
    print(f"{'object':22s} {'method':6s} {'step ns':>8s} {'point':>7s} {'ratio':>6s} {'reported':>9s} {'ratio':>6s} "
          f"{'step instr':>11s} {'point':>7s} {'ratio':>6s} {'reported':>9s} {'ratio':>6s}")
    for model, method in ((m, method) for m in args.recorded_objects for method in RECORDED_METHODS):
        result = subprocess.run(record_command(model, method, "both", args.record_points), capture_output=True,
                                text=True)
        if result.returncode != 0:
            raise SystemExit(f"record_cost {model} {method} failed: {result.stderr.strip()}")
        timing = json.loads(result.stdout)
        line = (f"{model:22s} {method:6s} {timing['ns_per_step']:8.1f} {timing['ns_per_point']:7.1f} "
                f"{timing['point_to_step']:6.2f} {timing['ns_per_reported']:9.1f} {timing['reported_to_step']:6.2f}")
        if shutil.which("valgrind") is None:
            print(line + "   (valgrind not found: instruction counts skipped)")
            continue
        step, point, reported = (record_instructions(model, method, mode, args.callgrind_points)
                                 for mode in ("steps", "record", "reported"))
        print(f"{line} {step:11.1f} {point:7.0f} {point / step:6.2f} {reported:9.0f} {reported / step:6.2f}   "
              f"{'PASS' if point / step <= RECORD_GOAL else 'over'}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2_000_000, help="internal steps per timed run")
    parser.add_argument("--callgrind-steps", type=int, default=100_000)
    parser.add_argument("--record-points", type=int, default=500_000, help="recorded points per timed run")
    parser.add_argument("--callgrind-points", type=int, default=20_000)
    parser.add_argument("--no-agreement", action="store_true", help="skip section 4 (it rebuilds the old FMUs)")
    parser.add_argument("--callgrind-objects", type=lambda text: text.split(","), default=None,
                        help="the objects counted under callgrind, comma-separated (default: every object without "
                             "constraints)")
    parser.add_argument("--recorded-objects", type=lambda text: text.split(","), default=None,
                        help="the objects of section 3, comma-separated (default: every object without constraints)")
    args = parser.parse_args()
    countable = [m for m in object_names() if m not in constrained_names()]
    for option in ("callgrind_objects", "recorded_objects"):
        for name in getattr(args, option) or []:
            if name not in countable:
                parser.error(f"--{option.replace('_', '-')}: {name!r} is not one of {', '.join(countable)}")
    args.recorded_objects = args.recorded_objects or countable
    build_fmus()
    step_cost(args)
    evaluations_per_step()
    recorded_points(args)
    if not args.no_agreement:
        print("\n4. ", end="")
        return agreement_with_handwritten.agreement()
    return 0


if __name__ == "__main__":
    sys.exit(main())
