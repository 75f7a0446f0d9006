"""One component as the master's parts see it: inputs in, one step, outputs out, and FMU states that
are saved, restored and released. Every part of the master (algorithms, controls, the C loop) works
through this one interface; it calls the FMUs' C functions with preallocated ctypes arrays."""
from __future__ import annotations

import ctypes

import numpy as np

from harness.cosim.structure import Component, System
from harness.errors import HarnessError
from harness.fmi.fmu_instance import ERROR, STATUS_NAMES, AskedInputs, SharedFmus
from harness.fmi.native_calls import load_library
from harness.interrupts import held


class InputLine(ctypes.Structure):
    """cosim_core.c's InputLine: how an FMI 3.0 unit that receives inputs asks for them during its step."""
    _fields_ = [("component", ctypes.c_void_p), ("set_float", ctypes.c_void_p), ("n", ctypes.c_int),
                ("vrs", ctypes.POINTER(ctypes.c_uint)), ("u", ctypes.POINTER(ctypes.c_double)),
                ("du", ctypes.POINTER(ctypes.c_double)), ("values", ctypes.POINTER(ctypes.c_double)),
                ("t0", ctypes.c_double), ("active", ctypes.c_int), ("status", ctypes.c_int)]


def input_line_answer() -> int | None:
    """The address of cosim_core.c's intermediate-update callback that hands an FMI 3.0 unit its inputs'
    line, or None when the core has not been built (FMI 3.0 receivers then hold their inputs)."""
    library = load_library("cosim_core")
    return ctypes.cast(library.cosim_answer_inputs, ctypes.c_void_p).value if library is not None else None


class Arena:
    """The float buffers of many units carved one after another from shared blocks, so that a loop
    over a thousand units walks contiguous memory instead of a thousand scattered allocations."""

    BLOCK = 1 << 16  # items

    def __init__(self):
        self._blocks: dict[type, list[np.ndarray]] = {}
        self._free: dict[type, int] = {}

    def _take(self, kind, n: int):
        """A zeroed ctypes array of n (at least one) items of the ctypes type `kind`."""
        n = max(n, 1)
        blocks = self._blocks.setdefault(kind, [])
        if not blocks or self._free[kind] + n > len(blocks[-1]):
            blocks.append(np.zeros(max(self.BLOCK, n), dtype=np.dtype(kind)))
            self._free[kind] = 0
        view = blocks[-1][self._free[kind]:self._free[kind] + n]
        self._free[kind] += n
        return (kind * n).from_buffer(view)

    def doubles(self, n: int):
        return self._take(ctypes.c_double, n)

    def array(self, kind, values: list[int]):
        """A ctypes array of `kind` (an integer type) holding values."""
        array = self._take(kind, len(values))
        for i, value in enumerate(values):
            array[i] = value
        return array


class Unit:
    """One component with its preallocated buffers. `y_now`/`dy_now` are the outputs (and their
    derivatives) at the start of the macro step; `y_next_view`/`dy_next_view` what the last read
    returned; `u_view`/`du_view` the inputs (and derivatives) the next write hands over."""

    def __init__(self, component: Component, system: System, fmus: SharedFmus, arena: Arena,
                 answer: int | None = None):
        """`answer`: the address of the C callback that hands an FMI 3.0 unit its inputs in intermediate
        updates (native_core.input_line_answer), None to hold them."""
        self.name = component.name
        self._arena = arena
        self.line: InputLine | None = None  # where an FMI 3.0 unit asks for its inputs during a step
        self.instance = fmus.instance(component.fmu, component.name,
                                      asked_inputs=self._asked_inputs(component, system, fmus, answer))
        self.live_states = 0  # FMU states saved and not yet released
        try:
            self._prepare(component, system)
        except BaseException:
            self.instance.free()
            raise

    def _asked_inputs(self, component: Component, system: System, fmus: SharedFmus,
                      answer: int | None) -> AskedInputs | None:
        """FMI 3.0 has no input derivatives: an FMI 3.0 unit whose connected inputs its FMU lets the master set
        in intermediate updates registers them, and asks for them at the start of each step, at its end; the
        master then hands it the values on the line it extrapolates (`line`, filled in `_prepare`)."""
        description = fmus.description(component.fmu)
        names = [c.input for c in system.connections if c.target == self.name]
        if answer is None or not names or description.fmiVersion != "3.0" or description.coSimulation is None \
                or not description.coSimulation.providesIntermediateUpdate:
            return None
        variables = {v.name: v for v in description.modelVariables}
        asked = [variables.get(name) for name in names]
        if not all(v is not None and v.causality == "input" and v.intermediateUpdate for v in asked):
            return None
        self.line = InputLine()
        return AskedInputs(answer, ctypes.addressof(self.line), tuple(v.valueReference for v in asked))

    def _prepare(self, component: Component, system: System) -> None:
        self.start = component.start
        variables = self.instance.model_description.modelVariables
        self.real_outputs, self.integer_outputs = self.instance.recorded_outputs(
            [v.name for v in variables if v.causality == "output"])
        self.inputs = [c for c in system.connections if c.target == self.name]
        for c in self.inputs:
            variable = self.instance.variables.get(c.input)
            if variable is None or variable.causality != "input":
                raise HarnessError(f"connection {c}: {self.name} has no input {c.input!r}")
        n_out, n_in, n_int = len(self.real_outputs), len(self.inputs), len(self.integer_outputs)
        arena = self._arena
        self.out_vrs = arena.array(ctypes.c_uint, [self.instance.reference(n) for n in self.real_outputs])
        self.in_vrs = arena.array(ctypes.c_uint, [self.instance.reference(c.input) for c in self.inputs])
        self.orders_out = arena.array(ctypes.c_int, [1] * n_out)
        self.orders_in = arena.array(ctypes.c_int, [1] * n_in)
        doubles = arena.doubles
        # the buffers the loops touch every step, side by side: outputs now and next, their derivatives, inputs
        y_now, dy_now = doubles(n_out), doubles(n_out)
        self.y_next, self.dy_next = doubles(n_out), doubles(n_out)  # after this unit's step
        self.u, self.du = doubles(n_in), doubles(n_in)
        self.integers = self.instance.integer_reader(self.integer_outputs)
        self.ints = np.zeros(max(n_int, 1), dtype=self.integers.dtype)
        self.n_out, self.n_in, self.n_int = n_out, n_in, n_int
        # numpy views on the ctypes buffers: routing is vectorised, no per-variable Python work
        self.y_next_view = np.ctypeslib.as_array(self.y_next)[:n_out]
        self.dy_next_view = np.ctypeslib.as_array(self.dy_next)[:n_out]
        self.u_view = np.ctypeslib.as_array(self.u)[:n_in]
        self.du_view = np.ctypeslib.as_array(self.du)[:n_in]
        self.y_now = np.ctypeslib.as_array(y_now)[:n_out]  # outputs at the start of the macro step
        self.dy_now = np.ctypeslib.as_array(dy_now)[:n_out]
        raw = self.instance.raw
        self.component = raw.component
        self.set_real, self.get_real, self.do_step = raw.set_real, raw.get_real, raw.do_step
        self.set_derivatives = raw.input_derivatives()  # None for FMI 3.0
        self.get_derivatives = raw.output_derivatives()
        self.names = dict(raw.names, set=raw.float_type.setter, get=raw.float_type.getter)  # for messages
        energy_name = "E" if "E" in self.real_outputs else "E_pot" if "E_pot" in self.real_outputs else None
        self.energy_index = self.real_outputs.index(energy_name) if energy_name else None
        self.can_save = bool(self.instance.model_description.coSimulation.canGetAndSetFMUstate)
        if self.line is not None:
            line = self.line
            line.component, line.set_float = raw.component.value, raw.function(raw.float_type.setter)
            line.n, line.vrs, line.u, line.du = n_in, self.in_vrs, self.u, self.du
            line.values = doubles(n_in)

    @property
    def takes_slopes(self) -> bool:
        """Inputs can vary linearly over a step: FMI 2.0's input derivatives, or FMI 3.0's intermediate
        updates."""
        return self.set_derivatives is not None or self.line is not None

    def check(self, status: int, what: str) -> int:
        if status >= ERROR:
            raise HarnessError(f"{self.name}: {what} returned {STATUS_NAMES[status]}: {self.instance.last_message()}")
        return status

    def read_outputs(self, derivatives: bool) -> None:
        self.check(self.get_real(self.component, self.out_vrs, self.n_out, self.y_next), self.names["get"])
        if derivatives:
            self.check(self.get_derivatives(self.component, self.out_vrs, self.n_out, self.orders_out,
                                            self.dy_next), self.names["output_derivatives"])

    def write_inputs(self, derivatives: bool) -> None:
        self.check(self.set_real(self.component, self.in_vrs, self.n_in, self.u), self.names["set"])
        if derivatives and self.set_derivatives is not None:  # FMI 3.0: asked for during the step (`line`)
            self.check(self.set_derivatives(self.component, self.in_vrs, self.n_in, self.orders_in, self.du),
                       self.names["input_derivatives"])

    def step(self, t: float, H: float) -> int:
        line = self.line
        if line is not None:
            line.t0, line.status = t, 0
        status = self.do_step(self.component, t, H, 1)
        if line is not None and line.status >= ERROR:
            raise HarnessError(f"{self.name}: {self.names['set']} of its inputs, asked for in the step from t = {t}, "
                               f"returned {STATUS_NAMES[line.status]}: {self.instance.last_message()}")
        return self.check(status, f"{self.names['do_step']} at t = {t}")

    def accept(self, derivatives: bool) -> None:
        """The outputs just read become those at the start of the next macro step."""
        self.y_now[:] = self.y_next_view
        if derivatives:
            self.dy_now[:] = self.dy_next_view

    # ---- FMU states: each saved state is released by whoever saved it, once it has served
    def save(self) -> ctypes.c_void_p:
        state = ctypes.c_void_p()
        self.check(self.instance.role("get_state", ctypes.byref(state)), self.names["get_state"])
        self.live_states += 1
        return state

    def restore(self, state: ctypes.c_void_p) -> None:
        self.check(self.instance.role("set_state", state), self.names["set_state"])

    def release(self, state: ctypes.c_void_p) -> None:
        if state.value and self.instance.fmu is not None:
            self.live_states -= 1
            self.check(self.instance.role("free_state", ctypes.byref(state)), self.names["free_state"])

    def free(self) -> None:
        self.instance.free()


class Snapshot:
    """Every unit's FMU state and exchanged values at one moment, to roll back to, with the
    bookkeeping of the stepper the rollback repeats (`bookkeeping()` / `restore_bookkeeping()`, where
    it keeps any: the energy the power bonds measured). Taken when the `with` block starts and released
    when it ends, whatever happens inside it, so no state outlives its use: taken in __enter__, after
    which an interrupt is sure to reach __exit__."""

    def __init__(self, units: list[Unit], stepper=None):
        self.units = units
        self.stepper = stepper if hasattr(stepper, "bookkeeping") else None
        self.states: list[ctypes.c_void_p] = []

    def restore(self) -> None:
        for unit, state, (y, dy) in zip(self.units, self.states, self.values):
            unit.restore(state)
            unit.y_now[:], unit.dy_now[:] = y, dy
        if self.stepper:
            self.stepper.restore_bookkeeping(self.kept)

    def release(self) -> None:
        with held():  # all of them, whatever the moment of an interrupt
            states, self.states = self.states, []
            for unit, state in zip(self.units, states):
                unit.release(state)

    def __enter__(self) -> "Snapshot":
        return self.take()

    def take(self) -> "Snapshot":
        """The states and values now; the caller releases them (a `with` block does)."""
        self.kept = self.stepper.bookkeeping() if self.stepper else None
        try:
            with held():  # every state saved is in `states`, for release() to release
                for unit in self.units:
                    self.states.append(unit.save())
        except BaseException:
            self.release()
            raise
        self.values = [(unit.y_now.copy(), unit.dy_now.copy()) for unit in self.units]
        return self

    def __exit__(self, *exc) -> None:
        self.release()
