"""Runs an SSP in ecos (ecospy) and prints the named outputs per step as JSON (child process).

    run_ecos.py SSP STEP STEPS PARAMETER_SET COMPONENT.VARIABLE..."""
import json
import sys

from ecospy import EcosSimulation

ssp, step, steps, parameter_set = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
recorded = [name.replace(".", "::", 1) for name in sys.argv[5:]]
rows = []
with EcosSimulation(ssp_path=ssp, step_size=step) as simulation:
    simulation.init(parameter_set=parameter_set)  # ecos applies parameter sets by name, when asked
    for _ in range(steps):
        simulation.step()
        rows.append([simulation.get_real(name) for name in recorded])
print(json.dumps(rows))
