"""Seconds per macro step of the coupled-pendulums SSP in an independent importer (child process).

    peer_step_cost.py {libcosim|ecos} SSP STEP STEPS
"""
import sys
import time

peer, ssp, step, steps = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
if peer == "libcosim":
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_ssp_file(ssp, step_size=int(round(step * 1e9)))
    execution.step(1)  # initialization happens in the first step
    start = time.perf_counter()
    execution.step(steps)
    elapsed = time.perf_counter() - start
else:
    from ecospy import EcosSimulation
    with EcosSimulation(ssp_path=ssp, step_size=step) as simulation:
        simulation.init(parameter_set="initialValues")
        start = time.perf_counter()
        simulation.step(steps)
        elapsed = time.perf_counter() - start
print(f"RESULT {elapsed / steps:.9g}")
