"""Nothing a caller does wrong crashes the process or corrupts an instance; no mutable static data."""
from __future__ import annotations

import ctypes
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from harness.fmi.fmu_instance import ERROR, OK
from harness.fmi.fmus import FMU_NAMES

API = ["fmi2SetDebugLogging", "fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode",
       "fmi2Terminate", "fmi2Reset", "fmi2GetReal", "fmi2GetInteger", "fmi2GetBoolean", "fmi2GetString",
       "fmi2SetReal", "fmi2SetInteger", "fmi2SetBoolean", "fmi2SetString", "fmi2GetFMUstate", "fmi2SetFMUstate",
       "fmi2FreeFMUstate", "fmi2SerializedFMUstateSize", "fmi2SerializeFMUstate", "fmi2DeSerializeFMUstate",
       "fmi2GetDirectionalDerivative", "fmi2EnterEventMode", "fmi2NewDiscreteStates", "fmi2EnterContinuousTimeMode",
       "fmi2CompletedIntegratorStep", "fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetDerivatives",
       "fmi2GetEventIndicators", "fmi2GetContinuousStates", "fmi2GetNominalsOfContinuousStates",
       "fmi2SetRealInputDerivatives", "fmi2GetRealOutputDerivatives", "fmi2DoStep", "fmi2CancelStep",
       "fmi2GetStatus", "fmi2GetRealStatus", "fmi2GetIntegerStatus", "fmi2GetBooleanStatus", "fmi2GetStringStatus"]


@pytest.mark.parametrize("name", FMU_NAMES)
def test_every_function_with_a_null_instance_returns_error(unzipped, name):
    """Run in a child process, so that a crash fails the test instead of ending the run."""
    library = Path(unzipped[name]) / "binaries" / "linux64" / f"{name}.so"
    script = textwrap.dedent(f"""
        import ctypes
        lib = ctypes.CDLL({str(library)!r})
        lib.fmi2DoStep.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int]
        lib.fmi2SetupExperiment.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_double, ctypes.c_double,
                                            ctypes.c_int, ctypes.c_double]
        lib.fmi2SetTime.argtypes = [ctypes.c_void_p, ctypes.c_double]
        statuses = []
        for function in {API!r}:
            f = getattr(lib, function)
            if function in ("fmi2DoStep", "fmi2SetupExperiment", "fmi2SetTime"):
                args = {{"fmi2DoStep": (None, 0.0, 1.0, 1), "fmi2SetupExperiment": (None, 0, 0.0, 0.0, 0, 0.0),
                        "fmi2SetTime": (None, 0.0)}}[function]
            else:
                args = (None,) + (0,) * 6
            statuses.append(f(*args))
        lib.fmi2FreeInstance(None)
        lib.fmi2Instantiate.restype = ctypes.c_void_p
        assert lib.fmi2Instantiate(b"x", 1, b"{{wrong}}", b"", None, 0, 0) is None
        print(statuses)
    """)
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert eval(result.stdout) == [ERROR] * len(API)


@pytest.mark.parametrize("name", FMU_NAMES)
def test_no_mutable_static_data(unzipped, name):
    """Only the C runtime's own words in .data and .bss: instances share nothing, threads are safe."""
    library = Path(unzipped[name]) / "binaries" / "linux64" / f"{name}.so"
    headers = subprocess.run(["objdump", "-h", str(library)], capture_output=True, text=True, check=True).stdout
    sizes = {m.group(1): int(m.group(2), 16) for m in re.finditer(r"^\s*\d+\s+(\.data|\.bss)\s+([0-9a-f]+)",
                                                                   headers, re.M)}
    assert sizes.get(".data", 0) <= 16 and sizes.get(".bss", 0) <= 16, sizes


def test_model_exchange_call_order(open_fmu):
    fmu = open_fmu("SpringPendulum", kind="ME")
    states = (ctypes.c_double * 4)()
    assert fmu.call("fmi2GetDerivatives", states, 4) == ERROR  # before initialization
    assert "illegal call sequence" in fmu.last_message()
    fmu.initialize()
    assert fmu.call("fmi2SetContinuousStates", states, 4) == ERROR  # event mode
    assert fmu.call("fmi2EnterContinuousTimeMode") == OK
    assert fmu.call("fmi2SetContinuousStates", states, 3) == ERROR and "array length 3" in fmu.last_message()
    bad = (ctypes.c_double * 4)(0.0, float("nan"), 0.0, 0.0)
    assert fmu.call("fmi2SetContinuousStates", bad, 4) == ERROR and "eps = nan" in fmu.last_message()
    assert fmu.call("fmi2DoStep", ctypes.c_double(0.0), ctypes.c_double(0.1), 1) == ERROR
    assert "Model Exchange" in fmu.last_message()
    assert fmu.call("fmi2GetDerivatives", states, 4) == OK


def test_debug_logging_categories(open_fmu):
    fmu = open_fmu("SimplePendulum")
    categories = (ctypes.c_char_p * 1)(b"logNothing")
    assert fmu.call("fmi2SetDebugLogging", 1, 1, categories) == ERROR
    assert "unknown log category logNothing" in fmu.last_message()
    categories = (ctypes.c_char_p * 2)(b"logAll", b"logStatusError")
    assert fmu.call("fmi2SetDebugLogging", 1, 2, categories) == OK


def test_free_state_clears_the_pointer(open_fmu):
    fmu = open_fmu("DoublePendulum")
    fmu.initialize()
    state = fmu.get_state()
    fmu.free_state(state)
    assert state.value is None
    assert fmu.call("fmi2FreeFMUstate", ctypes.byref(state)) == OK  # freeing NULL is a no-op
    assert fmu.do_step(0.0, 0.1) == OK
