"""Property-based fuzzing: random sequences of FMI calls with random values (hypothesis, bounded).
Whatever the order or the values, no call crashes, and whenever fmi2GetReal returns fmi2OK every
Real value it returns is finite."""
from __future__ import annotations

import ctypes
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from harness.fmi.fmu_instance import OK, FmuInstance
from harness.fmi.fmus import FMU_NAMES
from harness.fmi.methods import SOLVERS

D = ctypes.c_double
values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-10, 10), st.sampled_from([0.0, 1e-9]))
operations = st.lists(st.one_of(
    st.tuples(st.just("set_real"), st.integers(0, 40), values),
    st.tuples(st.just("set_integer"), st.integers(0, 40), st.integers(-3, len(SOLVERS) + 2)),
    st.tuples(st.just("set_slope"), st.integers(0, 40), values),
    st.tuples(st.just("step"), st.floats(-0.5, 2.0), st.sampled_from([0.0, 0.3, 1.0])),
    st.tuples(st.sampled_from(["enter", "exit", "terminate", "reset", "save", "restore", "read"]), st.none(),
              st.none()),
), max_size=25)


def all_reals_finite_when_ok(fmu: FmuInstance) -> None:
    reals = [v.valueReference for v in fmu.model_description.modelVariables if v.type == "Real"]
    out = (D * len(reals))()
    if fmu.call("fmi2GetReal", (ctypes.c_uint * len(reals))(*reals), len(reals), out) == OK:
        assert all(math.isfinite(x) for x in out), list(out)


@pytest.mark.parametrize("name", FMU_NAMES)
def test_random_call_sequences(fmu_paths, unzipped, name):
    @settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
    @given(operations)
    def run(sequence):
        with FmuInstance(fmu_paths[name], unzipdir=unzipped[name]) as fmu:
            state = ctypes.c_void_p()
            for op, a, b in sequence:
                if op == "set_real":
                    fmu.call("fmi2SetReal", (ctypes.c_uint * 1)(a), 1, (D * 1)(b))
                elif op == "set_integer":
                    fmu.call("fmi2SetInteger", (ctypes.c_uint * 1)(a), 1, (ctypes.c_int * 1)(b))
                elif op == "set_slope":
                    fmu.call("fmi2SetRealInputDerivatives", (ctypes.c_uint * 1)(a), 1, (ctypes.c_int * 1)(1),
                             (D * 1)(b))
                elif op == "step":
                    t = fmu.last_successful_time() if a > 1.5 else a  # mostly a legal, sometimes a wrong time
                    fmu.call("fmi2DoStep", D(t), D(b), 1)
                elif op == "enter":
                    fmu.call("fmi2EnterInitializationMode")
                elif op == "exit":
                    fmu.call("fmi2ExitInitializationMode")
                elif op == "terminate":
                    fmu.call("fmi2Terminate")
                elif op == "reset":
                    fmu.call("fmi2Reset")
                elif op == "save":
                    fmu.call("fmi2GetFMUstate", ctypes.byref(state))
                elif op == "restore" and state.value:
                    fmu.call("fmi2SetFMUstate", state)
                all_reals_finite_when_ok(fmu)
            if state.value:
                fmu.call("fmi2FreeFMUstate", ctypes.byref(state))

    run()
