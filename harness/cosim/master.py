"""The co-simulation master: Jacobi or Gauss-Seidel over a fixed communication grid, inputs held or
extrapolated linearly, a discarded step handled by rollback and smaller steps or a clear stop. The
components may be FMI 2.0 and FMI 3.0 FMUs in any mix.

In FMI 2.0 an input and its derivative are values at the start of the receiving step. With linear
extrapolation a source that has not stepped yet hands over y(t) and its output derivative; in
Gauss-Seidel a source that has already stepped hands over y(t) with the slope (y(t+H) - y(t))/H,
which is second-order accurate without making a receiver such as the Spring advance y(t+H) again.

FMI 3.0 has no input derivatives, so an FMI 3.0 component cannot receive a linearly extrapolated
input: by default the inputs are extrapolated linearly when every receiving component is FMI 2.0
and held otherwise; asking for linear extrapolation (or iteration, which interpolates the inputs
the same way) with an FMI 3.0 receiver is refused by name. FMI 3.0 sources hand over their output
derivatives like FMI 2.0 ones.

The loop calls the FMUs' C functions directly with preallocated ctypes arrays: per FMU and macro
step one set, one step, one get of the float variables (plus the derivative calls for linear
extrapolation and a get of the integers where a component has integer outputs).
"""
from __future__ import annotations

import ctypes
import dataclasses
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from harness.cosim.structure import System
from harness.errors import HarnessError, where
from harness.fmi.fmu_instance import DISCARD, ERROR, OK, STATUS_NAMES, FmuInstance
from harness.fmi.results import TimeTable
from harness.fmi.simulation import Progress, check_table_size, communication_grid

ALGORITHMS = ("jacobi", "gauss-seidel")
EXTRAPOLATIONS = ("hold", "linear")


@dataclass
class MasterOptions:
    stop: float
    step: float
    start: float = 0.0
    algorithm: str = "gauss-seidel"
    extrapolation: str | None = None  # hold or linear; None: linear unless an FMI 3.0 component receives inputs
    on_discard: str = "stop"  # "stop", or "retry": roll back (FMU states) and halve the step
    max_halvings: int = 10
    iterate_tol: float | None = None  # iterate each macro step to this change in the outputs
    max_iterations: int = 20
    tolerance: float | None = None    # adapt the macro step by step doubling to this error per step
    progress: bool = False

    def __post_init__(self) -> None:
        if self.algorithm not in ALGORITHMS:
            raise HarnessError(f"--algorithm {self.algorithm!r}: choose one of {', '.join(ALGORITHMS)}")
        if self.extrapolation is not None and self.extrapolation not in EXTRAPOLATIONS:
            raise HarnessError(f"--extrapolation {self.extrapolation!r}: choose one of {', '.join(EXTRAPOLATIONS)}")
        if self.on_discard not in ("stop", "retry"):
            raise HarnessError(f"on_discard {self.on_discard!r}: choose stop or retry")
        for name in ("iterate_tol", "tolerance"):
            value = getattr(self, name)
            if value is not None and not (value > 0 and math.isfinite(value)):
                raise HarnessError(f"{name} = {value} must be a positive number")


@dataclass
class CoSimulationResult(TimeTable):
    energy: np.ndarray = field(default_factory=lambda: np.zeros(0))  # sum of E (or E_pot) over the components
    stopped_at: float | None = None
    message: str | None = None
    macro_steps: int = 0
    retries: int = 0  # macro steps redone: after a discard, or rejected by step doubling
    messages: list[str] = field(default_factory=list)
    iterations: int = 0  # passes of iterated macro steps
    unconverged: int = 0  # iterated macro steps that reached max_iterations
    extrapolation: str = "linear"  # what the run used (the default depends on the components' FMI versions)

    @property
    def energy_residual(self) -> float:
        """Largest |E_total(t) - E_total(0)|: the energy the coupling created or destroyed (for a
        system without damping)."""
        return float(np.max(np.abs(self.energy - self.energy[0]))) if len(self.energy) else 0.0


def _doubles(n: int):
    return (ctypes.c_double * max(n, 1))()


class _Unit:
    """One component with its preallocated buffers."""

    def __init__(self, component, system: System):
        self.name = component.name
        self.instance = FmuInstance(component.fmu, name=component.name)
        try:
            self._prepare(component, system)
        except BaseException:
            self.instance.free()
            raise

    def _prepare(self, component, system: System) -> None:
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
        self.out_vrs = (ctypes.c_uint * max(n_out, 1))(*[self.instance.reference(n) for n in self.real_outputs])
        self.in_vrs = (ctypes.c_uint * max(n_in, 1))(*[self.instance.reference(c.input) for c in self.inputs])
        self.orders_out = (ctypes.c_int * max(n_out, 1))(*([1] * n_out))
        self.orders_in = (ctypes.c_int * max(n_in, 1))(*([1] * n_in))
        self.y_next, self.dy_next = _doubles(n_out), _doubles(n_out)  # after this unit's step
        self.u, self.du = _doubles(n_in), _doubles(n_in)
        self.integers = self.instance.integer_reader(self.integer_outputs)
        self.ints = np.zeros(max(n_int, 1), dtype=self.integers.dtype)
        self.n_out, self.n_in, self.n_int = n_out, n_in, n_int
        # numpy views on the ctypes buffers: routing is vectorised, no per-variable Python work
        self.y_next_view = np.ctypeslib.as_array(self.y_next)[:n_out]
        self.dy_next_view = np.ctypeslib.as_array(self.dy_next)[:n_out]
        self.u_view = np.ctypeslib.as_array(self.u)[:n_in]
        self.du_view = np.ctypeslib.as_array(self.du)[:n_in]
        self.y_now = np.zeros(n_out)    # outputs at the start of the macro step
        self.dy_now = np.zeros(n_out)   # their derivatives there
        raw = self.instance.raw
        self.component = raw.component
        self.set_real, self.get_real, self.do_step = raw.set_real, raw.get_real, raw.do_step
        self.set_derivatives = raw.input_derivatives()  # None for FMI 3.0
        self.get_derivatives = raw.output_derivatives()
        self.names = dict(raw.names, set=raw.float_type.setter, get=raw.float_type.getter)  # for messages
        energy_name = "E" if "E" in self.real_outputs else "E_pot" if "E_pot" in self.real_outputs else None
        self.energy_index = self.real_outputs.index(energy_name) if energy_name else None
        self.states = [ctypes.c_void_p(), ctypes.c_void_p()]

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
        if derivatives:
            self.check(self.set_derivatives(self.component, self.in_vrs, self.n_in, self.orders_in, self.du),
                       self.names["input_derivatives"])

    def step(self, t: float, H: float) -> int:
        return self.check(self.do_step(self.component, t, H, 1), f"{self.names['do_step']} at t = {t}")

    def save(self, slot: int) -> None:
        self.check(self.instance.role("get_state", ctypes.byref(self.states[slot])), self.names["get_state"])

    def restore(self, slot: int) -> None:
        self.check(self.instance.role("set_state", self.states[slot]), self.names["set_state"])

    def free(self) -> None:
        """Releases the saved FMU states, then the instance."""
        if self.instance.fmu is not None:
            for state in self.states:
                if state.value:
                    self.instance.role("free_state", ctypes.byref(state))
        self.instance.free()


class Master:
    """Runs a System; build once, call run() once."""

    def __init__(self, system: System, options: MasterOptions):
        self.system, self.options = system, options
        names = [c.name for c in system.components]
        if len(set(names)) != len(names):
            raise HarnessError(f"system {system.name!r}: component names must be unique")
        self.units: list[_Unit] = []
        try:  # whatever fails while setting up, the instances made so far are freed
            with where(system.origin, system.workspace):
                for component in system.components:
                    self.units.append(_Unit(component, system))
                self._route()
                self.options = dataclasses.replace(options, extrapolation=self._extrapolation(options))
                self._check_states(options)
        except BaseException:
            self.free()
            raise
        self.iterations = self.unconverged = self.macro_steps = 0
        self.use_native = True  # the C loop for plain fixed-step runs, when it is built
        self.h_proposal: float | None = None

    def _route(self) -> None:
        by_name = {u.name: u for u in self.units}
        # For each receiving unit: (source unit, source output indices, input indices), vectorised.
        self.routes: list[list[tuple[_Unit, np.ndarray, np.ndarray]]] = []
        for unit in self.units:
            grouped: dict[str, tuple[list[int], list[int]]] = {}
            for k, c in enumerate(unit.inputs):
                source = by_name.get(c.source)
                if source is None:
                    raise HarnessError(f"connection {c}: no component {c.source!r}")
                if c.output not in source.real_outputs:
                    raise HarnessError(f"connection {c}: {c.source} has no Real output {c.output!r}")
                self._check_units(source, c.output, unit, c.input, c)
                outs, ins = grouped.setdefault(c.source, ([], []))
                outs.append(source.real_outputs.index(c.output))
                ins.append(k)
            self.routes.append([(by_name[s], np.array(o), np.array(i)) for s, (o, i) in grouped.items()])

    def _extrapolation(self, options: MasterOptions) -> str:
        """The extrapolation asked for, or by default linear unless an FMI 3.0 component receives
        inputs (FMI 3.0 has no input derivatives to hand them over)."""
        receivers = [u for u in self.units if u.n_in and u.set_derivatives is None]
        if not receivers:
            return options.extrapolation or "linear"
        names = ", ".join(f"{u.name!r}" for u in receivers)
        if options.extrapolation == "linear":
            raise HarnessError(f"linear extrapolation sets input derivatives, which the FMI 3.0 component(s) {names} "
                               "do not take: use --extrapolation hold, or their FMI 2.0 FMUs")
        if options.iterate_tol:
            raise HarnessError(f"iterated macro steps interpolate the inputs through input derivatives, which the "
                               f"FMI 3.0 component(s) {names} do not take: leave out --iterate, or use their FMI 2.0 FMUs")
        return "hold"

    def _check_states(self, options: MasterOptions) -> None:
        """Rollback (retry after a discard, iteration, step doubling) needs every component's FMU state."""
        uses = [what for what, used in (("--on-discard retry", options.on_discard == "retry"),
                                        ("--iterate", options.iterate_tol), ("--tolerance", options.tolerance)) if used]
        lacking = [u.name for u in self.units if not u.instance.model_description.coSimulation.canGetAndSetFMUstate]
        if uses and lacking:
            raise HarnessError(f"{' and '.join(uses)} roll back through FMU states, which {', '.join(lacking)} "
                               f"cannot save (canGetAndSetFMUstate is not true)")

    @staticmethod
    def _check_units(source: _Unit, output: str, target: _Unit, input_: str, connection) -> None:
        a = source.instance.variables[output].unit
        b = target.instance.variables[input_].unit
        if a and b and a != b:
            raise HarnessError(f"connection {connection}: units differ ({a} to {b})")

    # ---- setup
    def _initialize(self) -> None:
        linear = self.options.extrapolation == "linear"
        for unit in self.units:
            with where(self.system.origin, self.system.workspace), where(f"component {unit.name!r}"):
                unit.instance.enter_initialization(self.options.start, **unit.start)
        # Copy connected outputs to inputs until they settle, so that forces at t = 0 are consistent.
        for _ in range(50):
            change = 0.0
            for unit in self.units:
                unit.read_outputs(False)
                unit.y_now[:] = unit.y_next_view
            for unit, routes in zip(self.units, self.routes):
                if not unit.n_in:
                    continue
                before = unit.u_view.copy()
                for source, outs, ins in routes:
                    unit.u_view[ins] = source.y_now[outs]
                unit.write_inputs(False)
                change = max(change, float(np.max(np.abs(unit.u_view - before))))
            if change <= 1e-14:
                break
        for unit in self.units:
            unit.instance.exit_initialization()
            unit.read_outputs(linear)
            unit.y_now[:] = unit.y_next_view
            if linear:
                unit.dy_now[:] = unit.dy_next_view

    # ---- one macro step
    def _feed(self, k: int, H: float, stepped: set[str]) -> None:
        """Sets the inputs of unit k for the step [t, t + H]."""
        unit = self.units[k]
        if not unit.n_in:
            return
        linear = self.options.extrapolation == "linear"
        for source, outs, ins in self.routes[k]:
            if source.name in stepped:
                if linear:
                    unit.u_view[ins] = source.y_now[outs]
                    unit.du_view[ins] = (source.y_next_view[outs] - source.y_now[outs]) / H
                else:
                    unit.u_view[ins] = source.y_next_view[outs]
            else:
                unit.u_view[ins] = source.y_now[outs]
                if linear:
                    unit.du_view[ins] = source.dy_now[outs]
        unit.write_inputs(linear)

    def _macro_step(self, t: float, H: float) -> tuple[int, _Unit | None]:
        """Steps every unit from t to t + H; returns (status, the unit that discarded)."""
        linear = self.options.extrapolation == "linear"
        stepped: set[str] = set()
        if self.options.algorithm == "jacobi":
            for k in range(len(self.units)):
                self._feed(k, H, stepped)
            for unit in self.units:
                if unit.step(t, H) == DISCARD:
                    return DISCARD, unit
            for unit in self.units:
                unit.read_outputs(linear)
        else:
            for k, unit in enumerate(self.units):
                self._feed(k, H, stepped)
                if unit.step(t, H) == DISCARD:
                    return DISCARD, unit
                unit.read_outputs(linear)
                stepped.add(unit.name)
        for unit in self.units:
            unit.y_now[:] = unit.y_next_view
            if linear:
                unit.dy_now[:] = unit.dy_next_view
        return OK, None

    # ---- rollback through FMU states (slot 0: step control and discard retry, slot 1: iteration)
    def _save(self, slot: int) -> list[tuple[np.ndarray, np.ndarray]]:
        for unit in self.units:
            unit.save(slot)
        return [(unit.y_now.copy(), unit.dy_now.copy()) for unit in self.units]

    def _restore(self, slot: int, saved: list[tuple[np.ndarray, np.ndarray]]) -> None:
        for unit, (y, dy) in zip(self.units, saved):
            unit.restore(slot)
            unit.y_now[:], unit.dy_now[:] = y, dy

    def _iterated_step(self, t: float, H: float) -> tuple[int, _Unit | None]:
        """Fixed-point iteration of one macro step: every input varies linearly from its source's
        value at t to the source's value at t + H from the previous pass (the first pass uses the
        extrapolation), until the outputs at t + H change by less than iterate_tol (1 + |y|)."""
        linear = self.options.extrapolation == "linear"
        saved = self._save(1)
        guess = [unit.y_now + H * unit.dy_now if linear else unit.y_now.copy() for unit in self.units]
        index = {unit.name: k for k, unit in enumerate(self.units)}
        for iteration in range(1, self.options.max_iterations + 1):
            self.iterations += 1
            for k, unit in enumerate(self.units):
                if not unit.n_in:
                    continue
                for source, outs, ins in self.routes[k]:
                    unit.u_view[ins] = source.y_now[outs]
                    unit.du_view[ins] = (guess[index[source.name]][outs] - source.y_now[outs]) / H
                unit.write_inputs(True)
            for unit in self.units:
                if unit.step(t, H) == DISCARD:
                    return DISCARD, unit
            change = 0.0
            for unit, g in zip(self.units, guess):
                unit.read_outputs(linear)
                change = max(change, float(np.max(np.abs(unit.y_next_view - g) / (1.0 + np.abs(unit.y_next_view)),
                                                  initial=0.0)))
            if change <= self.options.iterate_tol or iteration == self.options.max_iterations:
                if change > self.options.iterate_tol:
                    self.unconverged += 1
                for unit in self.units:
                    unit.y_now[:] = unit.y_next_view
                    if linear:
                        unit.dy_now[:] = unit.dy_next_view
                return OK, None
            guess = [unit.y_next_view.copy() for unit in self.units]
            self._restore(1, saved)
        raise AssertionError("unreachable")

    def _trial(self, t: float, H: float) -> tuple[int, _Unit | None]:
        return self._iterated_step(t, H) if self.options.iterate_tol else self._macro_step(t, H)

    def _advance(self, t: float, H: float, depth: int = 0) -> tuple[int, _Unit | None, int]:
        """[t, t + H] in one macro step or, after a discard with on_discard="retry", in halves."""
        retry = self.options.on_discard == "retry"
        saved = self._save(0) if retry else None
        status, culprit = self._trial(t, H)
        if status != DISCARD or not retry or depth >= self.options.max_halvings:
            return status, culprit, 0
        self._restore(0, saved)
        status, culprit, retries = self._advance(t, H / 2, depth + 1)
        if status == DISCARD:
            return status, culprit, retries + 1
        status, culprit, more = self._advance(t + H / 2, H / 2, depth + 1)
        return status, culprit, retries + more + 1

    def _outputs(self) -> np.ndarray:
        return np.concatenate([unit.y_now for unit in self.units])

    def _advance_adaptive(self, t: float, t_end: float) -> tuple[int, _Unit | None, int]:
        """[t, t_end] in macro steps chosen by step doubling: one step of h against two of h/2 from
        the same state (rolled back in between); the difference, divided by 2^p - 1, estimates the
        coupling error of the two half steps, which are kept when it is within
        tolerance (1 + |y|) h / duration. Controlling the error per unit step keeps the sum of the
        local errors, and so the global error, near the tolerance."""
        duration = self.options.stop - self.options.start
        order = 2 if self.options.extrapolation == "linear" or self.options.iterate_tol else 1
        smallest = (t_end - t) / 2 ** 20
        h = min(self.h_proposal or (t_end - t), t_end - t)
        rejected = 0
        steps_before = self.macro_steps  # a failed interval adds none: its steps reach no recorded row
        while t < t_end:
            last = h >= t_end - t
            step = t_end - t if last else h
            saved = self._save(0)
            status, culprit = self._trial(t, step)
            if status != DISCARD:
                full = self._outputs()
                self._restore(0, saved)
                status, culprit = self._trial(t, step / 2)
                if status != DISCARD:
                    status, culprit = self._trial(t + step / 2, step / 2)
            if status == DISCARD:
                error = math.inf
            else:
                half = self._outputs()
                error = float(np.max(np.abs(half - full) / (1.0 + np.abs(half)))) / (2 ** order - 1) \
                    / (self.options.tolerance * step / duration)
            # local error ~ h^(p+1) against a bound ~ h: the step scales with error^(-1/p)
            factor = 2.0 if error == 0 else min(2.0, max(0.2, 0.9 * error ** (-1.0 / order)))
            if error <= 1.0:
                t = t_end if last else t + step
                self.macro_steps += 2
                if not last or step >= h:
                    h = step * factor
            else:
                self._restore(0, saved)
                rejected += 1
                h = step * min(factor, 0.5)
                if h < smallest:
                    self.macro_steps = steps_before
                    return (DISCARD, culprit, rejected) if status == DISCARD else (ERROR, None, rejected)
        self.h_proposal = h
        return OK, None, rejected

    # ---- the run
    @property
    def columns(self) -> list[str]:
        """time, then <component>.<output> for every Real output, then every Integer output."""
        return ["time"] + [f"{u.name}.{n}" for u in self.units for n in u.real_outputs] + \
               [f"{u.name}.{n}" for u in self.units for n in u.integer_outputs]

    def run(self, on_row: Callable[[np.ndarray], None] | None = None) -> CoSimulationResult:
        options = self.options
        grid = communication_grid(options.start, options.stop, options.step)
        columns = self.columns
        check_table_size(len(grid), len(columns))
        table = np.empty((len(grid), len(columns)))
        energy = np.empty(len(grid))
        has_energy = any(u.energy_index is not None for u in self.units)
        stopped_at, message, retries, rows = None, None, 0, 0
        self._initialize()
        progress = Progress(options.stop) if options.progress else None

        def record(t: float) -> None:
            table[rows, 0] = t
            column = 1
            for unit in self.units:
                table[rows, column:column + unit.n_out] = unit.y_now
                column += unit.n_out
            for unit in self.units:
                if unit.n_int:
                    unit.check(unit.integers.read(unit.ints.ctypes.data), unit.integers.function)
                    table[rows, column:column + unit.n_int] = unit.ints[:unit.n_int]
                    column += unit.n_int
            energy[rows] = sum(u.y_now[u.energy_index] for u in self.units if u.energy_index is not None) \
                if has_energy else math.nan
            if on_row is not None:
                on_row(table[rows])

        fast = self._native_runner(table, energy) if self._native_eligible() else None
        if fast is not None:
            rows, status, culprit_index = fast(grid, on_row)
            self.macro_steps = rows - 1
            if status >= ERROR:
                culprit = self.units[culprit_index]
                raise HarnessError(f"{culprit.name}: an {culprit.instance.prefix} call returned {STATUS_NAMES[status]} near "
                                   f"t = {grid[rows - 1]:g}: {culprit.instance.last_message()}")
            if status != OK:
                culprit = self.units[culprit_index]
                stopped_at = culprit.instance.last_successful_time() if status == DISCARD else grid[rows - 1]
                message = f"{culprit.name} could not complete the step from t = {grid[rows - 1]:g}: " \
                          f"{culprit.instance.last_message()}"
            if not has_energy:
                energy[:rows] = math.nan  # as the Python loop records it
            grid = grid[:0]  # done: skip the Python loop
        for k, t in enumerate(grid):
            record(t)
            rows += 1
            if k + 1 == len(grid):
                break
            if options.tolerance:
                status, culprit, extra = self._advance_adaptive(t, grid[k + 1])
            else:
                status, culprit, extra = self._advance(t, grid[k + 1] - t)
                self.macro_steps += status == OK
            retries += extra
            if status == ERROR:
                stopped_at = t
                message = f"step doubling could not meet the tolerance {options.tolerance:g} after t = {t:g}"
                break
            if status == DISCARD:
                stopped_at = culprit.instance.last_successful_time()
                message = (f"{culprit.name} could not complete the step from t = {t:g}"
                           + (f" even with {2 ** options.max_halvings}x smaller steps" if options.on_discard == "retry"
                              else "") + f": {culprit.instance.last_message()}")
                break
            if progress is not None:
                progress(grid[k + 1], (k + 1) / (len(grid) - 1))
        messages = [f"{u.name}: {m}" for u in self.units for m in u.instance.log.messages]
        return CoSimulationResult(columns, table[:rows], energy[:rows], stopped_at, message, self.macro_steps,
                                  retries, messages, self.iterations, self.unconverged, self.options.extrapolation)

    def _native_eligible(self) -> bool:
        o = self.options
        return o.iterate_tol is None and o.tolerance is None and o.on_discard == "stop" and self.use_native

    def _native_runner(self, table: np.ndarray, energy: np.ndarray):
        """The C loop over the same buffers and C functions, run in chunks so that progress is shown
        and rows reach the caller as they come; None when the core is not built."""
        from harness.cosim.native_core import CoreUnit, load_core
        from harness.fmi.native_calls import fill_calls
        core = load_core()
        if core is None:
            return None
        index = {unit.name: k for k, unit in enumerate(self.units)}
        structs = (CoreUnit * len(self.units))()
        keep = []  # arrays the structs point into
        double_p, int_p = ctypes.POINTER(ctypes.c_double), ctypes.POINTER(ctypes.c_int)
        for struct, unit in zip(structs, self.units):
            sources = np.array([index[c.source] for c in unit.inputs] or [0], dtype=np.intc)
            positions = np.array([self.units[index[c.source]].real_outputs.index(c.output) for c in unit.inputs]
                                 or [0], dtype=np.intc)
            keep += [sources, positions]
            fill_calls(struct.calls, unit.instance.raw, unit.integers)
            struct.int_vrs = unit.integers.vrs
            struct.n_out, struct.n_in, struct.n_int = unit.n_out, unit.n_in, unit.n_int
            struct.out_vrs, struct.in_vrs = unit.out_vrs, unit.in_vrs
            struct.orders_out, struct.orders_in = unit.orders_out, unit.orders_in
            struct.y_now = unit.y_now.ctypes.data_as(double_p)
            struct.dy_now = unit.dy_now.ctypes.data_as(double_p)
            struct.y_next, struct.dy_next = unit.y_next, unit.dy_next
            struct.u, struct.du, struct.ints = unit.u, unit.du, unit.ints.ctypes.data
            struct.source_unit = sources.ctypes.data_as(int_p)
            struct.source_index = positions.ctypes.data_as(int_p)
            struct.energy_index = -1 if unit.energy_index is None else unit.energy_index
        stepped = (ctypes.c_int * len(self.units))()
        gauss_seidel = int(self.options.algorithm == "gauss-seidel")
        linear = int(self.options.extrapolation == "linear")
        rows_done, culprit = ctypes.c_long(), ctypes.c_int()

        def run(grid: np.ndarray, on_row) -> tuple[int, int, int]:
            chunk, first = 20000, 0
            progress = Progress(self.options.stop) if self.options.progress else None
            while True:
                end = min(first + chunk, len(grid) - 1)
                part = np.ascontiguousarray(grid[first:end + 1])
                status = core.cosim_run(structs, len(self.units), part.ctypes.data_as(double_p), len(part),
                                        gauss_seidel, linear, table[first:].ctypes.data_as(double_p),
                                        table.shape[1], energy[first:].ctypes.data_as(double_p), stepped,
                                        ctypes.byref(rows_done), ctypes.byref(culprit))
                rows = first + rows_done.value
                if on_row is not None:
                    for row in table[first + (1 if first else 0):rows]:
                        on_row(row)
                if status != OK or end == len(grid) - 1:
                    return rows, DISCARD if status == DISCARD else status, culprit.value
                first = end
                if progress is not None:
                    progress(grid[first], first / (len(grid) - 1))

        self._keep_alive = (structs, keep, stepped)
        return run

    def free(self) -> None:
        for unit in self.units:
            unit.free()
        self.units = []

    def __enter__(self) -> "Master":
        return self

    def __exit__(self, *exc) -> None:
        self.free()


def run_system(system: System, options: MasterOptions) -> CoSimulationResult:
    with Master(system, options) as master:
        return master.run()
