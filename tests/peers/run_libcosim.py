"""Runs an SSP in libcosim (libcosimpy) and prints the named outputs per step as JSON.

    run_libcosim.py SSP STEP STEPS START_JSON COMPONENT.VARIABLE...

STEP "file": no step given, libcosim takes the one the SSP's DefaultExperiment annotation names.
START_JSON: {"component": {"variable": value}}: start values of states, which libcosim's SSP loader
skips when they are bound (it applies bindings to parameters and inputs only). Run as a child
process: libcosim can take the process down on a broken FMU."""
import json
import sys

from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimObserver import CosimObserver

ssp, step, steps = sys.argv[1], None if sys.argv[2] == "file" else float(sys.argv[2]), int(sys.argv[3])
starts = json.loads(sys.argv[4])
recorded = [name.split(".", 1) for name in sys.argv[5:]]
execution = CosimExecution.from_ssp_file(ssp) if step is None else \
    CosimExecution.from_ssp_file(ssp, step_size=int(round(step * 1e9)))
index = {info.name.decode(): info.index for info in execution.slave_infos()}
references = {name: {v.name.decode(): v.reference for v in execution.slave_variables(i)} for name, i in index.items()}
for component, values in starts.items():
    for variable, value in values.items():
        execution.real_initial_value(index[component], references[component][variable], value)
observer = CosimObserver.create_last_value()
execution.add_observer(observer)
rows = []
for _ in range(steps):
    assert execution.step(1)
    rows.append([observer.last_real_values(index[c], [references[c][v]])[0] for c, v in recorded])
print(json.dumps(rows))
