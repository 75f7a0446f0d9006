"""The ctypes side of the native loops: harness/fmi/native/fmi_calls.h's FmiCalls (the FMI functions of
one instance, either version) filled from a loaded FMU, and the compiled loop libraries.

The recorder's loop (native/record_loop.c) lives here; the master's (harness/cosim/native) builds on
the same FmiCalls."""
from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

from harness.fmi.calls import Calls
from harness.fmi.fmus import build_dir

INTEGER_KINDS = {np.dtype(np.intc): 0, np.dtype(np.int64): 1, np.dtype(np.uint64): 2}  # fmi_calls.h
AT_STEP, AT_FLOATS, AT_INTEGERS = 0, 1, 2  # record_loop.c: the call that stopped a run


class FmiCalls(ctypes.Structure):
    _fields_ = [("component", ctypes.c_void_p), ("set_float", ctypes.c_void_p), ("get_float", ctypes.c_void_p),
                ("get_integer", ctypes.c_void_p), ("do_step", ctypes.c_void_p), ("set_derivatives", ctypes.c_void_p),
                ("get_derivatives", ctypes.c_void_p), ("fmi3", ctypes.c_int), ("integer_kind", ctypes.c_int),
                ("last_time", ctypes.POINTER(ctypes.c_double)), ("get_state", ctypes.c_void_p),
                ("set_state", ctypes.c_void_p), ("free_state", ctypes.c_void_p)]


def fill_calls(calls: FmiCalls, raw: Calls, integer_reader=None) -> None:
    """The addresses of one instance's functions (and of its integer reader's, if any) into `calls`."""
    calls.component = raw.component.value
    calls.fmi3 = int(raw.version == "3.0")
    calls.set_float, calls.get_float = raw.function(raw.float_type.setter), raw.function(raw.float_type.getter)
    calls.do_step = raw.function(raw.names["do_step"])
    if raw.names["input_derivatives"]:
        calls.set_derivatives = raw.function(raw.names["input_derivatives"])
    calls.get_derivatives = raw.function(raw.names["output_derivatives"])
    calls.last_time = ctypes.pointer(raw.last_time)
    names = [raw.names[role] for role in ("get_state", "set_state", "free_state")]
    if all(hasattr(raw.dll, name) for name in names):  # an FMU that cannot save its state need not export them
        calls.get_state, calls.set_state, calls.free_state = (raw.function(name) for name in names)
    if integer_reader is not None:
        calls.get_integer = integer_reader.address
        calls.integer_kind = INTEGER_KINDS[integer_reader.dtype]


def load_library(name: str) -> ctypes.CDLL | None:
    """build/lib/<name>.so, or None when it has not been built (the loops then run in Python)."""
    path = Path(build_dir()) / "lib" / f"{name}.so"
    return ctypes.CDLL(str(path)) if path.is_file() else None


class RecordUnit(ctypes.Structure):
    _fields_ = [("calls", FmiCalls), ("n_real", ctypes.c_int), ("n_int", ctypes.c_int),
                ("real_vrs", ctypes.c_void_p), ("int_vrs", ctypes.c_void_p),
                ("reals", ctypes.c_void_p), ("real_stride", ctypes.c_long),
                ("ints", ctypes.c_void_p), ("int_stride", ctypes.c_long)]


def load_record_loop() -> ctypes.CDLL | None:
    library = load_library("record_loop")
    if library is not None:
        library.record_rows.argtypes = [ctypes.POINTER(RecordUnit), ctypes.c_void_p, ctypes.c_long, ctypes.c_long,
                                        ctypes.POINTER(ctypes.c_long), ctypes.POINTER(ctypes.c_int)]
        library.record_rows.restype = ctypes.c_int
    return library
