"""ctypes binding of harness/cosim/native/cosim_core.c, the master's fixed-step loop in C."""
from __future__ import annotations

import ctypes
import time

import numpy as np

from harness.cosim.algorithm_registry import ENTRY
from harness.cosim.unit import InputLine
from harness.errors import HarnessError
from harness.fmi.native_calls import FmiCalls, load_library
from harness.interrupts import held

CORE_REFUSED = -1  # cosim_run's answer to an algorithm id it does not know

_double_p = ctypes.POINTER(ctypes.c_double)
_uint_p = ctypes.POINTER(ctypes.c_uint)
_int_p = ctypes.POINTER(ctypes.c_int)


class CoreUnit(ctypes.Structure):
    _fields_ = [("calls", FmiCalls), ("line", ctypes.POINTER(InputLine)),
                ("n_out", ctypes.c_int), ("n_in", ctypes.c_int),
                ("n_int", ctypes.c_int), ("out_vrs", _uint_p), ("in_vrs", _uint_p), ("int_vrs", _uint_p),
                ("orders_out", _int_p), ("orders_in", _int_p), ("y_now", _double_p), ("dy_now", _double_p),
                ("y_next", _double_p), ("dy_next", _double_p), ("u", _double_p), ("du", _double_p),
                ("ints", ctypes.c_void_p), ("source_unit", _int_p), ("source_index", _int_p),
                ("energy_index", ctypes.c_int)]


class ContactControl(ctypes.Structure):
    """cosim_core.c's ContactControl: the settings and state of harness.cosim.contacts.ContactSteps."""
    _fields_ = [("n_watches", ctypes.c_int), ("watch_unit", _int_p), ("watch_gap", _int_p), ("watch_rate", _int_p),
                ("per_contact", ctypes.c_int), ("max_landings", ctypes.c_int), ("largest", ctypes.c_double),
                ("growth", ctypes.c_double), ("landed_share", ctypes.c_double), ("smallest_share", ctypes.c_double),
                ("contact_step", ctypes.c_double), ("last_step", ctypes.c_double), ("size", ctypes.c_double),
                ("last_rates", _double_p),
                ("have_rates", ctypes.c_int), ("macro_steps", ctypes.c_long), ("retries", ctypes.c_long),
                ("landings", ctypes.c_long), ("landed", _double_p), ("landed_capacity", ctypes.c_long),
                ("n_landed", ctypes.c_long), ("failed", ctypes.c_int), ("failed_at", ctypes.c_double),
                ("scratch", _double_p), ("states", ctypes.POINTER(ctypes.c_void_p)), ("saved", _double_p),
                ("swing", ctypes.c_double), ("redo", ctypes.c_double), ("blind", ctypes.c_int),
                ("have_entry", ctypes.c_int), ("entry_redos", ctypes.c_int), ("entry_have_rates", ctypes.c_int),
                ("entry_t", ctypes.c_double), ("entry_contact_step", ctypes.c_double),
                ("entry_size", ctypes.c_double), ("entry_last_step", ctypes.c_double),
                ("entry_macro_steps", ctypes.c_long), ("entry_n_landed", ctypes.c_long),
                ("entry_rates", _double_p), ("entry_states", ctypes.POINTER(ctypes.c_void_p)),
                ("entry_saved", _double_p), ("rounding", ctypes.c_double)]


class NativeContacts:
    """A ContactSteps control handed to the C loop: its settings and state in a ContactControl, and back."""

    LANDED_CAPACITY = 4096  # landed onsets the C loop keeps before it hands them over

    def __init__(self, control, units: list):
        from harness.cosim import contacts
        self.control = control
        index = {id(unit): k for k, unit in enumerate(units)}
        watches = control.watches
        self._arrays = [np.array([index[id(w.unit)] for w in watches], dtype=np.intc),
                        np.array([w.gap for w in watches], dtype=np.intc),
                        np.array([w.rate for w in watches], dtype=np.intc),
                        np.zeros(len(watches)), np.zeros(self.LANDED_CAPACITY), np.zeros(3 * len(watches)),
                        np.zeros(2 * sum(u.n_out for u in units)), np.zeros(len(watches)),
                        np.zeros(2 * sum(u.n_out for u in units))]
        self._states = (ctypes.c_void_p * len(units))()
        self._entry_states = (ctypes.c_void_p * len(units))()
        c = self.struct = ContactControl()
        unit_of, gap, rate, rates, landed, scratch, saved, entry_rates, entry_saved = self._arrays
        c.n_watches = len(watches)
        c.watch_unit, c.watch_gap, c.watch_rate = (a.ctypes.data_as(_int_p) for a in (unit_of, gap, rate))
        c.per_contact, c.max_landings = control.per_contact, contacts.MAX_LANDINGS
        c.largest, c.growth = control.largest, contacts.GROWTH
        c.landed_share, c.smallest_share = contacts.LANDED, contacts.SMALLEST
        c.last_rates, c.landed, c.scratch, c.saved = (a.ctypes.data_as(_double_p) for a in (rates, landed, scratch,
                                                                                           saved))
        c.landed_capacity = self.LANDED_CAPACITY
        c.states = self._states
        c.swing, c.redo, c.rounding = contacts.SWING, contacts.REDO, contacts.ROUNDING
        c.entry_rates, c.entry_saved = (a.ctypes.data_as(_double_p) for a in (entry_rates, entry_saved))
        c.entry_states = self._entry_states
        c.contact_step, c.last_step, c.size = control.contact_step, control.last_step, control.size
        c.have_rates = int(all(r is not None for r in control.last_rates))
        if c.have_rates:
            rates[:] = control.last_rates

    def hand_back(self, tally) -> None:
        """What the C loop did since the last call, into the control and the tally."""
        c, control = self.struct, self.control
        control.contact_step, control.last_step, control.size = c.contact_step, c.last_step, c.size
        control.last_rates = [float(r) for r in self._arrays[3]] if c.have_rates else control.last_rates
        control.landed.extend(float(t) for t in self._arrays[4][:c.n_landed])
        control.landings += c.landings
        tally.macro_steps += c.macro_steps
        tally.retries += c.retries
        c.n_landed = c.landings = c.macro_steps = c.retries = 0
        if c.failed == 1:
            control.failure = control.too_small(c.failed_at)
        elif c.failed == 2:
            control.failure = control.too_short(c.failed_at)


class EnergyGuard(ctypes.Structure):
    """cosim_core.c's EnergyGuard: the settings and state of harness.cosim.contact_guard.ContactGuard."""
    _fields_ = [("n_kinetic", ctypes.c_int), ("n_watches", ctypes.c_int), ("kinetic_unit", _int_p),
                ("kinetic_index", _int_p), ("watch_unit", _int_p), ("watch_gap", _int_p), ("watch_rate", _int_p),
                ("watch_stored", _int_p), ("share", ctypes.c_double), ("floor_share", ctypes.c_double),
                ("low", ctypes.c_double), ("scale", ctypes.c_double), ("magnitude", ctypes.c_double),
                ("before", _double_p), ("failed", ctypes.c_int), ("failed_at", ctypes.c_double),
                ("failed_step", ctypes.c_double), ("created", ctypes.c_double), ("failed_scale", ctypes.c_double),
                ("entry_low", ctypes.c_double), ("entry_scale", ctypes.c_double), ("entry_magnitude", ctypes.c_double),
                ("entry_before", _double_p)]


class NativeGuard:
    """A ContactGuard handed to the C loop: its settings and state in an EnergyGuard, and back."""

    def __init__(self, guard, units: list):
        from harness.cosim import contact_guard
        self.guard = guard
        index = {id(unit): k for k, unit in enumerate(units)}
        watches = guard.watches
        self._arrays = [np.array([index[id(u)] for u, _ in guard.kinetic] or [0], dtype=np.intc),
                        np.array([k for _, k in guard.kinetic] or [0], dtype=np.intc),
                        np.array([index[id(w.unit)] for w in watches], dtype=np.intc),
                        np.array([w.gap for w in watches], dtype=np.intc),
                        np.array([w.rate for w in watches], dtype=np.intc),
                        np.array([k for _, k in guard.stored], dtype=np.intc)]
        self.before = guard.before  # shared: C writes the contacts' values at each step's start into it
        self.entry_before = np.zeros_like(guard.before)
        g = self.struct = EnergyGuard()
        g.n_kinetic, g.n_watches = len(guard.kinetic), len(watches)
        g.kinetic_unit, g.kinetic_index, g.watch_unit, g.watch_gap, g.watch_rate, g.watch_stored = (
            a.ctypes.data_as(_int_p) for a in self._arrays)
        g.share, g.floor_share = contact_guard.SHARE, contact_guard.FLOOR
        g.low, g.scale, g.magnitude = guard.low, guard.scale, guard.magnitude
        g.before = self.before.ctypes.data_as(_double_p)
        g.entry_before = self.entry_before.ctypes.data_as(_double_p)

    def hand_back(self) -> None:
        """What the C loop left, into the guard."""
        from harness.cosim.contact_guard import GuardStop
        g, guard = self.struct, self.guard
        guard.low, guard.scale, guard.magnitude = g.low, g.scale, g.magnitude
        if g.failed and guard.stop is None:
            guard.stop = GuardStop(g.failed_at, g.failed_step, g.created, g.failed_scale, guard.before.copy())


def load_core() -> ctypes.CDLL | None:
    """The compiled core, or None when it has not been built (the master then loops in Python)."""
    library = load_library("cosim_core")
    if library is not None:
        library.cosim_run.argtypes = [ctypes.POINTER(CoreUnit), ctypes.c_int, _double_p, ctypes.c_long, ctypes.c_int,
                                      ctypes.c_int, _double_p, ctypes.c_long, _double_p, _int_p,
                                      ctypes.POINTER(ContactControl), ctypes.POINTER(EnergyGuard),
                                      ctypes.POINTER(ctypes.c_long), _int_p]
        library.cosim_run.restype = ctypes.c_int
    return library


class NativeLoop:
    """The C loop over the units' own buffers and C functions, for plain fixed-step runs and for contact
    steps (`contacts`, a ContactSteps over the plain algorithm). It runs in chunks, so that progress is
    shown, rows reach the caller as they come and an interrupt (seen between two calls) ends a run at once."""

    CHUNK_SECONDS = 0.1  # calls grow from a few rows to about this long, as the recorder's (harness/fmi/simulation.py)

    def __init__(self, core: ctypes.CDLL, units: list, algorithm: str, linear: bool, contacts=None, tally=None,
                 guard=None):
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
            if unit.line is not None:
                struct.line = ctypes.pointer(unit.line)
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
        self.algorithm, self.linear = algorithm, int(linear)
        self.code = ENTRY[algorithm].code  # the C loop's id for it
        self.contacts = NativeContacts(contacts, units) if contacts is not None else None
        self.guard = NativeGuard(guard, units) if guard is not None and guard.active else None
        self.tally = tally

    @property
    def saves_states(self) -> bool:
        """Every unit's binary exports the FMU state functions."""
        return all(struct.calls.get_state and struct.calls.set_state and struct.calls.free_state
                   for struct in self.structs)

    def run(self, grid: np.ndarray, table: np.ndarray, energy: np.ndarray, on_row=None,
            progress=None) -> tuple[int, int, int]:
        """Records grid[0], steps to each next point and records it. Returns (rows written, status,
        index of the unit that failed)."""
        rows_done, culprit = ctypes.c_long(), ctypes.c_int()
        first, chunk = 0, 16
        while True:
            started = time.perf_counter()
            end = min(first + chunk, len(grid) - 1)
            part = np.ascontiguousarray(grid[first:end + 1])
            with held():  # the rows a call computed reach the caller before an interrupt ends the run
                status = self.core.cosim_run(self.structs, self.n_units, part.ctypes.data_as(_double_p), len(part),
                                             self.code, self.linear, table[first:].ctypes.data_as(_double_p),
                                             table.shape[1], energy[first:].ctypes.data_as(_double_p), self.stepped,
                                             ctypes.byref(self.contacts.struct) if self.contacts else None,
                                             ctypes.byref(self.guard.struct) if self.guard else None,
                                             ctypes.byref(rows_done), ctypes.byref(culprit))
                if self.contacts:
                    self.contacts.hand_back(self.tally)
                if self.guard:
                    self.guard.hand_back()
                if status == CORE_REFUSED:
                    raise HarnessError(f"the C master loop does not know algorithm {self.algorithm!r} "
                                       f"(id {self.code}): "
                                       f"harness/cosim/native/cosim_core.c implements the registry's ids")
                rows = first + rows_done.value
                if on_row is not None:
                    for row in table[first + (1 if first else 0):rows]:
                        on_row(row)
            if status != 0 or rows == len(grid):
                return rows, status, culprit.value
            first = rows - 1  # the chunk's end, or where the contacts' landed onsets were handed over
            if progress is not None:
                progress(grid[first], first / (len(grid) - 1))
            # a call of about CHUNK_SECONDS (rows handed on included), growing at most fourfold
            elapsed = time.perf_counter() - started
            chunk = int(min(max(chunk * self.CHUNK_SECONDS / max(elapsed, 1e-9), 1), 4 * chunk, 1 << 24))
