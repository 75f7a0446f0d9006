"""Bad input, case by case: each gets fmi2Error (or a refused instantiation) and a log message that
names the function, the variable or argument, the value and what is allowed, and the instance is
unharmed afterwards. Value cases are generated from the model descriptions' ranges."""
from __future__ import annotations

import ctypes
import math

import pytest
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave

from harness.fmi.fmu_instance import ERROR, OK, LogCollector
from harness.fmi.fmus import FMU_NAMES, build_dir

D = ctypes.c_double


def serialized_size(fmu) -> int:
    """The size of this FMU's serialized state, as it reports it."""
    state, size = ctypes.c_void_p(), ctypes.c_size_t()
    assert fmu.call("fmi2GetFMUstate", ctypes.byref(state)) == OK
    assert fmu.call("fmi2SerializedFMUstateSize", state, ctypes.byref(size)) == OK
    fmu.call("fmi2FreeFMUstate", ctypes.byref(state))
    return size.value


def value_cases() -> list[tuple[str, str, float, str]]:
    cases = []
    for name in FMU_NAMES:
        md = read_model_description(str(build_dir() / "fmus" / f"{name}.fmu"))
        for v in md.modelVariables:
            if v.causality not in ("parameter", "input") and v.initial != "exact":
                continue
            if v.type == "Real":
                cases.append((name, v.name, math.nan, "not a finite number"))
                if v.min is not None:
                    cases.append((name, v.name, float(v.min) - 0.5 - abs(float(v.min)), "out of its allowed range"))
                if v.max is not None:
                    cases.append((name, v.name, float(v.max) + 1.0, "out of its allowed range"))
            elif v.type == "Enumeration":
                count = len(v.declaredType.items)
                cases += [(name, v.name, 0, "out of its allowed range"), (name, v.name, count + 1, "out of its allowed range")]
    return cases


VALUE_CASES = value_cases()


def test_there_are_at_least_fifty_cases():
    assert len(VALUE_CASES) + len(MISUSE) + len(AFTER_INIT) + 2 >= 50


@pytest.mark.parametrize("name,variable,value,words", VALUE_CASES,
                         ids=[f"{c[0]}.{c[1]}={c[2]:g}" for c in VALUE_CASES])
def test_out_of_range_or_non_finite_values(open_fmu, name, variable, value, words):
    fmu = open_fmu(name)
    assert fmu.set(**{variable: value}) == ERROR
    message = fmu.last_message()
    function = "fmi2SetInteger" if isinstance(value, int) else "fmi2SetReal"
    assert function in message and f"variable {variable} " in message and words in message, message
    assert ("nan" in message) if isinstance(value, float) and math.isnan(value) else (f"{value:.6g}"[:4] in message)
    fmu.initialize()  # nothing was stored: the defaults initialize and step
    assert fmu.do_step(0.0, 0.01) == OK


def _set_real(fmu, vr, n, values):
    return fmu.call("fmi2SetReal", vr, n, values)


MISUSE: dict = {
    "Real value reference unknown": (lambda f: _set_real(f, (ctypes.c_uint * 1)(9999), 1, (D * 1)(0.0)),
                                     "unknown value reference 9999"),
    "Integer value reference unknown": (lambda f: f.call("fmi2GetInteger", (ctypes.c_uint * 1)(9999), 1,
                                                         (ctypes.c_int * 1)()), "unknown value reference 9999"),
    "Integer call on a Real variable": (lambda f: f.call("fmi2SetInteger", (ctypes.c_uint * 1)(0), 1,
                                                         (ctypes.c_int * 1)(1)), "unknown value reference 0"),
    "Real call on an Integer variable": (lambda f: _set_real(f, (ctypes.c_uint * 1)(f.reference("solver")), 1,
                                                             (D * 1)(1.0)), "unknown value reference"),
    "Boolean variable": (lambda f: f.call("fmi2GetBoolean", (ctypes.c_uint * 1)(0), 1, (ctypes.c_int * 1)()),
                         "no Boolean variables"),
    "String variable": (lambda f: f.call("fmi2SetString", (ctypes.c_uint * 1)(0), 1, (ctypes.c_char_p * 1)(b"x")),
                        "no String variables"),
    "NULL value array": (lambda f: _set_real(f, (ctypes.c_uint * 1)(0), 1, None), "NULL array"),
    "NULL reference array": (lambda f: f.call("fmi2GetReal", None, 2, (D * 2)()), "NULL array"),
    "calculated output set": (lambda f: f.set(x=1.0), "calculated output"),
    "derivative order 2 in": (lambda f: f.call("fmi2SetRealInputDerivatives", (ctypes.c_uint * 1)(f.reference("F_x")),
                                               1, (ctypes.c_int * 1)(2), (D * 1)(1.0)), "derivative order 2"),
    "input derivative of a non-input": (lambda f: f.call("fmi2SetRealInputDerivatives",
                                                         (ctypes.c_uint * 1)(f.reference("L")), 1,
                                                         (ctypes.c_int * 1)(1), (D * 1)(1.0)),
                                        "variable L (value reference 10) is not a Real input (allowed: the 4 Real inputs)"),
    "input derivative of an output": (lambda f: f.call("fmi2SetRealInputDerivatives",
                                                       (ctypes.c_uint * 1)(f.reference("x")), 1,
                                                       (ctypes.c_int * 1)(1), (D * 1)(1.0)),
                                      "variable x (value reference 16) is not a Real input"),
    "input derivative of an unknown reference": (lambda f: f.call("fmi2SetRealInputDerivatives",
                                                                  (ctypes.c_uint * 1)(9999), 1, (ctypes.c_int * 1)(1),
                                                                  (D * 1)(1.0)), "unknown value reference 9999"),
    "NaN input derivative": (lambda f: f.call("fmi2SetRealInputDerivatives", (ctypes.c_uint * 1)(f.reference("F_x")),
                                              1, (ctypes.c_int * 1)(1), (D * 1)(math.nan)), "not a finite number"),
    "unknown log category": (lambda f: f.call("fmi2SetDebugLogging", 1, 1, (ctypes.c_char_p * 1)(b"logEverything")),
                             "unknown log category logEverything"),
    "NaN start time": (lambda f: f.call("fmi2SetupExperiment", 0, D(0), D(math.nan), 0, D(0)), "startTime = nan"),
    "stop before start": (lambda f: f.call("fmi2SetupExperiment", 0, D(0), D(5.0), 1, D(1.0)), "stopTime = 1"),
    "NULL FMU state": (lambda f: f.call("fmi2SetFMUstate", None), "FMUstate is NULL"),
    "NULL FMU state pointer": (lambda f: f.call("fmi2GetFMUstate", None), "FMUstate pointer is NULL"),
    "truncated serialized state": (lambda f: f.call("fmi2DeSerializeFMUstate", ctypes.create_string_buffer(10), 10,
                                                    ctypes.byref(ctypes.c_void_p())), "size = 10"),
    "garbage serialized state": (lambda f: f.call("fmi2DeSerializeFMUstate",
                                                  ctypes.create_string_buffer(size := serialized_size(f)), size,
                                                  ctypes.byref(ctypes.c_void_p())), "corrupt"),
    "directional derivative with respect to a parameter": (
        lambda f: f.call("fmi2GetDirectionalDerivative", (ctypes.c_uint * 1)(3), 1, (ctypes.c_uint * 1)(10), 1,
                         (D * 1)(1.0), (D * 1)()), "known L (value reference 10) is not a continuous state or a Real input"),
    "directional derivative with a NaN seed": (
        lambda f: f.call("fmi2GetDirectionalDerivative", (ctypes.c_uint * 1)(3), 1, (ctypes.c_uint * 1)(0), 1,
                         (D * 1)(math.nan), (D * 1)()), "seed[0] = nan is not a finite number"),
    "directional derivative without arrays": (
        lambda f: f.call("fmi2GetDirectionalDerivative", None, 1, None, 1, None, None), "NULL array"),
}
AFTER_INIT: dict = {
    "step of zero length": (lambda f: f.call("fmi2DoStep", D(0.0), D(0.0), 1), "communicationStepSize = 0"),
    "negative step": (lambda f: f.call("fmi2DoStep", D(0.0), D(-0.1), 1), "communicationStepSize = -0.1"),
    "NaN step": (lambda f: f.call("fmi2DoStep", D(0.0), D(math.nan), 1), "communicationStepSize = nan"),
    "infinite step": (lambda f: f.call("fmi2DoStep", D(0.0), D(math.inf), 1), "communicationStepSize = inf"),
    "wrong communication point": (lambda f: f.call("fmi2DoStep", D(0.5), D(0.1), 1), "currentCommunicationPoint = 0.5"),
    "NaN communication point": (lambda f: f.call("fmi2DoStep", D(math.nan), D(0.1), 1), "currentCommunicationPoint"),
    "fixed parameter after initialization": (lambda f: f.set(L=2.0), "fixed parameter"),
    "state set after initialization": (lambda f: f.set(phi=0.1), "is a state and cannot be set"),
    "initialization twice": (lambda f: f.call("fmi2EnterInitializationMode"), "illegal call sequence"),
    "Model Exchange call in Co-Simulation": (lambda f: f.call("fmi2SetTime", D(1.0)), "illegal call sequence"),
}


# Getters are only legal after initialization: their argument errors are checked there.
for _case in ("Integer value reference unknown", "Boolean variable", "NULL reference array",
              "directional derivative with respect to a parameter", "directional derivative with a NaN seed",
              "directional derivative without arrays"):
    AFTER_INIT[_case] = MISUSE.pop(_case)


@pytest.mark.parametrize("case", list(MISUSE) + list(AFTER_INIT))
def test_misuse(open_fmu, case):
    fmu = open_fmu("SimplePendulum")
    if case in AFTER_INIT:
        fmu.initialize()
        call, words = AFTER_INIT[case]
    else:
        call, words = MISUSE[case]
    assert call(fmu) == ERROR
    assert words in fmu.last_message(), fmu.last_message()
    if case not in AFTER_INIT:
        fmu.initialize()
    assert fmu.do_step(0.0, 0.01) == OK  # still usable


@pytest.mark.parametrize("guid,kind,words", [("{00000000-0000-0000-0000-000000000000}", 1, "does not match this FMU"),
                                             (None, 7, "fmuType = 7")])
def test_refused_instantiation(fmu_paths, unzipped, guid, kind, words):
    md = read_model_description(str(fmu_paths["DoublePendulum"]))
    log = LogCollector()
    slave = FMU2Slave(guid=guid or md.guid, unzipDirectory=unzipped["DoublePendulum"],
                      modelIdentifier="DoublePendulum", instanceName="refused")
    instantiate = slave.dll.fmi2Instantiate
    instantiate.restype = ctypes.c_void_p
    handle = instantiate(b"refused", kind, (guid or md.guid).encode(), b"", ctypes.byref(log.callbacks), 0, 0)
    assert handle is None and words in log.messages[-1].text
    slave.freeLibrary()
