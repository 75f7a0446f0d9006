"""Runs one FMU alone in libcosim or ecos and prints the named outputs after each step as JSON (child
process: an importer can take the process down on a broken FMU).

    run_single.py {libcosim|ecos} FMU STEP STEPS START_JSON VARIABLE...

START_JSON maps real variables to start values (e.g. the Spring's inputs).
"""
import json
import sys

peer, fmu, step, steps = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
start, names = json.loads(sys.argv[5]), sys.argv[6:]
rows = []
if peer == "libcosim":
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave
    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_step_size(step_size=int(round(step * 1e9)))
    index = execution.add_local_slave(CosimLocalSlave(fmu_path=fmu, instance_name="unit"))
    references = {v.name.decode(): v.reference for v in execution.slave_variables(index)}
    for name, value in start.items():
        execution.real_initial_value(index, references[name], value)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    for _ in range(steps):
        assert execution.step(1)
        rows.append(observer.last_real_values(index, [references[n] for n in names]))
else:
    from ecospy import EcosSimulation, EcosSimulationStructure
    structure = EcosSimulationStructure()
    structure.add_model("unit", fmu)
    with EcosSimulation(structure=structure, step_size=step) as simulation:
        for name, value in start.items():
            simulation.set_real(f"unit::{name}", value)
        simulation.init()
        for _ in range(steps):
            simulation.step()
            rows.append([simulation.get_real(f"unit::{n}") for n in names])
print(json.dumps(rows))
