"""Runs an SSP in ecos (ecospy) and prints the bobs' positions per step as JSON (child process)."""
import json
import sys

from ecospy import EcosSimulation

ssp, step, steps, parameter_set = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
rows = []
with EcosSimulation(ssp_path=ssp, step_size=step) as simulation:
    simulation.init(parameter_set=parameter_set)  # ecos applies parameter sets by name, when asked
    for _ in range(steps):
        simulation.step()
        rows.append([simulation.get_real(f"{name}::{q}") for name in ("left", "right") for q in ("x", "y")])
print(json.dumps(rows))
