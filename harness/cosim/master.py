"""The co-simulation master: Jacobi or Gauss-Seidel over a fixed communication grid, inputs held or
extrapolated linearly, a discarded step handled by rollback and smaller steps or a clear stop. The
components may be FMI 2.0 and FMI 3.0 FMUs in any mix.

The master is assembled from parts over one unit interface (`harness.cosim.unit`): an algorithm
(`harness.cosim.algorithms`), the controls over it (`harness.cosim.controls`: iteration, retry on
discard, step doubling; `harness.cosim.energy`: the energy step control; `harness.cosim.contacts`: steps
that land on contacts) and, for plain fixed-step runs and contact steps over plain macro steps, the same
loop in C (`harness.cosim.native_core`), which the tests keep bit-identical to the Python parts.

FMI 3.0 has no input derivatives: an FMI 3.0 component whose inputs its FMU lets the master set in
intermediate updates asks for them at the start of each step, at the step's end, and the master answers
on the line it extrapolates (`harness.cosim.unit.Unit.line`), which gives FMI 2.0's numbers. By default the
inputs are extrapolated linearly unless a receiver cannot take them so (an FMI 3.0 FMU without such inputs),
where they are held; asking for linear extrapolation (or iteration, which interpolates the inputs the same
way) with such a receiver is refused by name. FMI 3.0 sources hand over their output derivatives like FMI
2.0 ones.

The loop calls the FMUs' C functions directly with preallocated ctypes arrays: per FMU and macro
step one set, one step, one get of the float variables (plus the derivative calls for linear
extrapolation and a get of the integers where a component has integer outputs).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from harness.cosim.algorithm_registry import DEFAULT as DEFAULT_ALGORITHM, ENTRY
from harness.cosim.algorithms import ALGORITHMS, Exchange
from harness.cosim.contact_guard import ContactGuard
from harness.cosim.contacts import ENERGY_SMALLEST, ContactSteps, contact_watches
from harness.cosim.energy import BondedStep, EnergyController, EnergyStepControl, PowerBonds, order_of
from harness.cosim.controls import Iteration, RetryOnDiscard, StepDoubling, Stepper, Tally
from harness.cosim.native_core import NativeLoop, load_core
from harness.cosim.structure import System
from harness.cosim.unit import Arena, Unit, input_line_answer
from harness.errors import HarnessError, where
from harness.fmi.fmu_instance import DISCARD, ERROR, OK, STATUS_NAMES, SharedFmus
from harness.fmi.results import TimeTable
from harness.fmi.simulation import Progress, check_table_size, communication_grid
from harness.interrupts import held

EXTRAPOLATIONS = ("hold", "linear")
DEFAULT_CONTACT_STEPS = 100  # macro steps per contact on a scene with Contact elements, unless the user chooses


@dataclass
class MasterOptions:
    stop: float
    step: float
    start: float = 0.0
    algorithm: str = DEFAULT_ALGORITHM
    extrapolation: str | None = None  # hold or linear; None: linear unless a receiver cannot take it
    on_discard: str = "stop"  # "stop", or "retry": roll back (FMU states) and halve the step
    max_halvings: int = 10
    iterate_tol: float | None = None  # iterate each macro step to this change in the outputs
    max_iterations: int = 20
    tolerance: float | None = None    # adapt the macro step by step doubling to this error per step
    energy_tol: float | None = None   # adapt the macro step to keep the energy the power bonds create [J] below this
    energy_correction: bool = False   # hand the energy a bond created back through the next step's force
    # land macro steps on contacts' onsets, this many steps per contact; 0: plain macro steps; None:
    # DEFAULT_CONTACT_STEPS on a scene with Contact elements unless another control chooses the steps (--tolerance,
    # --energy-tolerance, --on-discard retry)
    contact_steps: int | None = None
    progress: bool = False

    def __post_init__(self) -> None:
        if self.algorithm not in ALGORITHMS:
            raise HarnessError(f"--algorithm {self.algorithm!r}: choose one of {', '.join(ALGORITHMS)}")
        if self.extrapolation is not None and self.extrapolation not in EXTRAPOLATIONS:
            raise HarnessError(f"--extrapolation {self.extrapolation!r}: choose one of {', '.join(EXTRAPOLATIONS)}")
        if self.on_discard not in ("stop", "retry"):
            raise HarnessError(f"on_discard {self.on_discard!r}: choose stop or retry")
        if self.tolerance is not None and self.energy_tol is not None:
            raise HarnessError("--tolerance (step doubling) and --energy-tolerance each choose the macro steps: "
                               "give one of them")
        if self.tolerance is not None and self.energy_correction:
            raise HarnessError("--energy-correction does not combine with --tolerance: step doubling compares one "
                               "step with two halves, and the correction's forces, which hand back energy over "
                               "later steps, are no error of either")
        if self.energy_tol is not None and self.on_discard == "retry":
            raise HarnessError("--energy-tolerance chooses the macro steps without rollback; it does not combine with "
                               "--on-discard retry")
        if self.contact_steps is not None:
            if not (isinstance(self.contact_steps, int) and 0 <= self.contact_steps <= 100_000):
                raise HarnessError(f"--contact-steps {self.contact_steps!r}: give a whole number of steps per contact "
                                   "from 1 to 100000, or 0 for plain macro steps")
            if self.contact_steps and self.tolerance is not None:
                raise HarnessError("--contact-steps chooses the macro steps itself: it does not combine with "
                                   "--tolerance (step doubling)")
            if self.contact_steps and self.on_discard == "retry":
                raise HarnessError("--contact-steps chooses the macro steps and rolls back itself: it does not combine "
                                   "with --on-discard retry")
        for name in ("iterate_tol", "tolerance", "energy_tol"):
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
    bond_energy: dict[str, float] = field(default_factory=dict)  # bond -> energy it created [J] (energy options)

    @property
    def energy_residual(self) -> float:
        """Largest |E_total(t) - E_total(0)|: the energy the coupling created or destroyed (for a
        system without damping)."""
        return float(np.max(np.abs(self.energy - self.energy[0]))) if len(self.energy) else 0.0


class Master:
    """Runs a System; build once, call run() once. It sets the parts up from the options (an
    algorithm, the controls over it, the C loop for plain fixed-step runs and contact steps) and records the rows."""

    def __init__(self, system: System, options: MasterOptions, fmus: SharedFmus | None = None):
        """`fmus`: extractions and loaded libraries to share with other runs (kept open); by default the
        master makes its own and removes them when it is freed."""
        self.system, self.options = system, options
        self.units: list[Unit] = []
        self._owns_fmus = fmus is None
        # instances of one FMU share its extraction and its loaded library
        self.fmus = fmus if fmus is not None else SharedFmus()
        arena = Arena()  # and the units' buffers lie side by side
        answer = input_line_answer()
        try:  # whatever fails while setting up, the instances made so far are freed
            with where(system.origin, system.workspace):
                for component in system.components:
                    with held():  # each instance made is in `units`, for free() to free
                        self.units.append(Unit(component, system, self.fmus, arena, answer))
                self.watches = contact_watches(self.units)  # the Contact elements' gaps, if any
                self.options = dataclasses.replace(options, extrapolation=self._extrapolation(options),
                                                   contact_steps=self._contact_steps(options))
                self.exchange = Exchange(self.units, self.options.extrapolation == "linear")
                for unit in self.units:
                    if unit.line is not None:
                        unit.line.active = int(self.exchange.linear)
                self._check_states(options)
                self.guard = ContactGuard(self.units, self.watches)
        except BaseException:
            self.free()
            raise
        self.tally = Tally()
        self.use_native = True  # the C loop for plain fixed-step runs and contact steps, when it is built
        try:
            self.interval = self._parts()
        except BaseException:
            self.free()
            raise

    def _parts(self) -> Stepper | StepDoubling | EnergyStepControl | ContactSteps:
        """What covers one communication interval: the macro step (the algorithm, or iteration over
        it), with retry on discard, or step doubling over it."""
        o = self.options
        algorithm = ALGORITHMS[o.algorithm](self.exchange)
        stepper = Iteration(self.exchange, o.iterate_tol, o.max_iterations, self.tally) if o.iterate_tol \
            else algorithm
        self.bonds = None
        if o.energy_tol or o.energy_correction:
            if not self.system.bonds:
                raise HarnessError(f"{self.system.name}: the energy-conserving coupling needs power bonds: declare "
                                   "\"bonds\" in the scene (a force input with the velocity output at its point)")
            self.bonds = PowerBonds(self.system, self.exchange)
            stepper = BondedStep(stepper, self.bonds, o.energy_correction)
            if o.energy_tol:
                landing = bool(o.contact_steps or self.watches)  # land on contacts, sized by energy
                energy = EnergyController(o.energy_tol, o.stop - o.start, order_of(self.exchange), o.step,
                                          o.step * (ENERGY_SMALLEST if landing else 2.0 ** -10))
                if landing:
                    return ContactSteps(stepper, self.exchange, o.step, o.contact_steps, self.tally, energy, self.guard)
                return EnergyStepControl(stepper, energy, self.tally)
        if o.contact_steps:
            return ContactSteps(stepper, self.exchange, o.step, o.contact_steps, self.tally, guard=self.guard)
        if o.tolerance:
            order = 2 if o.extrapolation == "linear" or o.iterate_tol else 1
            return StepDoubling(stepper, self.exchange, o.tolerance, o.stop - o.start, order, self.tally)
        if o.on_discard == "retry":
            return RetryOnDiscard(stepper, self.exchange, o.max_halvings, self.tally)
        return stepper

    def _contact_steps(self, options: MasterOptions) -> int:
        """The steps per contact asked for, or by default DEFAULT_CONTACT_STEPS on a scene with Contact elements
        whose steps no other control chooses; 0 for plain macro steps."""
        if options.contact_steps is not None:
            return options.contact_steps
        chosen = options.tolerance is not None or options.energy_tol is not None or options.on_discard == "retry"
        landing = self.watches and all(u.can_save for u in self.units)
        return DEFAULT_CONTACT_STEPS if landing and not chosen else 0

    def _extrapolation(self, options: MasterOptions) -> str:
        """The extrapolation asked for, or by default linear unless a component receives inputs it cannot
        take on a line: an FMI 3.0 FMU whose inputs cannot be set in intermediate updates (FMI 3.0 has no
        input derivatives)."""
        receivers = [u for u in self.units if u.n_in and not u.takes_slopes]
        if not receivers:
            return options.extrapolation or "linear"
        names = ", ".join(f"{u.name!r}" for u in receivers)
        if options.extrapolation == "linear":
            raise HarnessError(f"linear extrapolation hands over inputs on a line, which the FMI 3.0 component(s) "
                               f"{names} cannot take (their inputs are not set in intermediate updates): use "
                               "--extrapolation hold, or their FMI 2.0 FMUs")
        if options.iterate_tol:
            raise HarnessError(f"iterated macro steps interpolate the inputs on a line, which the FMI 3.0 component(s) "
                               f"{names} cannot take (their inputs are not set in intermediate updates): leave out "
                               "--iterate, or use their FMI 2.0 FMUs")
        return "hold"

    def _check_states(self, options: MasterOptions) -> None:
        """Rollback (retry after a discard, iteration, step doubling) needs every component's FMU state."""
        uses = [what for what, used in (("--on-discard retry", options.on_discard == "retry"),
                                        ("--iterate", options.iterate_tol), ("--tolerance", options.tolerance)) if used]
        lacking = [u.name for u in self.units if not u.can_save]
        if uses and lacking:
            raise HarnessError(f"{' and '.join(uses)} roll back through FMU states, which {', '.join(lacking)} "
                               f"cannot save (canGetAndSetFMUstate is not true)")

    def _initialize(self) -> None:
        for unit in self.units:
            with where(self.system.origin, self.system.workspace), where(f"component {unit.name!r}"):
                unit.instance.enter_initialization(self.options.start, **unit.start)
        self.exchange.settle()
        for unit in self.units:
            unit.instance.exit_initialization()
            unit.read_outputs(self.exchange.linear)
        self.exchange.accept()

    # ---- the run
    @property
    def columns(self) -> list[str]:
        """time, then <component>.<output> for every Real output, then every Integer output."""
        return ["time"] + [f"{u.name}.{n}" for u in self.units for n in u.real_outputs] + \
               [f"{u.name}.{n}" for u in self.units for n in u.integer_outputs]

    @property
    def macro_steps(self) -> int:
        return self.tally.macro_steps

    def run(self, on_row: Callable[[np.ndarray], None] | None = None) -> CoSimulationResult:
        options, tally = self.options, self.tally
        grid = communication_grid(options.start, options.stop, options.step)
        columns = self.columns
        check_table_size(len(grid), len(columns))
        table = np.empty((len(grid), len(columns)))
        energy = np.empty(len(grid))
        has_energy = any(u.energy_index is not None for u in self.units)
        stopped_at, message, rows = None, None, 0
        self._initialize()
        self.guard.begin()
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

        native = self._native_loop()
        if native is not None:
            rows, status, culprit_index = native.run(grid, table, energy, on_row, progress)
            if native.contacts is None:
                tally.macro_steps = rows - 1
            if status >= ERROR and culprit_index < 0 and self.guard.stop is not None:  # a step created energy
                stopped_at, message = grid[rows - 1], self.guard.message(options.contact_steps)
            elif status >= ERROR and culprit_index < 0:  # the contact steps stopped the run
                stopped_at, message = grid[rows - 1], self.interval.failure
            elif status >= ERROR:
                culprit = self.units[culprit_index]
                raise HarnessError(f"{culprit.name}: an {culprit.instance.prefix} call returned {STATUS_NAMES[status]} "
                                   f"near t = {grid[rows - 1]:g}: {culprit.instance.last_message()}")
            elif status != OK:
                culprit = self.units[culprit_index]
                stopped_at = culprit.instance.last_successful_time() if status == DISCARD else grid[rows - 1]
                message = f"{culprit.name} could not complete the step from t = {grid[rows - 1]:g}: " \
                          f"{culprit.instance.last_message()}"
            if not has_energy:
                energy[:rows] = math.nan  # as the Python loop records it
            grid = grid[:0]  # done: skip the Python loop
        advances = bool(options.tolerance or options.energy_tol or options.contact_steps)  # many steps an interval
        checks_itself = isinstance(self.interval, ContactSteps)  # the energy check after each of its steps
        for k, t in enumerate(grid):
            record(t)
            rows += 1
            if k + 1 == len(grid):
                break
            outcome = self.interval.advance(t, grid[k + 1]) if advances else self.interval.step(t, grid[k + 1] - t)
            if outcome.status == OK and not checks_itself and not self.guard.check(t, grid[k + 1] - t):
                stopped_at, message = t, self.guard.message(options.contact_steps)
                break
            if not advances:
                tally.macro_steps += outcome.status == OK
            if outcome.status == ERROR:
                stopped_at = t
                message = getattr(self.interval, "failure", "") or \
                    f"step doubling could not meet the tolerance {options.tolerance:g} after t = {t:g}"
                break
            if outcome.status == DISCARD:
                culprit = outcome.culprit
                stopped_at = culprit.instance.last_successful_time()
                message = (f"{culprit.name} could not complete the step from t = {t:g}"
                           + (f" even with {2 ** options.max_halvings}x smaller steps" if options.on_discard == "retry"
                              else "") + f": {culprit.instance.last_message()}")
                break
            if progress is not None:
                progress(grid[k + 1], (k + 1) / (len(grid) - 1))
        messages = [f"{u.name}: {m}" for u in self.units for m in u.instance.log.messages]
        bond_energy = {str(bond): float(e) for bond, e in zip(self.system.bonds, self.bonds.created)} \
            if self.bonds is not None else {}
        return CoSimulationResult(columns, table[:rows], energy[:rows], stopped_at, message, tally.macro_steps,
                                  tally.retries, messages, tally.iterations, tally.unconverged,
                                  self.options.extrapolation, bond_energy)

    def _native_loop(self) -> NativeLoop | None:
        """The C loop, for plain fixed-step runs and contact steps over plain macro steps, when it is built."""
        o = self.options
        if o.iterate_tol is not None or o.tolerance is not None or o.on_discard != "stop" or self.bonds is not None \
                or not self.use_native or ENTRY[o.algorithm].code is None:
            return None
        core = load_core()
        if core is None:
            return None
        contacts = self.interval if o.contact_steps else None
        loop = NativeLoop(core, self.units, o.algorithm, self.exchange.linear, contacts, self.tally, self.guard)
        return loop if contacts is None or loop.saves_states else None

    def free(self) -> None:
        with held():  # an interrupt does not leave instances or extracted FMUs behind
            units, self.units = self.units, []
            for unit in units:
                unit.free()
            if self._owns_fmus:
                self.fmus.close()

    def __enter__(self) -> "Master":
        return self

    def __exit__(self, *exc) -> None:
        self.free()


def run_system(system: System, options: MasterOptions, fmus: SharedFmus | None = None) -> CoSimulationResult:
    with Master(system, options, fmus) as master:
        return master.run()
