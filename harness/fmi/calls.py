"""The C functions of one loaded FMU binary, called in one shape for FMI 2.0 and FMI 3.0.

The two versions name their functions differently and FMI 3.0 adds arguments: every get and set
takes the number of values after the values, fmi3DoStep hands back its flags and the last
successful time through pointers, and FMI 3.0 has no input derivatives. Everything the harness
calls is listed once per version here (FUNCTIONS, TYPES); the loops (the recorder, the master)
call get_real, set_real and do_step with FMI 2.0's argument lists, which for FMI 3.0 are thin
adapters over the binary's own functions.
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass
from functools import partial

from harness.errors import HarnessError

VERSIONS = ("2.0", "3.0")

# role -> function name, per version
FUNCTIONS = {
    "2.0": dict(reset="fmi2Reset", exit_initialization="fmi2ExitInitializationMode",
                get_state="fmi2GetFMUstate", set_state="fmi2SetFMUstate", free_state="fmi2FreeFMUstate",
                state_size="fmi2SerializedFMUstateSize", serialize="fmi2SerializeFMUstate",
                deserialize="fmi2DeSerializeFMUstate", output_derivatives="fmi2GetRealOutputDerivatives",
                input_derivatives="fmi2SetRealInputDerivatives", do_step="fmi2DoStep",
                continuous_time_mode="fmi2EnterContinuousTimeMode", set_time="fmi2SetTime",
                set_states="fmi2SetContinuousStates", derivatives="fmi2GetDerivatives",
                directional="fmi2GetDirectionalDerivative"),
    "3.0": dict(reset="fmi3Reset", exit_initialization="fmi3ExitInitializationMode",
                get_state="fmi3GetFMUState", set_state="fmi3SetFMUState", free_state="fmi3FreeFMUState",
                state_size="fmi3SerializedFMUStateSize", serialize="fmi3SerializeFMUState",
                deserialize="fmi3DeserializeFMUState", output_derivatives="fmi3GetOutputDerivatives",
                input_derivatives=None, do_step="fmi3DoStep",
                continuous_time_mode="fmi3EnterContinuousTimeMode", set_time="fmi3SetTime",
                set_states="fmi3SetContinuousStates", derivatives="fmi3GetContinuousStateDerivatives",
                directional="fmi3GetDirectionalDerivative"),
}


@dataclass(frozen=True)
class ScalarType:
    """How a variable type of the model description travels through the C API."""
    c_type: type
    setter: str
    getter: str
    smallest: int | None = None  # integer range; None for a float
    largest: int | None = None

    @property
    def is_float(self) -> bool:
        return self.smallest is None


_INT32 = (-2**31, 2**31 - 1)
_INT64 = (-2**63, 2**63 - 1)
TYPES = {
    "2.0": {"Real": ScalarType(ctypes.c_double, "fmi2SetReal", "fmi2GetReal"),
            "Integer": ScalarType(ctypes.c_int, "fmi2SetInteger", "fmi2GetInteger", *_INT32),
            "Enumeration": ScalarType(ctypes.c_int, "fmi2SetInteger", "fmi2GetInteger", *_INT32),
            "Boolean": ScalarType(ctypes.c_int, "fmi2SetBoolean", "fmi2GetBoolean", 0, 1)},
    "3.0": {"Float64": ScalarType(ctypes.c_double, "fmi3SetFloat64", "fmi3GetFloat64"),
            "Float32": ScalarType(ctypes.c_float, "fmi3SetFloat32", "fmi3GetFloat32"),
            "Int32": ScalarType(ctypes.c_int32, "fmi3SetInt32", "fmi3GetInt32", *_INT32),
            "Int64": ScalarType(ctypes.c_int64, "fmi3SetInt64", "fmi3GetInt64", *_INT64),
            "UInt64": ScalarType(ctypes.c_uint64, "fmi3SetUInt64", "fmi3GetUInt64", 0, 2**64 - 1),
            "Enumeration": ScalarType(ctypes.c_int64, "fmi3SetInt64", "fmi3GetInt64", *_INT64),
            "Boolean": ScalarType(ctypes.c_bool, "fmi3SetBoolean", "fmi3GetBoolean", 0, 1)},
}
FLOAT_TYPES = ("Real", "Float64", "Float32")


def is_float(variable) -> bool:
    """A Real (FMI 2.0) or a Float64/Float32 (FMI 3.0) variable of fmpy's model description."""
    return variable.type in FLOAT_TYPES


def scalar_type(version: str, variable) -> ScalarType:
    try:
        return TYPES[version][variable.type]
    except KeyError:
        raise HarnessError(f"variable {variable.name!r} has type {variable.type}, which this harness does not "
                           f"read or write in FMI {version}") from None


_ADDRESS = ctypes.c_void_p
_STATUS = ctypes.c_int
# (instance, value references, count, values[, count of values])
_VALUES2 = ctypes.CFUNCTYPE(_STATUS, _ADDRESS, _ADDRESS, ctypes.c_size_t, _ADDRESS)
_VALUES3 = ctypes.CFUNCTYPE(_STATUS, _ADDRESS, _ADDRESS, ctypes.c_size_t, _ADDRESS, ctypes.c_size_t)
_STEP2 = ctypes.CFUNCTYPE(_STATUS, _ADDRESS, ctypes.c_double, ctypes.c_double, ctypes.c_int)
_STEP3 = ctypes.CFUNCTYPE(_STATUS, _ADDRESS, ctypes.c_double, ctypes.c_double, ctypes.c_bool, _ADDRESS, _ADDRESS,
                          _ADDRESS, _ADDRESS)
# (instance, value references, count, orders, values[, count of values])
_DERIVATIVES2 = ctypes.CFUNCTYPE(_STATUS, _ADDRESS, _ADDRESS, ctypes.c_size_t, _ADDRESS, _ADDRESS)
_DERIVATIVES3 = ctypes.CFUNCTYPE(_STATUS, _ADDRESS, _ADDRESS, ctypes.c_size_t, _ADDRESS, _ADDRESS, ctypes.c_size_t)
# (instance, unknowns, count, knowns, count, seed[, count], sensitivity[, count])
_DIRECTIONAL2 = ctypes.CFUNCTYPE(_STATUS, _ADDRESS, _ADDRESS, ctypes.c_size_t, _ADDRESS, ctypes.c_size_t, _ADDRESS,
                                 _ADDRESS)
_DIRECTIONAL3 = ctypes.CFUNCTYPE(_STATUS, _ADDRESS, _ADDRESS, ctypes.c_size_t, _ADDRESS, ctypes.c_size_t, _ADDRESS,
                                 ctypes.c_size_t, _ADDRESS, ctypes.c_size_t)


# The functions whose arguments have the same shape in both versions, after the instance.
_SAME_SHAPE = {"reset": (), "exit_initialization": (), "get_state": (_ADDRESS,), "set_state": (_ADDRESS,),
               "free_state": (_ADDRESS,), "state_size": (_ADDRESS, _ADDRESS),
               "serialize": (_ADDRESS, _ADDRESS, ctypes.c_size_t), "deserialize": (_ADDRESS, ctypes.c_size_t, _ADDRESS),
               "continuous_time_mode": (), "set_time": (ctypes.c_double,), "set_states": (_ADDRESS, ctypes.c_size_t),
               "derivatives": (_ADDRESS, ctypes.c_size_t)}


def function_address(dll, name: str) -> int:
    return ctypes.cast(getattr(dll, name), ctypes.c_void_p).value


class Calls:
    """The entry points of one instance with plain-address prototypes (arrays go in as addresses,
    so a loop can write straight into numpy rows), in FMI 2.0's shapes for both versions."""

    def __init__(self, version: str, dll, component: int) -> None:
        self.version = version
        self.dll = dll
        self.component = ctypes.c_void_p(component)
        self.names = FUNCTIONS[version]
        self.float_type_name = "Real" if version == "2.0" else "Float64"
        self.float_type = TYPES[version][self.float_type_name]
        self.last_time = ctypes.c_double(0.0)  # fmi3DoStep's lastSuccessfulTime
        self.step_flags = None  # fmi3DoStep's eventHandlingNeeded, terminateSimulation, earlyReturn
        self._roles: dict[str, object] = {}
        self._values: dict[str, object] = {}
        self.get_real = self.values(self.float_type, False)
        self.set_real = self.values(self.float_type, True)
        if version == "2.0":
            self.do_step = _STEP2(function_address(dll, "fmi2DoStep"))
        else:
            step = _STEP3(function_address(dll, "fmi3DoStep"))
            flags = (ctypes.c_bool * 3)()
            event, terminate, early = (ctypes.addressof(flags) + k * ctypes.sizeof(ctypes.c_bool) for k in range(3))
            last = ctypes.addressof(self.last_time)
            self._keep = step
            self.step_flags = flags
            self.do_step = lambda c, t, h, no_prior: step(c, t, h, bool(no_prior), event, terminate, early, last)

    def __call__(self, role: str, *args) -> int:
        """The function of a role in _SAME_SHAPE (reset, the FMU state functions, ...) on this instance."""
        function = self._roles.get(role)
        if function is None:
            prototype = ctypes.CFUNCTYPE(_STATUS, _ADDRESS, *_SAME_SHAPE[role])
            function = self._roles[role] = prototype(function_address(self.dll, self.names[role]))
        return function(self.component, *args)

    def function(self, name: str) -> int:
        """The address of a C function of this binary."""
        return function_address(self.dll, name)

    def values(self, scalar: ScalarType, setting: bool):
        """fmiNSet<Type> or fmiNGet<Type> as f(instance, vrs, n, values), made once per function."""
        name = scalar.setter if setting else scalar.getter
        made = self._values.get(name)
        if made is None:
            if self.version == "2.0":
                made = _VALUES2(function_address(self.dll, name))
            else:
                function = _VALUES3(function_address(self.dll, name))
                made = lambda c, vrs, n, values: function(c, vrs, n, values, n)  # noqa: E731
            self._values[name] = made
        return made

    def reader(self, scalar: ScalarType, vrs, n: int):
        """A call reading the n variables `vrs` of one type into the array at an address."""
        read = self.values(scalar, False)
        return partial(read, self.component, vrs, n)

    def output_derivatives(self):
        """f(instance, vrs, n, orders, values) -> status."""
        name = self.names["output_derivatives"]
        if self.version == "2.0":
            return _DERIVATIVES2(function_address(self.dll, name))
        function = _DERIVATIVES3(function_address(self.dll, name))
        return lambda c, vrs, n, orders, values: function(c, vrs, n, orders, values, n)

    def directional(self):
        """f(instance, unknowns, n_unknown, knowns, n_known, seed, sensitivity) -> status: the Jacobian
        of the unknowns with respect to the knowns times the seed."""
        name = self.names["directional"]
        if self.version == "2.0":
            return _DIRECTIONAL2(function_address(self.dll, name))
        function = _DIRECTIONAL3(function_address(self.dll, name))
        return lambda c, unknowns, n_unknown, knowns, n_known, seed, sensitivity: function(
            c, unknowns, n_unknown, knowns, n_known, seed, n_known, sensitivity, n_unknown)

    def input_derivatives(self):
        """f(instance, vrs, n, orders, values) -> status, or None: FMI 3.0 has no input derivatives."""
        name = self.names["input_derivatives"]
        return _DERIVATIVES2(function_address(self.dll, name)) if name else None
