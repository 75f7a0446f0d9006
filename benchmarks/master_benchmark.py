#!/usr/bin/env python3
"""Cost per macro step of co-simulating the coupled-pendulums scene (spring + two pendulums, one
internal RK4 step per macro step), measured side by side in one run and reported as ratios:
the harness's master against a plain fmpy loop (list API), libcosim, ecos and a native C loop."""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from fmpy import extract, read_model_description  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402

from harness.cosim.master import Master, MasterOptions  # noqa: E402
from harness.cosim.system import load_system  # noqa: E402
from harness.fmi.fmus import build_dir, build_fmus  # noqa: E402

STEP = 0.001
SCENE = ROOT / "scenes" / "coupled_pendulums.json"


# extracted FMUs: removed with this folder when the benchmark exits
SCRATCH = tempfile.TemporaryDirectory(prefix="benchmark_")

def harness_cost(steps: int, algorithm: str, extrapolation: str) -> float:
    system = load_system(SCENE)
    with Master(system, MasterOptions(stop=steps * STEP, step=STEP, algorithm=algorithm,
                                      extrapolation=extrapolation)) as master:
        start = time.perf_counter()
        master.run()
        return (time.perf_counter() - start) / steps


def plain_fmpy_cost(steps: int) -> float:
    """What an fmpy user writes by hand: FMU2Slave, setReal/getReal with lists, Jacobi, inputs held."""
    paths = {"spring": build_dir() / "fmus" / "Spring.fmu", "pendulum": build_dir() / "fmus" / "SimplePendulum.fmu"}
    descriptions = {k: read_model_description(str(p)) for k, p in paths.items()}
    unzipped = {k: extract(str(p), unzipdir=tempfile.mkdtemp(dir=SCRATCH.name)) for k, p in paths.items()}
    vr = {k: {v.name: v.valueReference for v in md.modelVariables} for k, md in descriptions.items()}
    slaves = {}
    for name, kind in (("spring", "spring"), ("left", "pendulum"), ("right", "pendulum")):
        slave = FMU2Slave(guid=descriptions[kind].guid, unzipDirectory=unzipped[kind],
                          modelIdentifier=descriptions[kind].coSimulation.modelIdentifier, instanceName=name)
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slaves[name] = slave
    p, s = vr["pendulum"], vr["spring"]
    slaves["spring"].setReal([s["k"], s["l0"]], [10.0, 1.5])
    slaves["left"].setReal([p["phi"], p["h"]], [0.5, 0.001])
    slaves["right"].setReal([p["phi"], p["anchor_x"], p["h"]], [0.0, 1.5, 0.001])
    for slave in slaves.values():
        slave.enterInitializationMode()
        slave.exitInitializationMode()
    bob = [p["x"], p["y"], p["v_x"], p["v_y"]]
    ends = [s[n] for n in ("a_x", "a_y", "a_vx", "a_vy", "b_x", "b_y", "b_vx", "b_vy")]
    forces = [s[n] for n in ("Fa_x", "Fa_y", "Fb_x", "Fb_y")]
    force_inputs = [p["F_x"], p["F_y"]]
    left, right, spring = slaves["left"], slaves["right"], slaves["spring"]
    left_out, right_out, spring_out = left.getReal(bob), right.getReal(bob), spring.getReal(forces)
    start = time.perf_counter()
    for k in range(steps):
        t = k * STEP
        spring.setReal(ends, left_out + right_out)
        left.setReal(force_inputs, spring_out[:2])
        right.setReal(force_inputs, spring_out[2:])
        spring.doStep(t, STEP)
        left.doStep(t, STEP)
        right.doStep(t, STEP)
        spring_out, left_out, right_out = spring.getReal(forces), left.getReal(bob), right.getReal(bob)
    elapsed = time.perf_counter() - start
    for slave in slaves.values():
        slave.terminate()
        slave.freeInstance()
    return elapsed / steps


def peer_cost(peer: str, steps: int) -> float | None:
    ssp = build_dir() / "scenes" / "coupled_pendulums.ssp"
    # ecos extracts the SSP into the temporary folder and leaves it there: give it one that goes
    with tempfile.TemporaryDirectory(prefix="peer_") as scratch:
        result = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "peer_step_cost.py"), peer, str(ssp),
                                 str(STEP), str(steps)], capture_output=True, text=True,
                                env={**os.environ, "TMPDIR": scratch})
    lines = [line for line in result.stdout.splitlines() if line.startswith("RESULT")]
    return float(lines[-1].split()[1]) if result.returncode == 0 and lines else None


def native_cost(steps: int, recording: bool = False) -> float:
    """The plain C loop; `recording`: with the calls of a master that records every output (one get
    of each unit's float outputs and one of its integers per step, written into a table)."""
    pendulum = read_model_description(str(build_dir() / "fmus" / "SimplePendulum.fmu"))
    spring = read_model_description(str(build_dir() / "fmus" / "Spring.fmu"))
    p = {v.name: v.valueReference for v in pendulum.modelVariables}
    s = {v.name: v.valueReference for v in spring.modelVariables}
    vrs = [p[n] for n in ("x", "y", "v_x", "v_y", "F_x", "F_y", "phi", "anchor_x", "h")] + \
          [s[n] for n in ("a_x", "a_y", "a_vx", "a_vy", "b_x", "b_y", "b_vx", "b_vy", "Fa_x", "Fa_y", "Fb_x", "Fb_y",
                          "k", "l0")]
    command = [str(build_dir() / "bin" / "coupled_native"),
               str(build_dir() / "lib" / "SimplePendulum" / "SimplePendulum.so"), pendulum.guid,
               str(build_dir() / "lib" / "Spring" / "Spring.so"), spring.guid, str(steps), str(STEP)] + \
              [str(v) for v in vrs]
    if recording:
        command += ["record"] + _recorded(pendulum, ("x", "y", "v_x", "v_y"), integers=True) + \
            _recorded(spring, ("Fa_x", "Fa_y", "Fb_x", "Fb_y"), integers=False)
    return float(subprocess.run(command, check=True, capture_output=True, text=True).stdout.split()[0])


def _recorded(description, routed: tuple[str, ...], integers: bool) -> list[str]:
    """coupled_native's `record` arguments for one FMU: its float outputs, where the routed ones are
    among them, and (for a pendulum) its integer outputs, in the order the harness records them."""
    outputs = [v for v in description.modelVariables if v.causality == "output"]
    floats = [v for v in outputs if v.type == "Real"]
    names = [v.name for v in floats]
    arguments = [len(floats)] + [v.valueReference for v in floats]
    if integers:
        ints = [v for v in outputs if v.type in ("Integer", "Enumeration")]
        arguments += [names.index(n) for n in routed] + [len(ints)] + [v.valueReference for v in ints]
    else:
        arguments += [names.index(n) for n in routed]
    return [str(a) for a in arguments]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20000, help="macro steps per measurement")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved repeats; medians are reported")
    args = parser.parse_args()
    build_fmus()
    runs = {
        "harness jacobi/hold": lambda: harness_cost(args.steps, "jacobi", "hold"),
        "harness gauss-seidel/linear": lambda: harness_cost(args.steps, "gauss-seidel", "linear"),
        "plain fmpy loop (jacobi/hold)": lambda: plain_fmpy_cost(args.steps),
        "libcosim (jacobi/hold)": lambda: peer_cost("libcosim", args.steps),
        "ecos (jacobi/hold)": lambda: peer_cost("ecos", args.steps),
        "native C loop (jacobi/hold)": lambda: native_cost(args.steps),
        "native C loop, same calls": lambda: native_cost(args.steps, recording=True),
    }
    samples: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(args.rounds):
        for name, run in runs.items():
            cost = run()
            if cost is not None:
                samples[name].append(cost)
    cost = {name: statistics.median(values) for name, values in samples.items() if values}
    reference = cost["harness jacobi/hold"]
    print(f"Coupled pendulums, {args.steps} macro steps of {STEP} s, median of {args.rounds} interleaved rounds")
    print(f"{'runner':32s} {'us/macro step':>14s} {'harness jacobi/hold / runner':>30s}")
    for name in runs:
        if name in cost:
            print(f"{name:32s} {1e6 * cost[name]:14.2f} {reference / cost[name]:30.2f}")
        else:
            print(f"{name:32s} {'not available':>14s}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
