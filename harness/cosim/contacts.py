"""Macro steps that see contacts: a control that lands a macro step on the onset of each contact, resolves
the contact in steps sized for its duration, and lets the step grow again after the bodies part.

A contact between two FMUs lasts a tenth of a millisecond for steel balls: a fixed macro step either
steps over it or costs a million steps. The control watches every component with the outputs `gap` and
`gap_rate` (the Contact element), which it reads at each macro step's end; it knows nothing of the law.

* Apart (every gap >= 0): the step is the communication interval, unless a closing gap predicts its
  onset sooner (tau = gap / -gap_rate). Then the step goes half way to the prediction, and again, until the
  onset is less than one contact step away, and lands on it. The halving makes each later prediction
  better (the element predicts the gap at a step's end from its inputs' values and slopes, exact to
  O(H^3)), and the last, short steps land on the onset to a fraction of a contact step.
* A step that ends with a gap below minus half a contact step's approach (the prediction failed: an
  acceleration changed, a body arrived from outside the prediction) is rolled back through every unit's
  FMU state and redone half way to the secant estimate of the onset (but no shorter than the landing
  precision, a thousandth of a contact step: a step that short is kept even if it overshoots, as a
  grazing contact's does), up to `MAX_LANDINGS` times; the approach then lands on the onset as above.
  Only a step that begins apart can overshoot: the FMU states are saved before those alone.
* In contact (a gap < 0): the overlap behaves locally as an oscillator of angular frequency omega^2 =
  |d(gap_rate)/dt| / |gap|, so half a period pi / omega is the contact's duration; the step is that over
  `steps_per_contact`, grown at most twofold per step. At an overlap shallower than one step's approach,
  that approach stands in for |gap| (so the accelerations the bodies had apart do not read as a stiff
  contact).
* A contact's first steps are blind: until an overlap is deep enough to show the contact's frequency, the
  step grows from the last contact's (at first a ten-thousandth of the interval), and a contact shorter than
  that step is stepped through, the bodies driven deep into each other at once. The FMU states at the start
  of the step that entered the contact are kept through those steps; where one changes a gap's rate by more
  than one of `steps_per_contact` steps through a contact can (pi / steps_per_contact of the fastest approach,
  a contact turning the rate v around as v cos(omega t); beside what the rates' slopes account for), the
  units go back there and enter again with a contact step `REDO` times shorter, up to `MAX_LANDINGS` times.
  (Hertz's chain has no time scale of its own: a stiffer contact is only shorter, the rates after it the
  same.)
* After the last contact ends, the step grows twofold per step back to the communication interval.
* With the energy step control (`energy`, over steps that measure their bonds), no step is longer than the
  energy controller's: in contact that sizes the steps by the energy each exchange creates, beside (or,
  without steps per contact, instead of) the contact's duration.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from harness.cosim.algorithms import DONE, Exchange, Outcome
from harness.cosim.contact_guard import ContactGuard
from harness.cosim.controls import ends_interval
from harness.cosim.energy import EnergyController
from harness.cosim.unit import Snapshot, Unit
from harness.errors import HarnessError
from harness.fmi.fmu_instance import DISCARD, ERROR

MAX_LANDINGS = 30  # rollbacks to land one step on an onset
GROWTH = 2.0  # the largest ratio of one macro step to the one before, in and after contacts
FIRST_CONTACT_STEP = 1e-4  # the contact step before any contact was seen, as a share of the interval
LANDED = 1e-3  # an onset predicted within this share of a contact step is reached
SMALLEST = 2.0 ** -40  # the smallest macro step, as a share of the interval: below it the run stops, named
# The energy controller's shortest step here, as a share of the interval: the bonds measure the energy to
# about |F| ulp(x) per step (1e-14 J on the cradle), and a controller that chases that rounding shrinks its
# steps to nothing (the cradle at 1e-5 s and 1e-3 J stopped at 9e-18 s)
ENERGY_SMALLEST = 2.0 ** -20
# A blind step in a contact that changes a gap's rate by more than SWING times what one of steps_per_contact steps
# through a contact can change it was too long for the contact: back to the contact's entry, with a contact step
# REDO times shorter
SWING = 1.0
REDO = 8.0
# A gap above minus this is no contact: the Contact element's event rule (its indicator is gap + 1e-13 m), so that
# bodies touching at rest whose gap rounds to -1e-18 m are not read as a contact of no force and no frequency
ROUNDING = 1e-13


@dataclass(frozen=True)
class Watch:
    """A component's gap, its rate, and where they are among its outputs."""
    unit: Unit
    gap: int
    rate: int

    def gap_now(self) -> float:
        """The gap as the contact's own event rule reads it: an overlap shallower than the rounding is none."""
        return float(self.unit.y_now[self.gap]) + ROUNDING

    def values(self, exchange: Exchange, last_rate: float | None, last_step: float) -> tuple[float, float, float]:
        """gap, gap_rate and the rate's derivative at the units' current time (the output derivative with
        linear extrapolation, else the last step's difference)."""
        gap, rate = self.gap_now(), float(self.unit.y_now[self.rate])
        if exchange.linear:
            slope = float(self.unit.dy_now[self.rate])
        else:
            slope = (rate - last_rate) / last_step if last_rate is not None and last_step > 0 else 0.0
        return gap, rate, slope


def contact_watches(units: list[Unit]) -> list[Watch]:
    """Every unit with the outputs gap and gap_rate."""
    return [Watch(u, u.real_outputs.index("gap"), u.real_outputs.index("gap_rate")) for u in units
            if "gap" in u.real_outputs and "gap_rate" in u.real_outputs]


@dataclass
class Entry:
    """Where the units entered a contact: the FMU states at the start of the step that entered it, and the
    control's own numbers there, to go back to while the contact's first steps are blind."""
    snapshot: Snapshot
    t: float
    numbers: tuple  # contact_step, size, _wanted, last_rates, last_step, macro_steps, landed, energy's (h, last_error)
    guard: tuple | None = None  # the energy check's numbers (ContactGuard.mark)
    redos: int = 0


class ContactSteps:
    """Macro steps inside [t, t_end] that land on each contact's onset and resolve the contact (see the
    module's text). Counts its steps and rollbacks in the tally."""

    def __init__(self, stepper, exchange: Exchange, largest: float, steps_per_contact: int | None, tally,
                 energy: EnergyController | None = None, guard: ContactGuard | None = None):
        self.stepper, self.exchange, self.tally, self.energy, self.guard = stepper, exchange, tally, energy, guard
        self.units = exchange.units
        self.watches = contact_watches(self.units)
        if not self.watches:
            raise HarnessError("--contact-steps watches the gaps of Contact elements: the system has no component "
                               "with the outputs gap and gap_rate")
        lacking = [u.name for u in self.units if not u.can_save]
        if lacking:
            raise HarnessError(f"--contact-steps rolls back through FMU states, which {', '.join(lacking)} cannot "
                               "save (canGetAndSetFMUstate is not true)")
        self.largest, self.per_contact = largest, steps_per_contact
        self.contact_step = largest * FIRST_CONTACT_STEP  # the last contact's step: where the next one starts
        self.last_step = largest  # the step taken last: the held inputs' slope divides by it
        self.size = largest  # the step the next grows from: the last, unless the interval's end cut it short
        self._wanted = largest  # the step the plan wanted, before the interval's end
        self.last_rates: list[float | None] = [None] * len(self.watches)
        self.landings = 0  # rollbacks to land on an onset
        self.landed: list[float] = []  # the ends of the steps planned onto an onset
        self.failure = ""  # why the control stopped a run
        self._landing = False
        self._blind = False  # the step planned last is in a contact whose frequency no overlap shows yet
        self._entry: Entry | None = None  # the units where they entered a contact, while its first steps are blind

    def too_small(self, t: float) -> str:
        return f"the contact steps fell below {self.largest * SMALLEST:.3g} s after t = {t:.17g}"

    def too_short(self, t: float) -> str:
        return (f"a contact entered at t = {t:.17g} is shorter than its first contact steps, also after "
                f"{MAX_LANDINGS} entries, each with a contact step {REDO:g} times shorter (the last "
                f"{self.contact_step:.3g} s)")

    def _state(self) -> list[tuple[float, float, float]]:
        return [w.values(self.exchange, r, self.last_step) for w, r in zip(self.watches, self.last_rates)]

    def _planned(self, state: list[tuple[float, float, float]], room: float) -> tuple[float, bool]:
        """The next step (at most `room`) and whether any contact acts at its start."""
        touching = [(g, r, a) for g, r, a in state if g < 0.0]
        if touching:
            # the overlap's own frequency, from the overlaps deeper than one step's approach: at a shallower one
            # the accelerations the bodies have from elsewhere (a neighbour's push) would read as a stiff contact
            deep = [(g, a) for g, r, a in touching if -g > abs(r) * self.size]
            omega = max((math.sqrt(abs(a) / -g) for g, a in deep), default=0.0)
            sized = math.pi / omega / self.per_contact if omega > 0 and self.per_contact else math.inf
            self._blind = not sized <= GROWTH * self.size  # the step grows: the contact's frequency does not bound it
            step = min(sized, GROWTH * self.size)
            if self.energy is not None:
                step = min(step, self.energy.h)
            self.contact_step = step
        else:
            self._blind = False
            step = min(self.largest, GROWTH * self.size)
            if self.energy is not None:
                step = min(step, self.energy.h)
        # the gaps that will cross zero: an onset ahead, or the end of a contact; halve the way, then land on it
        crossing = [g / -r for g, r, _ in state if (g >= 0.0 and r < 0.0) or (g < 0.0 and r > 0.0)]
        if crossing:
            onset = min(crossing)
            if onset <= self.contact_step * LANDED:  # on the onset already: into the contact
                step = min(step, self.contact_step)
            elif onset <= min(step, self.contact_step):
                step, self._landing = onset, True
            elif onset < 2 * step:
                step = onset / 2
        self._wanted = step
        return min(step, room), bool(touching)

    def advance(self, t: float, t_end: float) -> Outcome:
        try:
            return self._advance(t, t_end)
        finally:
            self._leave_entry()  # no state outlives the interval: its rows are recorded

    def _advance(self, t: float, t_end: float) -> Outcome:
        while t < t_end:
            state = self._state()
            self._landing = False
            step, touching = self._planned(state, t_end - t)
            if not (touching and self._blind):  # the contact's frequency is known, or no contact acts
                self._leave_entry()
            last = ends_interval(t, t_end, step)
            if not last and step < self.largest * SMALLEST:
                self.failure = self.too_small(t)
                return Outcome(ERROR)
            if last:
                step = t_end - t
            if touching:  # inside a contact no step is rolled back, but to the contact's entry while blind
                outcome = self.stepper.step(t, step)
                if outcome.status == DISCARD:
                    return outcome
                if self._entry is not None and self._swung(state, step):
                    if self._entry.redos == MAX_LANDINGS:
                        self.failure = self.too_short(self._entry.t)
                        return Outcome(ERROR)
                    t = self._enter_again()
                    continue
            else:
                step, last = self._landed_step(t, step, last, state)
                if step is None:
                    return last
            if self.guard is not None and not self.guard.check(t, step):
                if self._entry is not None and self._entry.redos < MAX_LANDINGS:  # a blind step: enter again
                    self.guard.stop = None
                    t = self._enter_again()
                    continue
                self.failure = self.guard.message(self.per_contact)
                return Outcome(ERROR)
            self.tally.macro_steps += 1
            self.last_rates = [s[1] for s in state]
            self.last_step = step
            if self.energy is not None:
                self.energy.update(step, self.stepper.bonds.last_magnitude, last)
            # a step cut short by the interval's end (to one rounding, at worst) says nothing of the next
            self.size = max(step, self._wanted) if last else step
            t = t_end if last else t + step
            if self._landing:
                self.landed.append(t)
        return DONE

    def _landed_step(self, t: float, step: float, last: bool, state: list[tuple[float, float, float]]):
        """A step that began apart, rolled back and redone half way to the onset where it overshot one: the
        step taken and whether it ends the interval, or (None, the discard)."""
        numbers = self._numbers()
        start = Snapshot(self.units, self.stepper).take()
        try:
            for landing in range(MAX_LANDINGS + 1):
                outcome = self.stepper.step(t, step)
                if outcome.status == DISCARD:
                    return None, outcome
                missed = self._overshoot(state, step)
                shortest = self.contact_step * LANDED  # an onset nearer than this is reached: no shorter retry
                if missed is None or landing == MAX_LANDINGS or step <= shortest:
                    break
                start.restore()
                self.tally.retries += 1
                self.landings += 1
                step = max(missed / 2, shortest)  # half way to the onset: the approach then lands on it as always
                last, self._landing = False, False
            if self._entry is None and any(w.gap_now() < 0.0 for w in self.watches):
                # into a contact: kept while it is blind (the check has not seen this step yet)
                self._entry = Entry(start, t, numbers, self.guard.mark() if self.guard is not None else None)
                start = None
        finally:
            if start is not None:
                start.release()
        return step, last

    def _numbers(self) -> tuple:
        """The control's numbers that a step changes, to go back to (Entry.numbers)."""
        energy = (self.energy.h, self.energy.last_error) if self.energy is not None else None
        return (self.contact_step, self.size, self._wanted, list(self.last_rates), self.last_step,
                self.tally.macro_steps, len(self.landed), energy)

    def _swung(self, before: list[tuple[float, float, float]], step: float) -> bool:
        """After a blind step in a contact: whether a gap's rate changed by more than one contact step can change
        it, SWING times pi / steps_per_contact of the fastest approach at the step's start (a contact turns the
        rate v around as v cos(omega t), by at most v omega per second, over pi / omega), beside what the
        rates' slopes account for."""
        share = math.pi / self.per_contact if self.per_contact else 1.0
        bound = SWING * (share * max(abs(r) for _, r, _ in before) + max(abs(a) for _, _, a in before) * step)
        return any(abs(float(w.unit.y_now[w.rate]) - r) > bound for w, (_, r, _) in zip(self.watches, before))

    def _enter_again(self) -> float:
        """The units back where they entered the contact, the control's numbers too, and the contact step REDO
        times shorter than at the last entry; returns the entry's time."""
        entry = self._entry
        entry.snapshot.restore()
        entry.redos += 1
        contact_step, self.size, self._wanted, rates, self.last_step, steps, landed, energy = entry.numbers
        self.contact_step = contact_step / REDO ** entry.redos
        self.last_rates = list(rates)
        self.tally.macro_steps = steps
        del self.landed[landed:]
        if energy is not None:
            self.energy.h, self.energy.last_error = energy
        if entry.guard is not None:
            self.guard.back(entry.guard)
        self.tally.retries += 1
        return entry.t

    def _leave_entry(self) -> None:
        if self._entry is not None:
            self._entry.snapshot.release()
            self._entry = None

    def _overshoot(self, before: list[tuple[float, float, float]], step: float) -> float | None:
        """After a step that began apart: None where no gap fell below the landing depth, else the step to
        the earliest secant estimate of an onset, from the gaps before and after. (The end of a contact is
        not rolled back to: its force has faded to zero there.)"""
        shortest = None
        for watch, (g0, r0, _) in zip(self.watches, before):
            g1 = watch.gap_now()
            depth = 0.5 * abs(r0) * self.contact_step  # the approach of half a contact step, in gap
            if g1 < -depth and g0 > 0.0:
                guess = step * g0 / (g0 - g1)
                shortest = guess if shortest is None else min(shortest, guess)
        return shortest

