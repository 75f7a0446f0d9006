"""One FMU instance (FMI 2.0 or 3.0), addressed by variable names, with its log captured.

A thin layer over fmpy's FMU2Slave / FMU2Model / FMU3Slave / FMU3Model (which load the binary and
instantiate it): name lookup, enumeration names, status codes instead of exceptions, and the log
messages kept as a list so that callers can report or assert them. What differs between the
versions is in harness/fmi/calls.py.
"""
from __future__ import annotations

import ctypes
import math
import os
import re
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import ClassVar
from xml.etree import ElementTree

import numpy as np
from fmpy import read_model_description
from fmpy.fmi2 import (FMU2Model, FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2LastSuccessfulTime)
from fmpy.fmi3 import FMU3Model, FMU3Slave
from fmpy.fmi1 import calloc, free

from harness.archives import extract_fmu, remove_folder
from harness.errors import HarnessError, first_problem
from harness.fmi.binaries import checked_identifier, elf_problem
from harness.fmi.calls import FUNCTIONS, TYPES, Calls, scalar_type
from harness.fmi.methods import FREE_MOTION_ONLY, METHODS
from harness.interrupts import called_from_c, held

# The x86_64 Linux binary's folder, per FMI version.
PLATFORM_FOLDERS = {"2.0": "linux64", "3.0": "x86_64-linux"}

STATUS_NAMES = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4


@dataclass
class LogMessage:
    status: int
    category: str
    text: str

    def __str__(self) -> str:
        return f"[{STATUS_NAMES[self.status]}] {self.text}"


# libc's calloc and free as the FMU's memory functions: C calls them without running any Python, so no
# exception (an interrupt) can hand the FMU a block that is none
_LIBC_CALLOC = ctypes.cast(calloc, ctypes.c_void_p).value
_LIBC_FREE = ctypes.cast(free, ctypes.c_void_p).value


@dataclass
class LogCollector:
    """Callbacks whose logger appends to this instance's messages: fmi2's logger and memory
    functions, and fmi3's log-message callback (FMI 3.0 has no memory callbacks).

    fmpy's native logger proxy (which formats printf arguments) keeps one logger for the whole
    process, so it is not used here: each instance keeps its own log. Messages arrive as the FMU
    formatted them; any printf arguments an FMU passes separately are not expanded.

    The memory functions are libc's own. With `counting` set (tests set it on the class) they are
    Python functions that also count the blocks the FMU holds (`live_blocks`)."""
    messages: list[LogMessage] = field(default_factory=list)
    live_blocks: int = 0  # with `counting`: memory blocks the FMU allocated and has not freed yet
    counting: ClassVar[bool] = False

    def __post_init__(self) -> None:
        @called_from_c
        def log(env, instance_name, status, category, message):
            self.messages.append(LogMessage(status, (category or b"").decode(), (message or b"").decode()))

        @called_from_c
        def allocate(count, size):
            block = calloc(count, size)
            self.live_blocks += bool(block)
            return block

        @called_from_c
        def release(block):
            self.live_blocks -= bool(block)
            free(block)

        self._logger = fmi2CallbackLoggerTYPE(log)  # keep references: ctypes callbacks die with them
        self._allocate = fmi2CallbackAllocateMemoryTYPE(allocate if self.counting else _LIBC_CALLOC)
        self._free = fmi2CallbackFreeMemoryTYPE(release if self.counting else _LIBC_FREE)
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = self._logger
        self.callbacks.allocateMemory = self._allocate
        self.callbacks.freeMemory = self._free

    @called_from_c
    def fmi3_log_message(self, environment, status, category, message) -> None:
        self.messages.append(LogMessage(status, (category or b"").decode(), (message or b"").decode()))


def fmi_version(path: Path) -> str:
    """The fmiVersion of an FMU file ("2.0" or "3.0"); a one-line HarnessError for anything else."""
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
    if version is None:
        raise HarnessError(f"{path}: modelDescription.xml has no fmiVersion attribute")
    if version not in PLATFORM_FOLDERS:
        raise HarnessError(f"{path}: an FMI {version} FMU; this harness runs FMI 2.0 and 3.0 FMUs")
    return version


def read_description(path: Path):
    """fmpy's model description of an FMI 2.0 or 3.0 FMU; a one-line HarnessError for anything else."""
    fmi_version(path)
    try:
        description = read_model_description(str(path))
    except Exception as error:  # fmpy raises plain exceptions for invalid files
        raise HarnessError(f"{path}: invalid modelDescription.xml ({first_problem(error)})") from None
    if description.fmiVersion == "3.0":
        _read_intermediate_updates(path, description)
    return description


def _read_intermediate_updates(path: Path, description) -> None:
    """The variables' intermediateUpdate attribute, which fmpy's reader leaves at its default (false)."""
    import zipfile
    try:
        if Path(path).is_dir():
            text = (Path(path) / "modelDescription.xml").read_bytes()
        elif zipfile.is_zipfile(path):
            with zipfile.ZipFile(path) as archive:
                text = archive.read("modelDescription.xml")
        else:
            text = Path(path).read_bytes()
        variables = ElementTree.fromstring(text).find("ModelVariables")
    except (OSError, KeyError, ElementTree.ParseError, zipfile.BadZipFile):
        return  # fmpy read it: whatever keeps this from reading it again leaves the attribute false
    flagged = {element.get("name") for element in (variables if variables is not None else [])
               if element.get("intermediateUpdate") == "true"}
    for variable in description.modelVariables:
        variable.intermediateUpdate = variable.name in flagged


def float_start_values(description, overrides: dict | None = None) -> dict[str, float]:
    """A model description's float start values, with the numeric values of `overrides` (a scene's
    start values; item names and other text are left out) on top."""
    from harness.fmi.calls import is_float
    values = {v.name: float(v.start) for v in description.modelVariables if is_float(v) and v.start is not None}
    values.update({k: float(v) for k, v in (overrides or {}).items() if not isinstance(v, str)})
    return values


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


def exact_integer(name: str, value) -> int:
    """An integer start value exactly as written (a numeric string is read as a decimal, not through
    a double, so 9007199254740993 stays itself and 5.0000000000000001 is not 5); a HarnessError for
    anything that is not a whole number."""
    from decimal import Decimal, InvalidOperation
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(value, float) and math.isfinite(value) and value == int(value):
        return int(value)
    if isinstance(value, str) and is_number_text(value):
        try:
            number = Decimal(value.strip())
        except InvalidOperation:
            number = None
        if number is not None and number.is_finite() and abs(number.adjusted()) < 400 \
                and number == number.to_integral_value():
            return int(number)
    raise HarnessError(f"{name} = {value!r} is not an integer")


@dataclass(frozen=True)
class AskedInputs:
    """FMI 3.0 Co-Simulation inputs the importer sets in intermediate updates: `callback` (the address of a C
    fmi3IntermediateUpdateCallback) is called with `environment` (an address) as the instance environment,
    and the inputs `references` are registered in requiredIntermediateVariables."""
    callback: int
    environment: int
    references: tuple[int, ...]


def _instantiate_asking(fmu: FMU3Slave, logging_on: bool, log_message, early_return: bool,
                        asked: AskedInputs) -> None:
    """fmi3InstantiateCoSimulation with an instance environment of the caller's, which fmpy's
    instantiate leaves NULL, so that one C callback serves every instance."""
    from fmpy.fmi3 import fmi3IntermediateUpdateCallback, fmi3LogMessageCallback, fmi3ValueReference
    fmu.logMessage = fmi3LogMessageCallback(log_message)  # kept on the object, alive as long as the instance
    fmu.intermediateUpdate = fmi3IntermediateUpdateCallback(asked.callback)
    fmu.requiredIntermediateVariables = (fmi3ValueReference * len(asked.references))(*asked.references)
    resources = os.path.join(fmu.unzipDirectory, "resources") + os.path.sep  # as fmpy gives it
    fmu.component = fmu.fmi3InstantiateCoSimulation(
        fmu.instanceName.encode(), fmu.guid.encode(), resources.encode(), False, logging_on, False, early_return,
        fmu.requiredIntermediateVariables, len(asked.references), ctypes.c_void_p(asked.environment),
        fmu.logMessage, fmu.intermediateUpdate)
    if not fmu.component:
        raise Exception("fmi3InstantiateCoSimulation returned NULL")


class FmuInstance:
    """An instantiated FMU of either version (Co-Simulation by default, Model Exchange with kind="ME")."""

    def __init__(self, fmu: str | Path, kind: str = "CS", name: str = "instance", logging_on: bool = False,
                 unzipdir: str | None = None, description=None, template: "FmuInstance | None" = None,
                 early_return: bool = False, asked_inputs: AskedInputs | None = None):
        """`unzipdir`, `description` and `template` (an instance of the same FMU and kind, whose loaded
        library and function table this one shares): what `SharedFmus` hands each further instance of
        an FMU; by default the instance makes its own. `early_return`: an FMI 3.0 Co-Simulation instance
        may end a step at an event (`returned_early`). `asked_inputs`: an FMI 3.0 Co-Simulation instance
        asks for these inputs in intermediate updates."""
        self.early_return = early_return
        self.asked_inputs = asked_inputs
        self._template = template
        self.path = Path(fmu)
        self.fmu = None
        self._raw: Calls | None = None
        self._items: dict[str, dict[str, int]] = {}
        self.model_description = description if description is not None else read_description(self.path)
        self.version = self.model_description.fmiVersion
        self.unzipdir, self._extracted = unzipdir, False  # _extracted: a folder this instance made, removed when freed
        try:
            if unzipdir is None:  # (a folder an interrupt keeps from being stored here is removed at exit)
                self.unzipdir, self._extracted = str(extract_fmu(self.path, (PLATFORM_FOLDERS[self.version],))), True
            self._load(kind, name, logging_on)
        except BaseException:
            self.free()
            raise

    @property
    def prefix(self) -> str:
        """fmi2 or fmi3: the prefix of this instance's C functions, for messages."""
        return "fmi2" if self.version == "2.0" else "fmi3"

    def _load(self, kind: str, name: str, logging_on: bool) -> None:
        self.variables = {v.name: v for v in self.model_description.modelVariables}
        self.log = LogCollector()
        interface = self.model_description.coSimulation if kind == "CS" else self.model_description.modelExchange
        if interface is None:
            raise HarnessError(f"{self.path}: the FMU does not support {kind}")
        identifier = checked_identifier(interface.modelIdentifier, str(self.path))
        folder = f"binaries/{PLATFORM_FOLDERS[self.version]}"
        library = Path(self.unzipdir) / folder / f"{identifier}.so"
        if not library.is_file():
            raise HarnessError(f"{self.path}: no binary for this platform ({folder}/{library.name} is missing)")
        problem = elf_problem(library)
        if problem:
            raise HarnessError(f"{self.path}: {folder}/{library.name} {problem}")
        fmi3 = self.version == "3.0"
        cls = {(False, "CS"): FMU2Slave, (False, "ME"): FMU2Model, (True, "CS"): FMU3Slave, (True, "ME"): FMU3Model}
        with held():  # the library loaded and instantiated is this object's, which frees it
            try:
                if self._template is not None and self._template.kind == kind:
                    fmu = _sharing(self._template.loaded, str(library), name)
                else:
                    fmu = cls[fmi3, kind](guid=self.model_description.guid, unzipDirectory=self.unzipdir,
                                          modelIdentifier=interface.modelIdentifier, instanceName=name)
            except Exception as error:  # fmpy raises plain exceptions when the binary cannot be loaded
                raise HarnessError(f"{self.path}: cannot load {library.name} ({first_problem(error)})") from None
            self.loaded = fmu  # what a further instance of this FMU may share (`template`)
            self.library = library
            try:
                if fmi3 and kind == "CS" and self.asked_inputs is not None:
                    _instantiate_asking(fmu, logging_on, self.log.fmi3_log_message, self.early_return,
                                        self.asked_inputs)
                elif fmi3:
                    options = {"earlyReturnAllowed": True} if self.early_return and kind == "CS" else {}
                    fmu.instantiate(loggingOn=logging_on, logMessage=self.log.fmi3_log_message, **options)
                else:
                    fmu.instantiate(callbacks=self.log.callbacks, loggingOn=logging_on)
            except Exception:
                fmu.freeLibrary()
                what = "fmi3Instantiate" + ("CoSimulation" if kind == "CS" else "ModelExchange") if fmi3 \
                    else "fmi2Instantiate"
                raise HarnessError(f"{self.path}: {what} failed: {self.last_message()}") from None
            self.fmu = fmu
            self.kind = kind

    # ---- variables by name
    def reference(self, name: str) -> int:
        try:
            return self.variables[name].valueReference
        except KeyError:
            raise HarnessError(f"{self.path.name} has no variable {name!r}") from None

    def _variable(self, name: str):
        variable = self.variables.get(name)
        if variable is None:
            raise HarnessError(f"{self.path.name} has no variable {name!r}")
        return variable

    def _enumeration_items(self, variable) -> dict[str, int]:
        items = self._items.get(variable.name)
        if items is None:
            items = self._items[variable.name] = {item.name: int(item.value) for item in variable.declaredType.items}
        return items

    def encode(self, name: str, value) -> int | float:
        """The value as the FMI type of the variable: a number for a float (a numeric string is read),
        an integer in the type's range for an integer or enumeration (an enumeration also by item
        name, a Boolean also as true or false), read exactly. Anything else is a HarnessError naming
        the variable, never a silent conversion."""
        variable = self._variable(name)
        if variable.type == "Enumeration" and isinstance(value, str):
            items = self._enumeration_items(variable)
            if value in items:
                return items[value]
            if not is_number_text(value):
                raise HarnessError(f"{name} = {value!r} is not one of {', '.join(items)}")
        if variable.type == "Boolean" and isinstance(value, (str, bool)):
            words = {"true": 1, "false": 0}
            if isinstance(value, bool) or value.strip().lower() in words:
                return int(value) if isinstance(value, bool) else words[value.strip().lower()]
        scalar = scalar_type(self.version, variable)
        if scalar.is_float:
            return _number(name, value)
        try:
            number = exact_integer(name, value)
        except HarnessError:
            raise HarnessError(f"{name} = {value!r} is not an integer ({variable.type})") from None
        if not scalar.smallest <= number <= scalar.largest:
            raise HarnessError(f"{name} = {value!r} is outside the range of an FMI {self.version} {variable.type} "
                               f"[{scalar.smallest}, {scalar.largest}]")
        return int(number)

    def set(self, **values) -> int:
        """Sets variables by name; returns the worst status."""
        worst = OK
        raw = self.raw
        for name, value in values.items():
            encoded = self.encode(name, value)
            scalar = scalar_type(self.version, self.variables[name])
            vr = ctypes.c_uint(self.reference(name))
            status = raw.values(scalar, True)(raw.component, ctypes.byref(vr), 1, ctypes.byref(scalar.c_type(encoded)))
            worst = max(worst, status)
        return worst

    def get(self, *names: str) -> list[float]:
        values = []
        for name in names:
            variable = self._variable(name)
            scalar = scalar_type(self.version, variable)
            vr = (ctypes.c_uint * 1)(variable.valueReference)
            out = (scalar.c_type * 1)()
            status = self.raw.values(scalar, False)(self.raw.component, vr, 1, out)
            if status > DISCARD:
                raise HarnessError(f"{self.prefix}Get of {name} returned {STATUS_NAMES[status]}: {self.last_message()}")
            values.append(out[0] if scalar.is_float else int(out[0]))
        return values

    def recorded_outputs(self, names: list[str]) -> tuple[list[str], list[str]]:
        """The outputs `names` split into the float ones (Real, Float64) and the integer ones, which
        the harness records; any other type (Float32, Boolean, String, ...) is refused by name."""
        floats, integers = [], []
        for name in names:
            variable = self._variable(name)
            scalar = TYPES[self.version].get(variable.type)
            if scalar is self.raw.float_type:
                floats.append(name)
            elif scalar is not None and not scalar.is_float and variable.type != "Boolean":
                integers.append(name)
            else:
                raise HarnessError(f"{self.path.name}: output {name!r} is a {variable.type}; the harness records "
                                   f"{self.raw.float_type_name} and integer outputs")
        return floats, integers

    def integer_reader(self, names: list[str]) -> "IntegerReader":
        """One call reading the integer variables `names` (all of one type: FMI 3.0's counters are
        UInt64, FMI 2.0's Integer) into an array at an address."""
        # Integer and Enumeration (and FMI 3.0's Int64 and Enumeration) share their C type and function
        scalars = {scalar_type(self.version, self.variables[n]) for n in names}
        if len(scalars) > 1:
            types = sorted({self.variables[n].type for n in names})
            raise HarnessError(f"{self.path.name}: the integer outputs {', '.join(names)} are of several C types "
                               f"({', '.join(types)}); the harness records integers of one type")
        scalar = scalars.pop() if scalars else TYPES[self.version]["Integer" if self.version == "2.0" else "UInt64"]
        vrs = (ctypes.c_uint * max(len(names), 1))(*[self.reference(n) for n in names])
        return IntegerReader(np.dtype(scalar.c_type), self.raw.reader(scalar, vrs, len(names)), scalar.getter,
                             vrs, self.raw.function(scalar.getter))

    @property
    def raw(self) -> Calls:
        """Hot-loop entry points with plain-address prototypes, made once per instance."""
        if self._raw is None:
            self._raw = Calls(self.version, self.fmu.dll, self.fmu.component)
        return self._raw

    def call(self, function: str, *args) -> int:
        """A raw call by the C function's name, returning its status (fmpy's wrappers raise instead)."""
        # As c_void_p: for a function fmpy did not declare (a CS function on an ME instance) ctypes
        # would otherwise pass the handle as a 32-bit int.
        return getattr(self.fmu.dll, function)(self.raw.component, *args)

    @property
    def provides_directional_derivatives(self) -> bool:
        """The interface's capability flag (fmpy does not read FMI 3.0's, so it is read here)."""
        element = ElementTree.parse(Path(self.unzipdir) / "modelDescription.xml").getroot().find(
            "CoSimulation" if self.kind == "CS" else "ModelExchange")
        flag = "providesDirectionalDerivative" + ("" if self.version == "2.0" else "s")
        return element is not None and element.get(flag) in ("true", "1")

    def role(self, role: str, *args) -> int:
        """The function of a role (harness/fmi/calls.py: reset, get_state, ...) in this instance's version."""
        return self.raw(role, *args)

    # ---- life cycle
    def enter_initialization(self, start_time: float = 0.0, **start_values) -> None:
        """Start values set and Initialization Mode entered, at start_time."""
        if self.version == "2.0":
            self._require(self.call("fmi2SetupExperiment", 0, 0.0, ctypes.c_double(start_time), 0, 0.0),
                          "fmi2SetupExperiment")
            self._require(self.set(**start_values), "setting start values")
            self._require(self.call("fmi2EnterInitializationMode"), "fmi2EnterInitializationMode")
        else:  # FMI 3.0 sets start values before the experiment's times
            self._require(self.set(**start_values), "setting start values")
            enter = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_bool, ctypes.c_double, ctypes.c_double,
                                     ctypes.c_bool, ctypes.c_double)(
                ctypes.cast(self.fmu.dll.fmi3EnterInitializationMode, ctypes.c_void_p).value)
            self._require(enter(self.raw.component, False, 0.0, start_time, False, 0.0), "fmi3EnterInitializationMode")

    def exit_initialization(self) -> None:
        self._require(self.role("exit_initialization"), f"{self.prefix}ExitInitializationMode")

    def initialize(self, start_time: float = 0.0, **start_values) -> None:
        self.enter_initialization(start_time, **start_values)
        self.exit_initialization()

    def reset(self) -> None:
        self._require(self.role("reset"), f"{self.prefix}Reset")

    def do_step(self, t: float, H: float) -> int:
        return self.raw.do_step(self.raw.component, t, H, 1)

    def returned_early(self) -> bool:
        """Whether the last fmi3DoStep ended early, at an event (never, for FMI 2.0)."""
        flags = self.raw.step_flags
        return bool(flags is not None and flags[2])

    def work(self) -> int:
        """The integration's cost so far in right-hand-side evaluations: n_rhs plus, for the implicit
        methods, one per state for each Jacobian (n_jacobians; a Jacobian is one directional derivative
        per state, each about the price of a right-hand side)."""
        rhs, jacobians = self.get("n_rhs", "n_jacobians")
        states = sum(1 for v in self.model_description.modelVariables if v.derivative is not None)
        return int(rhs) + states * int(jacobians)

    def last_successful_time(self) -> float:
        if self.version == "3.0":
            return self.raw.last_time.value
        value = ctypes.c_double()
        self.call("fmi2GetRealStatus", fmi2LastSuccessfulTime, ctypes.byref(value))
        return value.value

    def output_derivatives(self, *names: str) -> np.ndarray:
        n = len(names)
        vrs = (ctypes.c_uint * n)(*[self.reference(name) for name in names])
        orders = (ctypes.c_int * n)(*([1] * n))
        out = (ctypes.c_double * n)()
        self._require(self.raw.output_derivatives()(self.raw.component, vrs, n, orders, out),
                      FUNCTIONS[self.version]["output_derivatives"])
        return np.array(out[:])

    def set_input_derivatives(self, **slopes: float) -> int:
        setter = self.raw.input_derivatives()
        if setter is None:
            raise HarnessError(f"{self.path.name} is an FMI {self.version} FMU, which takes no input derivatives")
        n = len(slopes)
        vrs = (ctypes.c_uint * n)(*[self.reference(name) for name in slopes])
        orders = (ctypes.c_int * n)(*([1] * n))
        values = (ctypes.c_double * n)(*slopes.values())
        return setter(self.raw.component, vrs, n, orders, values)

    # ---- FMU state
    def get_state(self) -> ctypes.c_void_p:
        state = ctypes.c_void_p()
        self._require(self.role("get_state", ctypes.byref(state)), FUNCTIONS[self.version]["get_state"])
        return state

    def set_state(self, state: ctypes.c_void_p) -> None:
        self._require(self.role("set_state", state), FUNCTIONS[self.version]["set_state"])

    def free_state(self, state: ctypes.c_void_p) -> None:
        self._require(self.role("free_state", ctypes.byref(state)), FUNCTIONS[self.version]["free_state"])

    def serialize(self, state: ctypes.c_void_p) -> bytes:
        size = ctypes.c_size_t()
        self._require(self.role("state_size", state, ctypes.byref(size)), FUNCTIONS[self.version]["state_size"])
        buffer = ctypes.create_string_buffer(size.value)
        self._require(self.role("serialize", state, buffer, size), FUNCTIONS[self.version]["serialize"])
        return buffer.raw

    def deserialize(self, data: bytes) -> ctypes.c_void_p:
        state = ctypes.c_void_p()
        buffer = ctypes.create_string_buffer(bytes(data), len(data))
        self._require(self.role("deserialize", buffer, len(data), ctypes.byref(state)),
                      FUNCTIONS[self.version]["deserialize"])
        return state

    # ---- log
    def last_message(self) -> str:
        return self.log.messages[-1].text if self.log.messages else "(no log message)"

    def _require(self, status: int, what: str) -> None:
        if status > WARNING:
            raise HarnessError(f"{self.path.name}: {what} returned {STATUS_NAMES[status]}: {self.last_message()}")

    def free(self) -> None:
        with held():  # an interrupt does not leave the instance or its folder half freed
            if self.fmu is not None:
                fmu, self.fmu = self.fmu, None
                fmu.freeInstance()
            if self._extracted:
                self._extracted = False
                remove_folder(self.unzipdir)

    def __enter__(self) -> "FmuInstance":
        return self

    def __exit__(self, *exc) -> None:
        self.free()


@dataclass(frozen=True)
class IntegerReader:
    dtype: np.dtype
    read: object  # read(address) -> status
    function: str  # the C function it calls, for messages
    vrs: object    # the value references, for a C loop
    address: int   # that function's address, for a C loop


def _sharing(loaded, library: str, name: str):
    """A new fmpy FMU object that shares `loaded`'s library and function table (fmpy builds the
    table by reflection, some milliseconds per instance). It takes one more reference to the
    library (the same handle: loaded once), which its freeInstance releases."""
    import copy
    fmu = copy.copy(loaded)
    fmu.library_reference = ctypes.CDLL(library)
    fmu.instanceName = name
    fmu.component = None
    return fmu


class SharedFmus:
    """One extraction and one model description per FMU file for all the instances made through it,
    so that instances of one FMU share one folder and one loaded library, also one run's after
    another's (the library stays loaded until `close()`). `close()` (after the instances are freed)
    removes the folders."""

    def __init__(self):
        self._extracted: dict[Path, tuple[str, object]] = {}
        self._templates: dict[tuple[Path, str], FmuInstance] = {}
        self._held: list[int] = []  # a reference of our own to each library the templates' tables point into

    def _extraction(self, fmu: str | Path) -> tuple[Path, str, object]:
        """The FMU's path as the key, its folder and its model description (extracted once)."""
        path = Path(fmu).resolve() if Path(fmu).exists() else Path(fmu)
        if path not in self._extracted:
            description = read_description(path)
            # (a folder an interrupt keeps from being stored here is removed at exit)
            folder = extract_fmu(path, (PLATFORM_FOLDERS[description.fmiVersion],))
            self._extracted[path] = (str(folder), description)
        return (path, *self._extracted[path])

    def description(self, fmu: str | Path):
        return self._extraction(fmu)[2]

    def instance(self, fmu: str | Path, name: str, kind: str = "CS",
                 asked_inputs: AskedInputs | None = None) -> FmuInstance:
        path, unzipdir, description = self._extraction(fmu)
        with held():  # the instance and its place as the FMU's template (with a library reference) together
            instance = FmuInstance(fmu, kind=kind, name=name, unzipdir=unzipdir, description=description,
                                   template=self._templates.get((path, kind)), asked_inputs=asked_inputs)
            if (path, kind) not in self._templates:
                self._templates[path, kind] = instance
                self._held.append(ctypes.CDLL(str(instance.library))._handle)
        return instance

    def close(self) -> None:
        from fmpy import freeLibrary
        with held():  # an interrupt does not leave libraries or folders behind
            self._templates = {}
            handles, self._held = self._held, []
            for handle in handles:
                freeLibrary(handle)
            folders, self._extracted = self._extracted, {}
            for unzipdir, _ in folders.values():
                remove_folder(unzipdir)

    def __enter__(self) -> "SharedFmus":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def accepted_methods(fmu: str | Path) -> tuple[str, ...]:
    """The integration methods an FMU runs from its default start, in the Solver enumeration's order: every
    method but stormer_verlet where the object's mass matrix is not constant, neither it nor taylor where a
    constraint always acts (bilateral, compliant), and neither where a rigid constraint acts at the start (a
    taut string: they integrate free motion only). Asked of the FMU itself (setting `solver` is refused for a
    method it lacks, initialization for one that cannot start), so that the answer is the binary's; once per
    process and version of the file (a sweep asks it per case and method)."""
    try:
        found = Path(fmu).stat()
    except OSError:
        raise HarnessError(f"{fmu}: no such FMU file") from None
    return _accepted_methods(str(fmu), (found.st_ino, found.st_size, found.st_mtime_ns, found.st_ctime_ns))


@lru_cache(maxsize=None)
def _accepted_methods(fmu: str, version: tuple[int, ...]) -> tuple[str, ...]:
    with FmuInstance(fmu, name="probe") as instance:
        events = instance.model_description.numberOfEventIndicators > 0

        def runs(method: str) -> bool:
            if instance.set(solver=method) != OK:
                return False
            if not (events and method in FREE_MOTION_ONLY):
                return True
            try:
                instance.initialize(0.0, solver=method)
                return True
            except HarnessError:
                return False
            finally:
                instance.reset()
        return tuple(m.name for m in METHODS if runs(m.name))
