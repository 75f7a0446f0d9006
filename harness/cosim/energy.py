"""Energy-conserving coupling over power bonds (in the manner of Sadjina et al.'s ECCO, which
libcosim offers): each bond pairs a force connection with the velocity connection at the same
point. Over a macro step [t, t + H] the receiver of the force gains the work of the force it was
handed, W_in = integral of F_in v, and the force's source (a Spring) gives up the work of its own
force along the velocity it was handed, W_out = integral of F v_in, where F_in, v_in are the inputs
as the receiving FMUs used them (held, or extrapolated with their derivatives) and F, v the outputs
the other side produced. The bond creates dE = W_in - W_out (destroys, when negative); a monolithic
system has dE = 0. A source that also reads the point's position (a Spring) is reset to the handed
position and velocity at each step's start, which changes its energy by -F dp: that is the bond's
too; the reset also changes the source's force and its rate at the step's start, which come from
the source's directional derivatives (`_Reset`). So measured, the bonds' energy summed over a run
is the run's energy drift to within a few per cent (1.002 to 1.03 times it on the spring scenes at
H = 0.005 to 0.02, tested).

Both works are integrated over the values at the step's ends by the trapezoid rule corrected with
the ends' derivatives, H/2 (g(t) + g(t+H)) + H^2/12 (g'(t) - g'(t+H)), exact to O(H^5): the plain
trapezoid rule errs by O(H^3) per step, as much as the coupling's own residual with linear
extrapolation, and would measure its own error instead. The derivatives come from the FMUs' output
derivatives (a velocity's is the acceleration) and the input derivatives handed over; with held
inputs (no derivatives) the plain trapezoid rule is used, whose error is then below the residual's
O(H^2).

* `BondedStep` measures dE per step and, optionally, corrects the next step's exchanged forces to
  give it back: each receiving component gets the force -dE v / (H |v|^2) along its bonds'
  velocities (no larger than the force it is handed).
* `EnergyStepControl` chooses the macro steps without rollback, by a PI controller on
  e = sum over bonds |dE_bond| / (tolerance H / duration), the residual against an even share of
  the run's energy tolerance: H_next = H min(max_rate, max(min_rate, safety e^-kI (e_last / e)^kP)).
  Each bond's magnitude, not the net |sum dE|: the net changes sign every few steps, and near
  each zero the controller took the largest step, whose residual then overran the tolerance (the
  chain of ten: 1.3e-2 J at 0.01 J).
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass

import numpy as np

from harness.cosim.algorithms import DONE, Exchange, Outcome
from harness.cosim.controls import ends_interval
from harness.cosim.structure import System
from harness.cosim.unit import Unit
from harness.errors import HarnessError
from harness.fmi.fmu_instance import DISCARD


@dataclass
class _Port:
    receiver: int  # unit that takes the force and gives the velocity
    force_in: int  # its input index of the force
    velocity_out: int  # its output index of the velocity
    source: int  # unit that gives the force and takes the velocity
    force_out: int
    velocity_in: int
    position_in: int | None  # the source's input index of the point's position, if it reads one


class _Reset:
    """A bond's source that reads its points' positions (a Spring): over a step it moves them with its
    velocity inputs (and their slopes), and at the next step's start they are reset to the positions
    and velocities handed over. The reset changes its energy by -F dp, and its force and the force's
    rate at the step's start by amounts its outputs (those of the last step's end) do not show: both
    come from its directional derivative along the reset, (dp, dv) for the force and (dv, da) for its
    rate. Without them the measure misses half to three quarters of the drift: the force is off by
    O(H^3) and its rate by O(H^2), which over a step is as much as the residual itself."""

    def __init__(self, unit: Unit, ports: list[int], all_ports: list[_Port], bonds: list) -> None:
        if not unit.instance.provides_directional_derivatives:
            raise HarnessError(f"bond {bonds[ports[0]]}: {unit.name} reads the point's position, and measuring "
                               f"the energy of its reset needs its directional derivatives, which its FMU does "
                               f"not provide")
        self.unit, self.ports = unit, np.array(ports)
        position_in = [all_ports[i].position_in for i in ports]
        velocity_in = [all_ports[i].velocity_in for i in ports]
        knowns = sorted(set(position_in) | set(velocity_in))  # an input in several bonds is seeded once
        self.position_slot = np.array([knowns.index(k) for k in position_in])
        self.velocity_slot = np.array([knowns.index(k) for k in velocity_in])
        self.position_in, self.velocity_in = np.array(position_in), np.array(velocity_in)
        reference = unit.instance.reference
        self.knowns = (ctypes.c_uint * len(knowns))(*[reference(unit.inputs[k].input) for k in knowns])
        self.unknowns = (ctypes.c_uint * len(ports))(
            *[reference(unit.real_outputs[all_ports[i].force_out]) for i in ports])
        self.seed = np.zeros(len(knowns))
        self.sensitivity = np.zeros(len(ports))
        self.derivative = unit.instance.raw.directional()
        self.moved: tuple | None = None  # where the last step took the positions, velocities and slopes
        self.held = np.zeros(len(ports))  # the slopes of held inputs

    def _along(self, positions: np.ndarray, velocities: np.ndarray) -> np.ndarray:
        """The change of the forces along a change of the position and velocity inputs."""
        unit = self.unit
        self.seed[self.position_slot], self.seed[self.velocity_slot] = positions, velocities
        unit.check(self.derivative(unit.component, self.unknowns, len(self.unknowns), self.knowns, len(self.knowns),
                                   self.seed.ctypes.data, self.sensitivity.ctypes.data), unit.names["directional"])
        return self.sensitivity.copy()

    def apply(self, H: float, linear: bool, start: np.ndarray, jumps: np.ndarray) -> None:
        """Puts the reset at the step just taken's start into `start` (the outputs there: force and
        its rate in columns 1 and 3) and `jumps` (the energy it changed), per port."""
        unit = self.unit
        positions, velocities = unit.u_view[self.position_in], unit.u_view[self.velocity_in]
        slopes = unit.du_view[self.velocity_in] if linear else self.held
        if self.moved is not None:
            dp, dv, da = positions - self.moved[0], velocities - self.moved[1], slopes - self.moved[2]
            jumps[self.ports] = -start[self.ports, 1] * dp
            start[self.ports, 1] += self._along(dp, dv)
            if linear:
                start[self.ports, 3] += self._along(dv, da)
        self.moved = (positions + velocities * H + slopes * H * H / 2, velocities + slopes * H, slopes)


class PowerBonds:
    """The system's bonds as indices into the units' buffers, and the energy they create per step."""

    def __init__(self, system: System, exchange: Exchange):
        self.exchange = exchange
        units = exchange.units
        index = {u.name: k for k, u in enumerate(units)}
        self.ports: list[_Port] = []
        for force, velocity, position in system.check_bonds():
            receiver, source = units[index[force.target]], units[index[force.source]]
            self.ports.append(_Port(index[force.target], receiver.inputs.index(force),
                                    receiver.real_outputs.index(velocity.output), index[force.source],
                                    source.real_outputs.index(force.output), source.inputs.index(velocity),
                                    None if position is None else source.inputs.index(position)))
        with_position: dict[int, list[int]] = {}  # source -> its ports that name a position
        for i, p in enumerate(self.ports):
            if p.position_in is not None:
                with_position.setdefault(p.source, []).append(i)
        self.resets = [_Reset(units[k], ports, self.ports, system.bonds) for k, ports in with_position.items()]
        self.created = np.zeros(len(self.ports))  # energy each bond created over the run so far [J]
        self.last = 0.0  # all bonds together, in the last macro step
        self.last_magnitude = 0.0  # the sum of each bond's |energy| in the last macro step

    def _inputs(self) -> np.ndarray:
        """Per port: the force input and its derivative at the receiver, the velocity input and its
        derivative at the source, as the step used them."""
        units, linear, corrections = self.exchange.units, self.exchange.linear, self.exchange.corrections
        values = []
        for p in self.ports:
            receiver, source = units[p.receiver], units[p.source]
            # the coupling's own residual: a correction handed back on purpose is not counted
            corrected = corrections[p.receiver][p.force_in] if corrections[p.receiver] is not None else 0.0
            values.append((receiver.u_view[p.force_in] - corrected, receiver.du_view[p.force_in] if linear else 0.0,
                           source.u_view[p.velocity_in], source.du_view[p.velocity_in] if linear else 0.0))
        return np.array(values).reshape(-1, 4)

    def before(self) -> np.ndarray:
        """The outputs at the step's start: receiver's velocity, source's force, and their derivatives."""
        return self._outputs()

    def _outputs(self) -> np.ndarray:
        units = self.exchange.units
        return np.array([(units[p.receiver].y_now[p.velocity_out], units[p.source].y_now[p.force_out],
                          units[p.receiver].dy_now[p.velocity_out], units[p.source].dy_now[p.force_out])
                         for p in self.ports]).reshape(-1, 4)

    def measure(self, H: float, start: np.ndarray) -> np.ndarray:
        """dE per port for the step just taken (the units' inputs are still those of the step)."""
        start, jumps = start.copy(), np.zeros(len(self.ports))
        for reset in self.resets:
            reset.apply(H, self.exchange.linear, start, jumps)
        inputs = self._inputs()
        end = self._outputs()
        force_in, d_force_in = inputs[:, 0], inputs[:, 1]
        velocity_in, d_velocity_in = inputs[:, 2], inputs[:, 3]
        ends = ((0.0, start), (H, end))
        # g = F_in v (the receiver's power), h = F v_in (the source's), and their time derivatives
        g = [(force_in + s * d_force_in) * o[:, 0] for s, o in ends]
        h = [o[:, 1] * (velocity_in + s * d_velocity_in) for s, o in ends]
        dg = [d_force_in * o[:, 0] + (force_in + s * d_force_in) * o[:, 2] for s, o in ends]
        dh = [o[:, 3] * (velocity_in + s * d_velocity_in) + o[:, 1] * d_velocity_in for s, o in ends]
        gained = H / 2 * (g[0] + g[1])
        given = H / 2 * (h[0] + h[1])
        if self.exchange.linear:  # the derivatives are read: the corrected rule
            gained += H * H / 12 * (dg[0] - dg[1])
            given += H * H / 12 * (dh[0] - dh[1])
        self.gained = gained  # per port: the work the receiver's force did over the step
        return gained - given + jumps


class BondedStep:
    """A macro step (the algorithm's, or iteration's) that measures the energy its bonds create and,
    with `correct`, hands it back through the next steps' forces."""

    CAP = 0.1

    def __init__(self, stepper, bonds: PowerBonds, correct: bool):
        self.stepper, self.bonds, self.correct = stepper, bonds, correct
        self.pending = 0.0  # energy the bonds created and the corrections have not given back yet [J]
        self.receivers = sorted({p.receiver for p in bonds.ports})

    def _set_corrections(self, H: float) -> None:
        """Forces along the bonds' velocities whose power over the next step gives back `pending`,
        shared among the bonds in proportion to their squared speeds; each at most CAP times the
        force its bond hands over, so that a slow point is not kicked (what is not given back now
        stays pending)."""
        exchange, ports = self.bonds.exchange, self.bonds.ports
        velocity = np.array([exchange.units[p.receiver].y_now[p.velocity_out] for p in ports])
        speed2 = float(velocity @ velocity)
        for k in self.receivers:
            exchange.corrections[k] = np.zeros(exchange.units[k].n_in)
        if speed2 <= 1e-12 or self.pending == 0.0:
            return
        for i, p in enumerate(ports):
            push = -self.pending / (H * speed2) * velocity[i]
            handed = self.CAP * abs(float(exchange.units[p.receiver].u_view[p.force_in]))
            exchange.corrections[p.receiver][p.force_in] = max(-handed, min(handed, push))

    def step(self, t: float, H: float) -> Outcome:
        if self.correct:
            self._set_corrections(H)
        start = self.bonds.before()
        returned = self._returned(H)
        outcome = self.stepper.step(t, H)
        if outcome.status == DISCARD:
            return outcome
        created = self.bonds.measure(H, start)
        self.bonds.last = float(np.sum(created))
        self.bonds.last_magnitude = float(np.sum(np.abs(created)))
        self.bonds.created += created
        self.pending += self.bonds.last + returned
        return outcome

    def bookkeeping(self) -> tuple:
        """What a rollback (step doubling, retry after a discard) restores besides the FMU states."""
        bonds = self.bonds
        return (self.pending, bonds.created.copy(), bonds.last, bonds.last_magnitude,
                [reset.moved for reset in bonds.resets])

    def restore_bookkeeping(self, kept: tuple) -> None:
        bonds = self.bonds
        self.pending, created, bonds.last, bonds.last_magnitude, moved = kept
        bonds.created[:] = created
        for reset, where in zip(bonds.resets, moved):
            reset.moved = where

    def _returned(self, H: float) -> float:
        """The work the corrections set for this step will do (negative: energy taken out),
        estimated at the step's start."""
        if not self.correct:
            return 0.0
        units = self.bonds.exchange.units
        return H * sum(float(self.bonds.exchange.corrections[p.receiver][p.force_in])
                       * float(units[p.receiver].y_now[p.velocity_out]) for p in self.bonds.ports)


class EnergyController:
    """The PI controller on the energy the bonds create (see the module's text): the next macro step `h`
    from the last step and the magnitude of what its bonds created. Serves EnergyStepControl and, on
    scenes with contacts, the contact steps (harness.cosim.contacts)."""

    SAFETY, MIN_RATE, MAX_RATE = 0.9, 0.2, 2.0

    def __init__(self, tolerance: float, duration: float, order: int, largest: float, smallest: float):
        self.tolerance, self.duration = tolerance, duration
        self.k_integral, self.k_proportional = 0.3 / order, 0.4 / order
        self.largest, self.smallest = largest, smallest
        self.h = largest / 4  # the first step: a quarter interval, then the controller's
        self.last_error = 1.0

    def update(self, step: float, magnitude: float, cut_short: bool) -> None:
        error = max(magnitude / (self.tolerance * step / self.duration), 1e-10)
        rate = self.SAFETY * error ** -self.k_integral * (self.last_error / error) ** self.k_proportional
        self.last_error = error
        if not cut_short or step >= self.h:  # a step cut short by the interval's end says little about h
            self.h = min(self.largest, max(self.smallest, step * min(self.MAX_RATE, max(self.MIN_RATE, rate))))


class EnergyStepControl:
    """Macro steps inside [t, t_end] chosen by the energy controller; no step is rejected, so no state is
    saved."""

    def __init__(self, step: BondedStep, controller: EnergyController, tally):
        self.bonded, self.controller, self.tally = step, controller, tally

    def advance(self, t: float, t_end: float) -> Outcome:
        while t < t_end:
            last = ends_interval(t, t_end, self.controller.h)
            step = t_end - t if last else self.controller.h
            outcome = self.bonded.step(t, step)
            if outcome.status == DISCARD:
                return outcome
            self.tally.macro_steps += 1
            t = t_end if last else t + step
            self.controller.update(step, self.bonded.bonds.last_magnitude, last)
        return DONE


def order_of(exchange: Exchange) -> int:
    """The coupling order the controller assumes: 2 with linear extrapolation, else 1."""
    return 2 if exchange.linear else 1

