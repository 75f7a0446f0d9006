#!/usr/bin/env python3
"""Energy-conserving coupling against fixed-step Gauss-Seidel with linear extrapolation at equal cost.

For each scene and energy tolerance: the PI energy control (with and without the correction) chooses
its macro steps; fixed-step Gauss-Seidel then runs with as many macro steps (equal fmi2DoStep calls),
with and without the correction. Reported: macro steps, the largest point error against the scene's
derived monolithic reference, and the energy drift (largest |E_total(t) - E_total(0)|)."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from harness.cosim.master import MasterOptions, run_system  # noqa: E402
from harness.cosim.system import load_system  # noqa: E402
from harness.fmi.fmus import build_fmus  # noqa: E402
from harness.studies.coupling import coupling_error, derived_reference  # noqa: E402

SCENES = ("coupled_pendulums.json", "double_and_cart.json", "spring_chain.json")
OUTPUT = 0.04  # output interval [s]: the energy control's largest macro step


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop", type=float, default=10.0)
    parser.add_argument("--tolerances", type=float, nargs="+", default=[0.1, 0.03, 0.01])
    args = parser.parse_args()
    build_fmus()
    print(f"{args.stop:g} s, Gauss-Seidel, linear extrapolation; rows every {OUTPUT} s")
    print(f"{'scene':24s} {'run':34s} {'macro steps':>11s} {'error [m]':>10s} {'drift [J]':>10s}")
    for name in SCENES:
        with load_system(ROOT / "scenes" / name) as system:
            reference = derived_reference(system, np.arange(round(args.stop / OUTPUT) + 1) * OUTPUT)

            def report(label: str, **options) -> int:
                result = run_system(system, MasterOptions(stop=args.stop, algorithm="gauss-seidel",
                                                          extrapolation="linear", **options))
                every = round(OUTPUT / options["step"])
                rows = result.time[::every]
                assert np.allclose(rows, reference[0]["time"])
                kept = type(result)(result.columns, result.values[::every], result.energy[::every])
                print(f"{name:24s} {label:34s} {result.macro_steps:11d} {coupling_error(kept, *reference):10.3e} "
                      f"{result.energy_residual:10.3e}")
                return result.macro_steps
            for tolerance in args.tolerances:
                steps = report(f"energy control {tolerance:g} J", step=OUTPUT, energy_tol=tolerance)
                report(f"energy control {tolerance:g} J, corrected", step=OUTPUT, energy_tol=tolerance,
                       energy_correction=True)
                # the fixed step with as many macro steps, on a grid that holds the output rows
                per_row = max(1, round(steps * OUTPUT / args.stop))
                report(f"fixed H = {OUTPUT / per_row:.3g} s", step=OUTPUT / per_row)
                report(f"fixed H = {OUTPUT / per_row:.3g} s, corrected", step=OUTPUT / per_row,
                       energy_correction=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
