#!/usr/bin/env python3
"""Large scenes: a chain of N SimplePendulums joined by N - 1 Springs (harness.scene.spring_scenes),
one FMU instance per component, for N = 10, 100 and 1000. Per N, measured in one run:

* start-up per instance: loading, instantiating and preparing the master's units, and initializing;
* memory per instance: the process's resident memory after start-up against before it;
* cost per component and macro step: Gauss-Seidel, linear extrapolation, H = 0.01 (the C loop), as
  the difference of the fastest runs of 2n and of n macro steps, each in a fresh process (so that the
  fixed costs of a run, initialization and the table, drop out), and its ratio to the smallest N's
  (flat: the cost grows linearly with N);
* the coupling error against the chain's derived monolithic reference, over the first seconds.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from harness.cosim.master import Master, MasterOptions  # noqa: E402
from harness.cosim.system import load_system  # noqa: E402
from harness.fmi.fmus import build_fmus  # noqa: E402
from harness.scene.spring_scenes import pendulum_chain  # noqa: E402
from harness.studies.coupling import coupling_error, derived_reference  # noqa: E402

STEP = 0.01
REPEATS = 5
COMPONENT_STEPS = 1_000_000  # per timed run at least: macro steps times instances


def resident_bytes() -> int:
    with open("/proc/self/statm") as handle:
        return int(handle.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def timed_run(scene: Path, steps: int) -> float:
    """Seconds of one master run of the scene (set-up not included)."""
    with load_system(scene) as system, Master(system, MasterOptions(stop=steps * STEP, step=STEP,
                                                                     algorithm="gauss-seidel",
                                                                     extrapolation="linear")) as master:
        start = time.perf_counter()
        master.run()
        return time.perf_counter() - start


def timed_run_in_a_process(scene: Path, steps: int) -> float:
    """`timed_run` in a fresh process: one scene per process, as a user runs it (a process that has
    made and freed thousands of instances before lays the next ones out differently in memory)."""
    result = subprocess.run([sys.executable, __file__, "--time-run", str(scene), str(steps)], capture_output=True,
                            text=True, check=True)
    return float(result.stdout.split()[-1])


def measure(n: int, steps: int, error_seconds: float, folder: Path, component_steps: int = COMPONENT_STEPS,
            repeats: int = REPEATS) -> dict:
    scene = folder / f"chain_{n}.json"
    scene.write_text(json.dumps(pendulum_chain(n)))
    system = load_system(scene)
    instances = len(system.components)
    def options(n_steps: int) -> MasterOptions:
        return MasterOptions(stop=n_steps * STEP, step=STEP, algorithm="gauss-seidel", extrapolation="linear")
    before, start = resident_bytes(), time.perf_counter()
    with Master(system, options(steps)) as master:
        master._initialize()
        startup = time.perf_counter() - start
        memory = resident_bytes() - before
    steps = max(steps, round(component_steps / instances))  # long enough to time for small N too
    seconds: dict[int, list[float]] = {steps: [], 2 * steps: []}
    for _ in range(repeats):
        for n_steps in seconds:
            seconds[n_steps].append(timed_run_in_a_process(scene, n_steps))
    # the fastest of each (the least disturbed by other work on a shared machine), then their difference
    cost = (min(seconds[2 * steps]) - min(seconds[steps])) / (steps * instances)
    error_options = MasterOptions(stop=error_seconds, step=STEP, algorithm="gauss-seidel", extrapolation="linear")
    with Master(system, error_options) as master:
        result = master.run()
    start = time.perf_counter()
    reference, pairs = derived_reference(system, result.time)
    reference_seconds = time.perf_counter() - start
    return dict(n=n, instances=instances, startup=startup / instances, memory=memory / instances, bytes=memory,
                cost=cost, error=coupling_error(result, reference, pairs),
                reference_seconds=reference_seconds)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 100, 1000])
    parser.add_argument("--steps", type=int, default=1000, help="macro steps per cost measurement")
    parser.add_argument("--error-seconds", type=float, default=2.0, help="simulated time of the error run")
    parser.add_argument("--component-steps", type=int, default=COMPONENT_STEPS,
                        help="per timed run at least: macro steps times instances")
    parser.add_argument("--repeats", type=int, default=REPEATS,
                        help="timed runs of each length, in processes of their own")
    parser.add_argument("--time-run", nargs=2, metavar=("SCENE", "STEPS"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.time_run:
        print(timed_run(Path(args.time_run[0]), int(args.time_run[1])))
        return 0
    build_fmus()
    with tempfile.TemporaryDirectory(prefix="chain_benchmark_") as folder:
        rows = [measure(n, args.steps, args.error_seconds, Path(folder), args.component_steps, args.repeats)
                for n in args.sizes]
    base = rows[0]["cost"]
    print(f"Chain of N pendulums and N - 1 springs, Gauss-Seidel, linear, H = {STEP} s; costs: the fastest of "
          f"{args.repeats} runs of 2n macro steps less the fastest of n (n at least {args.steps} and "
          f"{args.component_steps:.0e} / instances), each run in a process of its own")
    print(f"{'N':>6s} {'instances':>9s} {'start-up/instance':>18s} {'memory/instance':>16s} "
          f"{'us/(component step)':>20s} {'ratio to N=' + str(rows[0]['n']):>14s} "
          f"{'error [m] over ' + format(args.error_seconds, 'g') + ' s':>22s} {'reference [s]':>14s}")
    for r in rows:
        print(f"{r['n']:6d} {r['instances']:9d} {1e3 * r['startup']:15.3f} ms {r['memory'] / 1024:13.1f} KB "
              f"{1e6 * r['cost']:20.4f} {r['cost'] / base:14.2f} {r['error']:22.3e} {r['reference_seconds']:14.1f}")
    if len(rows) > 1:  # what one more instance adds, without what the first ones share (the library, the blocks)
        first, last = rows[0], rows[-1]
        print(f"memory per added instance from N = {first['n']} to {last['n']}: "
              f"{(last['bytes'] - first['bytes']) / (last['instances'] - first['instances']) / 1024:.1f} KB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
