"""Runtime conformance: every FMI 2.0 function in every reachable state of the Co-Simulation and
Model Exchange state machines. Allowed calls work; illegal ones return fmi2Error with an "illegal
call sequence" message. The expected table is the standard's (FMI 2.0, sections 3.2.3 and 4.2.4),
written here independently of the C code. Each (FMU, interface) pair's states run in a process of their own."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from fmpy import read_model_description

from harness.fmi.fmus import FMU_NAMES

CS = ("instantiated", "initializationMode", "stepComplete", "stepFailed", "terminated")
ME = ("instantiated", "initializationMode", "eventMode", "continuousTimeMode", "terminated")
EVERY = set(CS) | set(ME)
CS_READ = {"initializationMode", "stepComplete", "stepFailed", "terminated"}
ME_READ = {"initializationMode", "eventMode", "continuousTimeMode", "terminated"}
SETUP = {"instantiated", "initializationMode"}
STATE_FUNCTIONS = ("fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2FreeFMUstate", "fmi2SerializedFMUstateSize",
                   "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate")

ALLOWED: dict[str, tuple[set, set]] = {  # function: (Co-Simulation states, Model Exchange states)
    "fmi2SetDebugLogging": (EVERY, EVERY),
    "fmi2SetupExperiment": ({"instantiated"}, {"instantiated"}),
    "fmi2EnterInitializationMode": ({"instantiated"}, {"instantiated"}),
    "fmi2ExitInitializationMode": ({"initializationMode"}, {"initializationMode"}),
    "fmi2Terminate": ({"stepComplete", "stepFailed"}, {"eventMode", "continuousTimeMode"}),
    "fmi2Reset": (EVERY, EVERY),
    **{f"fmi2Get{t}": (CS_READ, ME_READ) for t in ("Real", "Integer", "Boolean", "String")},
    "fmi2SetReal": (SETUP | {"stepComplete"}, SETUP | {"eventMode", "continuousTimeMode"}),
    **{f"fmi2Set{t}": (SETUP | {"stepComplete"}, SETUP | {"eventMode"}) for t in ("Integer", "Boolean", "String")},
    **{f: (EVERY, EVERY) for f in STATE_FUNCTIONS},
    "fmi2GetDirectionalDerivative": (CS_READ, ME_READ),
    "fmi2EnterEventMode": (set(), {"eventMode", "continuousTimeMode"}),
    "fmi2NewDiscreteStates": (set(), {"eventMode"}),
    "fmi2EnterContinuousTimeMode": (set(), {"eventMode"}),
    "fmi2CompletedIntegratorStep": (set(), {"continuousTimeMode"}),
    "fmi2SetTime": (set(), {"eventMode", "continuousTimeMode"}),
    "fmi2SetContinuousStates": (set(), {"continuousTimeMode"}),
    **{f: (set(), ME_READ) for f in ("fmi2GetDerivatives", "fmi2GetEventIndicators", "fmi2GetContinuousStates",
                                     "fmi2GetNominalsOfContinuousStates")},
    "fmi2SetRealInputDerivatives": (SETUP | {"stepComplete"}, set()),
    "fmi2GetRealOutputDerivatives": ({"stepComplete", "stepFailed", "terminated"}, set()),
    "fmi2DoStep": ({"stepComplete"}, set()),
    "fmi2CancelStep": (set(), set()),  # only in stepInProgress, which a synchronous FMU never enters
    **{f"fmi2Get{t}Status": ({"stepComplete", "stepFailed", "terminated"}, set())
       for t in ("", "Real", "Integer", "Boolean", "String")},
}
CASES = [(name, "CS", state) for name in FMU_NAMES for state in CS
         if state != "stepFailed" or name in ("SpringPendulum", "Spring")] + \
        [(name, "ME", state) for name in FMU_NAMES for state in ME]


@pytest.fixture(scope="module")
def outcomes(fmu_paths, unzipped):
    """outcomes(name, kind) -> (exit code, {state: {function: [status, message]}}, stderr): every state of the
    pair's cases, called in one child process, run once per module."""
    script = Path(__file__).resolve().parents[1] / "conformance" / "call_in_state.py"
    done = {}

    def run(name: str, kind: str) -> tuple[int, dict, str]:
        if (name, kind) not in done:
            states = [state for n, k, state in CASES if (n, k) == (name, kind)]
            result = subprocess.run([sys.executable, str(script), str(fmu_paths[name]), str(unzipped[name]), kind,
                                     *states], capture_output=True, text=True, timeout=600)
            lines = [json.loads(line) for line in result.stdout.splitlines() if line.startswith('{"state"')]
            done[name, kind] = result.returncode, {line["state"]: line["outcome"] for line in lines}, \
                result.stderr[-3000:]
        return done[name, kind]
    return run


@pytest.mark.parametrize("name,kind,state", CASES)
def test_every_function_in_every_state(fmu_paths, outcomes, name, kind, state):
    returncode, by_state, stderr = outcomes(name, kind)
    assert returncode == 0 and state in by_state, stderr  # a crash fails every state of its FMU and interface
    outcome = by_state[state]
    assert set(outcome) == set(ALLOWED)
    for function, (status, message) in outcome.items():
        allowed = state in ALLOWED[function][0 if kind == "CS" else 1]
        if not allowed:
            assert status == 3 and "illegal call sequence" in message, (function, status, message)
        elif function == "fmi2GetDirectionalDerivative" and not provides_partial_derivatives(fmu_paths[name], kind):
            assert status == 3 and "provides no partial derivatives" in message, (function, status, message)
        else:
            assert status < 3, (function, status, message)


def provides_partial_derivatives(path: Path, kind: str) -> bool:
    """What the model description declares (the objects with constraints provide none)."""
    description = read_model_description(str(path))
    interface = description.coSimulation if kind == "CS" else description.modelExchange
    return bool(interface.providesDirectionalDerivative)
