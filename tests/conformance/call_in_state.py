"""Brings fresh instances of an FMU into each given state of the FMI 2.0 state machine and calls one
function on each: prints, per state as it is done, one line of JSON {"state": STATE, "outcome":
{function: [status, last log message]}}.

    call_in_state.py FMU UNZIPDIR {CS|ME} STATE [STATE ...]

Run as a child process, so that a crash fails only this FMU's and interface's cases (those of the states
not printed); one process for all of an interface's states, as starting one costs more than its calls."""
import ctypes
import json
import sys

from fmpy.fmi2 import fmi2EventInfo

from harness.fmi.fmu_instance import FmuInstance

path, unzipdir, kind, *states = sys.argv[1:]
D, Int, P = ctypes.c_double, ctypes.c_int, ctypes.c_void_p


def prepare(state: str) -> FmuInstance:
    fmu = FmuInstance(path, kind=kind, unzipdir=unzipdir)
    names = fmu.variables
    if state == "stepFailed":  # a configuration whose first step is discarded
        # the Spring's ends meet at the end of the first step; the spring pendulum's mass passes its anchor
        singular = {"b_x": 0.5, "b_vx": -0.5} if "b_x" in names else {"phi": 0.0, "eps": -0.5, "v_eps": -5.0, "g": 0.0}
        assert fmu.set(**singular) == 0
    if state == "instantiated":
        return fmu
    assert fmu.call("fmi2SetupExperiment", 0, D(0.0), D(0.0), 0, D(0.0)) == 0
    assert fmu.call("fmi2EnterInitializationMode") == 0
    if state == "initializationMode":
        return fmu
    assert fmu.call("fmi2ExitInitializationMode") == 0
    if state == "continuousTimeMode":
        assert fmu.call("fmi2EnterContinuousTimeMode") == 0
    if state == "stepFailed":
        assert fmu.call("fmi2DoStep", D(0.0), D(1.0), 1) == 2
    if state == "terminated":
        assert fmu.call("fmi2Terminate") == 0
    return fmu


def calls(fmu: FmuInstance) -> dict:
    md = fmu.model_description
    real_out = next(v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real")
    real_in = next(v.valueReference for v in md.modelVariables if v.causality == "input")
    nx = md.numberOfContinuousStates
    nz = md.numberOfEventIndicators
    vr_out, vr_in = (ctypes.c_uint * 1)(real_out), (ctypes.c_uint * 1)(real_in)
    values, order, states = (D * 1)(0.0), (Int * 1)(1), (D * max(nx, 1))()
    fmu.call("fmi2GetContinuousStates", states, nx)  # fills the buffer where allowed, harmless elsewhere
    state = P()
    fmu.call("fmi2GetFMUstate", ctypes.byref(state))  # allowed in every state reached here
    size = ctypes.c_size_t()
    fmu.call("fmi2SerializedFMUstateSize", state, ctypes.byref(size))
    data = ctypes.create_string_buffer(max(size.value, 1))
    fmu.call("fmi2SerializeFMUstate", state, data, size)
    flag1, flag2, real, status = Int(), Int(), D(), Int()
    return {
        "fmi2SetDebugLogging": lambda: fmu.call("fmi2SetDebugLogging", 0, 0, None),
        "fmi2SetupExperiment": lambda: fmu.call("fmi2SetupExperiment", 0, D(0.0), D(0.0), 0, D(0.0)),
        "fmi2EnterInitializationMode": lambda: fmu.call("fmi2EnterInitializationMode"),
        "fmi2ExitInitializationMode": lambda: fmu.call("fmi2ExitInitializationMode"),
        "fmi2Terminate": lambda: fmu.call("fmi2Terminate"),
        "fmi2Reset": lambda: fmu.call("fmi2Reset"),
        "fmi2GetReal": lambda: fmu.call("fmi2GetReal", vr_out, 1, values),
        "fmi2GetInteger": lambda: fmu.call("fmi2GetInteger", None, 0, None),
        "fmi2GetBoolean": lambda: fmu.call("fmi2GetBoolean", None, 0, None),
        "fmi2GetString": lambda: fmu.call("fmi2GetString", None, 0, None),
        "fmi2SetReal": lambda: fmu.call("fmi2SetReal", vr_in, 1, (D * 1)(0.0)),
        "fmi2SetInteger": lambda: fmu.call("fmi2SetInteger", None, 0, None),
        "fmi2SetBoolean": lambda: fmu.call("fmi2SetBoolean", None, 0, None),
        "fmi2SetString": lambda: fmu.call("fmi2SetString", None, 0, None),
        "fmi2GetFMUstate": lambda: fmu.call("fmi2GetFMUstate", ctypes.byref(P())),
        "fmi2SetFMUstate": lambda: fmu.call("fmi2SetFMUstate", state),
        "fmi2FreeFMUstate": lambda: fmu.call("fmi2FreeFMUstate", ctypes.byref(P())),
        "fmi2SerializedFMUstateSize": lambda: fmu.call("fmi2SerializedFMUstateSize", state, ctypes.byref(size)),
        "fmi2SerializeFMUstate": lambda: fmu.call("fmi2SerializeFMUstate", state, data, size),
        "fmi2DeSerializeFMUstate": lambda: fmu.call("fmi2DeSerializeFMUstate", data, size, ctypes.byref(P())),
        "fmi2GetDirectionalDerivative": lambda: fmu.call("fmi2GetDirectionalDerivative", vr_out, 1, vr_in, 1,
                                                         (D * 1)(1.0), values),
        "fmi2EnterEventMode": lambda: fmu.call("fmi2EnterEventMode"),
        "fmi2NewDiscreteStates": lambda: fmu.call("fmi2NewDiscreteStates", ctypes.byref(fmi2EventInfo())),
        "fmi2EnterContinuousTimeMode": lambda: fmu.call("fmi2EnterContinuousTimeMode"),
        "fmi2CompletedIntegratorStep": lambda: fmu.call("fmi2CompletedIntegratorStep", 1, ctypes.byref(flag1),
                                                        ctypes.byref(flag2)),
        "fmi2SetTime": lambda: fmu.call("fmi2SetTime", D(0.0)),
        "fmi2SetContinuousStates": lambda: fmu.call("fmi2SetContinuousStates", states, nx),
        "fmi2GetDerivatives": lambda: fmu.call("fmi2GetDerivatives", (D * max(nx, 1))(), nx),
        "fmi2GetEventIndicators": lambda: fmu.call("fmi2GetEventIndicators", (D * max(nz, 1))(), nz),
        "fmi2GetContinuousStates": lambda: fmu.call("fmi2GetContinuousStates", (D * max(nx, 1))(), nx),
        "fmi2GetNominalsOfContinuousStates": lambda: fmu.call("fmi2GetNominalsOfContinuousStates",
                                                              (D * max(nx, 1))(), nx),
        "fmi2SetRealInputDerivatives": lambda: fmu.call("fmi2SetRealInputDerivatives", vr_in, 1, order, (D * 1)(0.0)),
        "fmi2GetRealOutputDerivatives": lambda: fmu.call("fmi2GetRealOutputDerivatives", vr_out, 1, order, values),
        "fmi2DoStep": lambda: fmu.call("fmi2DoStep", D(fmu.last_successful_time() if kind == "CS" else 0.0),
                                       D(0.01), 1),
        "fmi2CancelStep": lambda: fmu.call("fmi2CancelStep"),
        "fmi2GetStatus": lambda: fmu.call("fmi2GetStatus", 0, ctypes.byref(status)),
        "fmi2GetRealStatus": lambda: fmu.call("fmi2GetRealStatus", 2, ctypes.byref(real)),
        "fmi2GetIntegerStatus": lambda: fmu.call("fmi2GetIntegerStatus", 0, ctypes.byref(status)),
        "fmi2GetBooleanStatus": lambda: fmu.call("fmi2GetBooleanStatus", 3, ctypes.byref(flag1)),
        "fmi2GetStringStatus": lambda: fmu.call("fmi2GetStringStatus", 0, ctypes.byref(ctypes.c_char_p())),
    }


for state in states:
    outcome = {}
    for name in calls(prepare(state)):
        fmu = prepare(state)  # a fresh instance per call: no call sees another's effect
        before = len(fmu.log.messages)
        result = calls(fmu)[name]()
        messages = fmu.log.messages[before:]
        outcome[name] = [result, messages[-1].text if messages else ""]
    print(json.dumps({"state": state, "outcome": outcome}), flush=True)
