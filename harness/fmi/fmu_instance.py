"""One FMU instance, addressed by variable names, with its log captured.

A thin layer over fmpy's FMU2Slave / FMU2Model (which load the binary and expose the raw fmi2
functions): name lookup, enumeration names, status codes instead of exceptions, and the log
messages kept as a list so that callers can report or assert them.
"""
from __future__ import annotations

import ctypes
import math
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fmpy import read_model_description
from fmpy.fmi2 import (FMU2Model, FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2LastSuccessfulTime)
from fmpy.fmi1 import calloc, free

from harness.archives import extract_fmu
from harness.errors import HarnessError
from harness.fmi.binaries import checked_identifier, elf_problem

STATUS_NAMES = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4


@dataclass
class LogMessage:
    status: int
    category: str
    text: str

    def __str__(self) -> str:
        return f"[{STATUS_NAMES[self.status]}] {self.text}"


@dataclass
class LogCollector:
    """fmi2 callbacks whose logger appends to this instance's messages.

    fmpy's native logger proxy (which formats printf arguments) keeps one logger for the whole
    process, so it is not used here: each instance keeps its own log. Messages arrive as the FMU
    formatted them; any printf arguments an FMU passes separately are not expanded."""
    messages: list[LogMessage] = field(default_factory=list)
    live_blocks: int = 0  # memory blocks the FMU allocated and has not freed yet (its instance, its states)

    def __post_init__(self) -> None:
        def log(env, instance_name, status, category, message):
            self.messages.append(LogMessage(status, (category or b"").decode(), (message or b"").decode()))

        def allocate(count, size):
            block = calloc(count, size)
            self.live_blocks += bool(block)
            return block

        def release(block):
            self.live_blocks -= bool(block)
            free(block)

        self._logger = fmi2CallbackLoggerTYPE(log)  # keep references: ctypes callbacks die with them
        self._allocate = fmi2CallbackAllocateMemoryTYPE(allocate)
        self._free = fmi2CallbackFreeMemoryTYPE(release)
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = self._logger
        self.callbacks.allocateMemory = self._allocate
        self.callbacks.freeMemory = self._free


def _first_line(error: Exception) -> str:
    lines = str(error).strip().splitlines()
    return lines[0] if lines else type(error).__name__


def read_fmi2_description(path: Path):
    """fmpy's model description of an FMI 2.0 FMU; a one-line HarnessError for anything else."""
    import xml.etree.ElementTree as ET
    from harness.archives import open_archive, read_member
    if not path.is_file():
        raise HarnessError(f"{path}: no such FMU file")
    with open_archive(path, str(path)) as archive:
        if "modelDescription.xml" not in archive.namelist():
            raise HarnessError(f"{path}: not an FMU (no modelDescription.xml)")
        text = read_member(archive, "modelDescription.xml", str(path))
    try:
        version = ET.fromstring(text).get("fmiVersion")
    except ET.ParseError as error:
        raise HarnessError(f"{path}: modelDescription.xml is not well-formed XML ({error})") from None
    if version != "2.0":
        raise HarnessError(f"{path}: an FMI {version} FMU; this harness runs FMI 2.0 FMUs")
    try:
        return read_model_description(str(path))
    except Exception as error:  # fmpy raises plain exceptions for invalid files
        raise HarnessError(f"{path}: invalid modelDescription.xml ({_first_line(error)})") from None


# A decimal number as C and JSON write it, in ASCII (Python's float() also takes "1_000" and other
# scripts' digits), or the names of infinity and NaN, which the FMU's range check then refuses.
_NUMBER_TEXT = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf|infinity|nan)", re.IGNORECASE | re.ASCII)


def is_number_text(text: str) -> bool:
    return _NUMBER_TEXT.fullmatch(text.strip()) is not None


def _number(name: str, value) -> float:
    """A start value as a float: numbers and numeric strings; NaN and infinity pass through, for
    the FMU's own range check to refuse with its message."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value) if not isinstance(value, int) or abs(value) < 2**1023 else math.inf
    if isinstance(value, str) and is_number_text(value):
        return float(value)
    raise HarnessError(f"{name} = {value!r} is not a number")


_GETTER = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p)
_STEPPER = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int)


class RawCalls:
    """fmi2GetReal, fmi2GetInteger and fmi2DoStep on their own prototypes (the same entry points as
    fmpy's): arrays go in as plain addresses, so a loop can write straight into numpy rows."""

    def __init__(self, dll, component) -> None:
        def address(function) -> int:
            return ctypes.cast(function, ctypes.c_void_p).value
        self.component = ctypes.c_void_p(component)
        self.get_real = _GETTER(address(dll.fmi2GetReal))
        self.get_integer = _GETTER(address(dll.fmi2GetInteger))
        self.set_real = _GETTER(address(dll.fmi2SetReal))  # same shape: (component, vr[], n, value[])
        self.set_integer = _GETTER(address(dll.fmi2SetInteger))
        self.do_step = _STEPPER(address(dll.fmi2DoStep))


class FmuInstance:
    """An instantiated FMU (Co-Simulation by default, Model Exchange with kind="ME")."""

    def __init__(self, fmu: str | Path, kind: str = "CS", name: str = "instance", logging_on: bool = False,
                 unzipdir: str | None = None):
        self.path = Path(fmu)
        self.fmu = None
        self._raw = None
        self._items: dict[str, dict[str, int]] = {}
        self.model_description = read_fmi2_description(self.path)
        self._extracted = unzipdir is None  # a folder this instance made, and removes when freed
        self.unzipdir = unzipdir or str(extract_fmu(self.path))
        try:
            self._load(kind, name, logging_on)
        except BaseException:
            self._remove_extracted()
            raise

    def _load(self, kind: str, name: str, logging_on: bool) -> None:
        self.variables = {v.name: v for v in self.model_description.modelVariables}
        self.log = LogCollector()
        interface = self.model_description.coSimulation if kind == "CS" else self.model_description.modelExchange
        if interface is None:
            raise HarnessError(f"{self.path}: the FMU does not support {kind}")
        identifier = checked_identifier(interface.modelIdentifier, str(self.path))
        library = Path(self.unzipdir) / "binaries" / "linux64" / f"{identifier}.so"
        if not library.is_file():
            raise HarnessError(f"{self.path}: no binary for this platform (binaries/linux64/{library.name} is missing)")
        problem = elf_problem(library)
        if problem:
            raise HarnessError(f"{self.path}: binaries/linux64/{library.name} {problem}")
        cls = FMU2Slave if kind == "CS" else FMU2Model
        try:
            fmu = cls(guid=self.model_description.guid, unzipDirectory=self.unzipdir,
                      modelIdentifier=interface.modelIdentifier, instanceName=name)
        except Exception as error:  # fmpy raises plain exceptions when the binary cannot be loaded
            raise HarnessError(f"{self.path}: cannot load {library.name} ({_first_line(error)})") from None
        try:
            fmu.instantiate(callbacks=self.log.callbacks, loggingOn=logging_on)
        except Exception:
            fmu.freeLibrary()
            raise HarnessError(f"{self.path}: fmi2Instantiate failed: {self.last_message()}") from None
        self.fmu = fmu
        self.kind = kind

    # ---- variables by name
    def reference(self, name: str) -> int:
        try:
            return self.variables[name].valueReference
        except KeyError:
            raise HarnessError(f"{self.path.name} has no variable {name!r}") from None

    def _enumeration_items(self, variable) -> dict[str, int]:
        items = self._items.get(variable.name)
        if items is None:
            items = self._items[variable.name] = {item.name: int(item.value) for item in variable.declaredType.items}
        return items

    def _encode(self, name: str, value) -> tuple[str, int | float]:
        """The value as the FMI type of the variable: a number for a Real (a numeric string is read),
        an integer in the 32-bit range for an Integer or Enumeration (an enumeration also by item
        name). Anything else is a HarnessError naming the variable, never a silent conversion."""
        variable = self.variables.get(name)
        if variable is None:
            raise HarnessError(f"{self.path.name} has no variable {name!r}")
        if variable.type == "Enumeration" and isinstance(value, str):
            items = self._enumeration_items(variable)
            if value in items:
                return "Integer", items[value]
            if not is_number_text(value):
                raise HarnessError(f"{name} = {value!r} is not one of {', '.join(items)}")
        number = _number(name, value)
        if variable.type == "Real":
            return "Real", number
        if not math.isfinite(number) or number != int(number):
            raise HarnessError(f"{name} = {value!r} is not an integer ({variable.type})")
        if not -2**31 <= number < 2**31:
            raise HarnessError(f"{name} = {value!r} is outside the 32-bit integer range of an FMI {variable.type}")
        return ("Boolean" if variable.type == "Boolean" else "Integer"), int(number)

    def set(self, **values) -> int:
        """Sets variables by name; returns the worst fmi2Status."""
        worst = OK
        raw = self.raw
        for name, value in values.items():
            kind, encoded = self._encode(name, value)
            vr = ctypes.c_uint(self.reference(name))
            if kind == "Real":
                status = raw.set_real(raw.component, ctypes.byref(vr), 1, ctypes.byref(ctypes.c_double(encoded)))
            elif kind == "Boolean":
                status = self.call("fmi2SetBoolean", ctypes.byref(vr), 1, ctypes.byref(ctypes.c_int(encoded)))
            else:
                status = raw.set_integer(raw.component, ctypes.byref(vr), 1, ctypes.byref(ctypes.c_int(encoded)))
            worst = max(worst, status)
        return worst

    def get(self, *names: str) -> list[float]:
        values = []
        for name in names:
            variable = self.variables.get(name)
            if variable is None:
                raise HarnessError(f"{self.path.name} has no variable {name!r}")
            vr = (ctypes.c_uint * 1)(variable.valueReference)
            if variable.type == "Real":
                out = (ctypes.c_double * 1)()
                status = self.call("fmi2GetReal", vr, 1, out)
            else:
                out = (ctypes.c_int * 1)()
                status = self.call("fmi2GetInteger", vr, 1, out)
            if status > DISCARD:
                raise HarnessError(f"fmi2Get of {name} returned {STATUS_NAMES[status]}: {self.last_message()}")
            values.append(out[0])
        return values

    @property
    def raw(self) -> "RawCalls":
        """Hot-loop entry points with plain-address prototypes, made once per instance."""
        if self._raw is None:
            self._raw = RawCalls(self.fmu.dll, self.fmu.component)
        return self._raw

    def call(self, function: str, *args) -> int:
        """A raw fmi2 call by name, returning its status (fmpy's wrappers raise instead)."""
        # As c_void_p: for a function fmpy did not declare (a CS function on an ME instance) ctypes
        # would otherwise pass the handle as a 32-bit int.
        return getattr(self.fmu.dll, function)(self.raw.component, *args)

    # ---- life cycle
    def initialize(self, start_time: float = 0.0, **start_values) -> None:
        self._require(self.call("fmi2SetupExperiment", 0, 0.0, start_time, 0, 0.0), "fmi2SetupExperiment")
        self._require(self.set(**start_values), "setting start values")
        self._require(self.call("fmi2EnterInitializationMode"), "fmi2EnterInitializationMode")
        self._require(self.call("fmi2ExitInitializationMode"), "fmi2ExitInitializationMode")

    def do_step(self, t: float, H: float) -> int:
        return self.call("fmi2DoStep", t, H, 1)

    def last_successful_time(self) -> float:
        value = ctypes.c_double()
        self.call("fmi2GetRealStatus", fmi2LastSuccessfulTime, ctypes.byref(value))
        return value.value

    def output_derivatives(self, *names: str) -> np.ndarray:
        n = len(names)
        vrs = (ctypes.c_uint * n)(*[self.reference(name) for name in names])
        orders = (ctypes.c_int * n)(*([1] * n))
        out = (ctypes.c_double * n)()
        self._require(self.call("fmi2GetRealOutputDerivatives", vrs, n, orders, out), "fmi2GetRealOutputDerivatives")
        return np.array(out[:])

    def set_input_derivatives(self, **slopes: float) -> int:
        n = len(slopes)
        vrs = (ctypes.c_uint * n)(*[self.reference(name) for name in slopes])
        orders = (ctypes.c_int * n)(*([1] * n))
        values = (ctypes.c_double * n)(*slopes.values())
        return self.call("fmi2SetRealInputDerivatives", vrs, n, orders, values)

    # ---- FMU state
    def get_state(self) -> ctypes.c_void_p:
        state = ctypes.c_void_p()
        self._require(self.call("fmi2GetFMUstate", ctypes.byref(state)), "fmi2GetFMUstate")
        return state

    def set_state(self, state: ctypes.c_void_p) -> None:
        self._require(self.call("fmi2SetFMUstate", state), "fmi2SetFMUstate")

    def free_state(self, state: ctypes.c_void_p) -> None:
        self._require(self.call("fmi2FreeFMUstate", ctypes.byref(state)), "fmi2FreeFMUstate")

    def serialize(self, state: ctypes.c_void_p) -> bytes:
        size = ctypes.c_size_t()
        self._require(self.call("fmi2SerializedFMUstateSize", state, ctypes.byref(size)), "fmi2SerializedFMUstateSize")
        buffer = ctypes.create_string_buffer(size.value)
        self._require(self.call("fmi2SerializeFMUstate", state, buffer, size), "fmi2SerializeFMUstate")
        return buffer.raw

    def deserialize(self, data: bytes) -> ctypes.c_void_p:
        state = ctypes.c_void_p()
        buffer = ctypes.create_string_buffer(bytes(data), len(data))
        self._require(self.call("fmi2DeSerializeFMUstate", buffer, len(data), ctypes.byref(state)),
                      "fmi2DeSerializeFMUstate")
        return state

    # ---- log
    def last_message(self) -> str:
        return self.log.messages[-1].text if self.log.messages else "(no log message)"

    def _require(self, status: int, what: str) -> None:
        if status > WARNING:
            raise HarnessError(f"{self.path.name}: {what} returned {STATUS_NAMES[status]}: {self.last_message()}")

    def free(self) -> None:
        if self.fmu is not None:
            self.fmu.freeInstance()
            self.fmu = None
        self._remove_extracted()

    def _remove_extracted(self) -> None:
        if self._extracted:
            shutil.rmtree(self.unzipdir, ignore_errors=True)
            self._extracted = False

    def __enter__(self) -> "FmuInstance":
        return self

    def __exit__(self, *exc) -> None:
        self.free()
