"""ctypes binding of harness/cosim/native/cosim_core.c, the master's fixed-step loop in C."""
from __future__ import annotations

import ctypes

import numpy as np

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


class NativeLoop:
    """The C loop over the units' own buffers and C functions, for plain fixed-step runs (no rollback).
    It runs in chunks, so that progress is shown and rows reach the caller as they come."""

    CHUNK = 20000  # rows per call

    def __init__(self, core: ctypes.CDLL, units: list, gauss_seidel: bool, linear: bool):
        from harness.fmi.native_calls import fill_calls
        self.core = core
        index = {unit.name: k for k, unit in enumerate(units)}
        self.structs = (CoreUnit * len(units))()
        # per input: the unit that feeds it and that unit's output, all units' side by side
        routes = np.array([(index[c.source], units[index[c.source]].real_outputs.index(c.output))
                           for unit in units for c in unit.inputs] or [(0, 0)], dtype=np.intc).reshape(-1, 2)
        self._keep = [routes.T.copy()]  # arrays the structs point into
        first = 0
        for struct, unit in zip(self.structs, units):
            sources = self._keep[0][0, first:]
            positions = self._keep[0][1, first:]
            first += unit.n_in
            fill_calls(struct.calls, unit.instance.raw, unit.integers)
            struct.int_vrs = unit.integers.vrs
            struct.n_out, struct.n_in, struct.n_int = unit.n_out, unit.n_in, unit.n_int
            struct.out_vrs, struct.in_vrs = unit.out_vrs, unit.in_vrs
            struct.orders_out, struct.orders_in = unit.orders_out, unit.orders_in
            struct.y_now = unit.y_now.ctypes.data_as(_double_p)
            struct.dy_now = unit.dy_now.ctypes.data_as(_double_p)
            struct.y_next, struct.dy_next = unit.y_next, unit.dy_next
            struct.u, struct.du, struct.ints = unit.u, unit.du, unit.ints.ctypes.data
            struct.source_unit = sources.ctypes.data_as(_int_p)
            struct.source_index = positions.ctypes.data_as(_int_p)
            struct.energy_index = -1 if unit.energy_index is None else unit.energy_index
        self.n_units = len(units)
        self.stepped = (ctypes.c_int * len(units))()
        self.gauss_seidel, self.linear = int(gauss_seidel), int(linear)

    def run(self, grid: np.ndarray, table: np.ndarray, energy: np.ndarray, on_row=None,
            progress=None) -> tuple[int, int, int]:
        """Records grid[0], steps to each next point and records it. Returns (rows written, status,
        index of the unit that failed)."""
        rows_done, culprit = ctypes.c_long(), ctypes.c_int()
        first = 0
        while True:
            end = min(first + self.CHUNK, len(grid) - 1)
            part = np.ascontiguousarray(grid[first:end + 1])
            status = self.core.cosim_run(self.structs, self.n_units, part.ctypes.data_as(_double_p), len(part),
                                         self.gauss_seidel, self.linear, table[first:].ctypes.data_as(_double_p),
                                         table.shape[1], energy[first:].ctypes.data_as(_double_p), self.stepped,
                                         ctypes.byref(rows_done), ctypes.byref(culprit))
            rows = first + rows_done.value
            if on_row is not None:
                for row in table[first + (1 if first else 0):rows]:
                    on_row(row)
            if status != 0 or end == len(grid) - 1:
                return rows, status, culprit.value
            first = end
            if progress is not None:
                progress(grid[first], first / (len(grid) - 1))
