"""Runs an SSP in libcosim (libcosimpy) and prints the bobs' positions per step as JSON.
Run as a child process: libcosim can take the process down on a broken FMU."""
import json
import sys

from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimObserver import CosimObserver

ssp, step, steps = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
start_angles = json.loads(sys.argv[4])  # libcosim skips bound start values of states: set them here
execution = CosimExecution.from_ssp_file(ssp, step_size=int(round(step * 1e9)))
index = {info.name.decode(): info.index for info in execution.slave_infos()}
references = {name: {v.name.decode(): v.reference for v in execution.slave_variables(i)} for name, i in index.items()}
for name, angle in start_angles.items():
    execution.real_initial_value(index[name], references[name]["phi"], angle)
observer = CosimObserver.create_last_value()
execution.add_observer(observer)
rows = []
for _ in range(steps):
    assert execution.step(1)
    row = []
    for name in ("left", "right"):
        row += observer.last_real_values(index[name], [references[name]["x"], references[name]["y"]])
    rows.append(row)
print(json.dumps(rows))
