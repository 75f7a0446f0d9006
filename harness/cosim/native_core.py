"""ctypes binding of harness/cosim/native/cosim_core.c, the master's fixed-step loop in C."""
from __future__ import annotations

import ctypes

from harness.fmi.native_calls import FmiCalls, load_library

_double_p = ctypes.POINTER(ctypes.c_double)
_uint_p = ctypes.POINTER(ctypes.c_uint)
_int_p = ctypes.POINTER(ctypes.c_int)


class CoreUnit(ctypes.Structure):
    _fields_ = [("calls", FmiCalls), ("n_out", ctypes.c_int), ("n_in", ctypes.c_int),
                ("n_int", ctypes.c_int), ("out_vrs", _uint_p), ("in_vrs", _uint_p), ("int_vrs", _uint_p),
                ("orders_out", _int_p), ("orders_in", _int_p), ("y_now", _double_p), ("dy_now", _double_p),
                ("y_next", _double_p), ("dy_next", _double_p), ("u", _double_p), ("du", _double_p),
                ("ints", ctypes.c_void_p), ("source_unit", _int_p), ("source_index", _int_p),
                ("energy_index", ctypes.c_int)]


def load_core() -> ctypes.CDLL | None:
    """The compiled core, or None when it has not been built (the master then loops in Python)."""
    library = load_library("cosim_core")
    if library is not None:
        library.cosim_run.argtypes = [ctypes.POINTER(CoreUnit), ctypes.c_int, _double_p, ctypes.c_long, ctypes.c_int,
                                      ctypes.c_int, _double_p, ctypes.c_long, _double_p, _int_p,
                                      ctypes.POINTER(ctypes.c_long), _int_p]
        library.cosim_run.restype = ctypes.c_int
    return library
