"""Runs one FMU alone, or an SSP, in OMSimulator (its Python package, 3.0) and prints the named outputs
after each communication step as JSON (child process: an importer can take the process down).

    run_omsimulator.py fmu FMU STEP STEPS START_JSON VARIABLE...
    run_omsimulator.py ssp SSP STEPS COMPONENT.VARIABLE...

An SSP runs at the step it names (no step is given to OMSimulator). OMSimulator writes a result file
where it runs: the script works in the temporary folder.
"""
import json
import os
import sys
import tempfile

from OMSimulator import SSP, CRef

os.chdir(tempfile.gettempdir())
if sys.argv[1] == "fmu":
    fmu, step, steps = os.path.abspath(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
    start = json.loads(sys.argv[5])
    recorded = [("unit", name) for name in sys.argv[6:]]
    model, system = SSP(), "default"
    model.addResource(fmu, new_name="resources/unit.fmu")
    model.addComponent(CRef(system, "unit"), "resources/unit.fmu")
    instance = model.instantiate()
    instance.setFixedStepSize(step)
    for name, value in start.items():
        instance.setValue(CRef(system, "unit", name), value)
else:
    model = SSP(os.path.abspath(sys.argv[2]))
    steps, recorded = int(sys.argv[3]), [tuple(name.split(".", 1)) for name in sys.argv[4:]]
    system = str(model.activeVariant.system.name)
    instance = model.instantiate()
instance.initialize()
rows = []
for _ in range(steps):
    instance.doStep()  # one step of the master at its step size
    rows.append([instance.getValue(CRef(system, component, variable)) for component, variable in recorded])
instance.terminate()
instance.delete()
print(json.dumps(rows))
