"""The check every master makes on a scene with Contact elements: a macro step that carries a contact
deeper into its overlap than the step can resolve creates energy, and the run stops there, naming the
contact, the time and a step that would do, with the rows so far kept.

A Hertz contact between steel balls lasts about a tenth of a millisecond. A macro step longer than that
lands the bodies deep in each other; the contact's force at that overlap, held over the next step, then
throws them apart with thousands of times the energy the scene had. The check reads only what the
components report:

* E, the scene's energy as the master records it (each component's E, or E_pot for an element), and
* K, the energy in motion: every component's E_kin and every contact's stored E_pot.

After each accepted macro step, where E has risen above its lowest value so far by more than `SHARE` of
the largest K seen before the step (plus the rounding of the energies, `FLOOR` of their magnitude), the
step created energy no coupling error of a resolved contact creates, and the run stops. A scene's energy
drifts by a few per cent of K over many strikes when its contacts are resolved (the cradle over 10 s with
100 steps per contact: 2 to 9 per cent); a step into a contact it cannot resolve creates many times K at
once. The check is off where no component reports E_kin (the share would have no measure).

Inside the contact steps (harness/cosim/contacts.py) a blind step into a contact that fails the check is first
taken again from the contact's entry with a shorter contact step, as one that swings the rates is; only where
no entry is kept, or the entries are used up, does the run stop. The same arithmetic, in the same order, runs
in the master's C loop (cosim_core.c's guard_check): both
loops stop at the same step. The message is composed here, from the numbers either loop left.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from harness.cosim.unit import Unit

SHARE = 0.5  # energy created in the run beyond this share of the largest energy in motion stops it
FLOOR = 1e-9  # the energies' rounding, as a share of the largest sum of their magnitudes
STEPS_PER_CONTACT = 20  # the fixed macro step a stop advises: this many over the contact's duration
# A Hertz contact of approach speed v and deepest overlap delta lasts about HERTZ_DURATION delta / v
# (2.94 for the exponent 3/2; pi for a linear spring, whose delta / v is 1 / omega)
HERTZ_DURATION = 2.94


def larger(a: float, b: float) -> float:
    """C's fmax: a NaN loses to a number."""
    return b if math.isnan(a) else a if math.isnan(b) else max(a, b)


def smaller(a: float, b: float) -> float:
    """C's fmin."""
    return b if math.isnan(a) else a if math.isnan(b) else min(a, b)


@dataclass
class GuardStop:
    """Where the check stopped a run: the step, the scene's energies, and the contacts before the step."""
    t: float
    step: float
    created: float
    scale: float
    before: np.ndarray  # per contact: gap, gap rate, stored energy at the step's start


class ContactGuard:
    """The check of one run (see the module's text); `watches` are the contacts (contacts.Watch)."""

    def __init__(self, units: list[Unit], watches: list):
        self.units, self.watches = units, watches
        self.energies = [(u, u.energy_index) for u in units if u.energy_index is not None]
        self.kinetic = [(u, u.real_outputs.index("E_kin")) for u in units if "E_kin" in u.real_outputs]
        self.stored = [(w.unit, w.unit.real_outputs.index("E_pot") if "E_pot" in w.unit.real_outputs else -1)
                       for w in watches]
        self.active = bool(watches and self.kinetic and self.energies)
        self.low = self.scale = self.magnitude = 0.0
        self.before = np.zeros((len(watches), 3))
        self.stop: GuardStop | None = None

    def sums(self) -> tuple[float, float, float]:
        """E, K and the sum of the energies' magnitudes now, each summed in the units' order (as in C)."""
        energy = magnitude = kinetic = 0.0
        for unit, k in self.energies:
            energy += float(unit.y_now[k])
            magnitude += abs(float(unit.y_now[k]))
        for unit, k in self.kinetic:
            kinetic += float(unit.y_now[k])
        for unit, k in self.stored:
            if k >= 0:
                kinetic += float(unit.y_now[k])
        return energy, kinetic, magnitude

    def _remember(self) -> None:
        for row, (w, (unit, k)) in zip(self.before, zip(self.watches, self.stored)):
            row[0], row[1] = unit.y_now[w.gap], unit.y_now[w.rate]
            row[2] = unit.y_now[k] if k >= 0 else 0.0

    def begin(self) -> None:
        """At the run's start (the units initialized)."""
        if self.active:
            self.low, self.scale, self.magnitude = self.sums()
            self._remember()

    def check(self, t: float, step: float) -> bool:
        """After an accepted macro step [t, t + step]: False (and `stop` set) where it created too much energy."""
        if not self.active:
            return True
        energy, kinetic, magnitude = self.sums()
        self.magnitude = larger(self.magnitude, magnitude)
        created = energy - self.low
        if created > SHARE * self.scale + FLOOR * self.magnitude:
            self.stop = GuardStop(t, step, created, self.scale, self.before.copy())
            return False
        self.low = smaller(self.low, energy)
        self.scale = larger(self.scale, kinetic)
        self._remember()
        return True

    def mark(self) -> tuple:
        """The check's numbers now, to go back to (contacts.Entry)."""
        return self.low, self.scale, self.magnitude, self.before.copy()

    def back(self, mark: tuple) -> None:
        self.low, self.scale, self.magnitude = mark[:3]
        self.before[:] = mark[3]  # in place: the C loop writes into this array

    def message(self, contact_steps: int | None) -> str:
        """The one line that names the contact, the time, and a step that would do."""
        stop = self.stop
        k = self._culprit(stop)
        watch = self.watches[k]
        gap0, rate0, _ = stop.before[k]
        depth = max(-float(watch.unit.y_now[watch.gap]), -gap0, 0.0)
        text = (f"{watch.unit.name}: the macro step of {stop.step:.3g} s from t = {stop.t:.10g} s took the contact "
                f"{depth:.3g} m deep and created {stop.created:.3g} J, more than {SHARE:.0%} of the energy the scene "
                f"had in motion ({stop.scale:.3g} J)")
        duration = self._duration(watch, stop.scale, abs(rate0) or abs(float(watch.unit.y_now[watch.rate])))
        lasts = f"; the contact lasts about {duration:.2g} s" if duration else ""
        if contact_steps:
            return (f"{text}{lasts}: more steps per contact would do "
                    f"(--contact-steps {min(4 * contact_steps, 100_000)})"
                    + (f", or macro steps of at most {duration / STEPS_PER_CONTACT:.1g} s with --contact-steps 0"
                       if duration else ""))
        advice = f"a macro step of at most {duration / STEPS_PER_CONTACT:.1g} s (--step), or " if duration else ""
        return f"{text}{lasts}: {advice}steps that land on the contacts (--contact-steps, the default on such scenes)"

    def _culprit(self, stop: GuardStop) -> int:
        """The contact whose stored energy rose most over the step; where none rose, whose gap rate changed most."""
        rises = [float(unit.y_now[k]) - stop.before[i, 2] if k >= 0 else 0.0
                 for i, (unit, k) in enumerate(self.stored)]
        if max(rises) > 0.0:
            return int(np.argmax(rises))
        return int(np.argmax([abs(float(w.unit.y_now[w.rate]) - stop.before[i, 1])
                              for i, w in enumerate(self.watches)]))

    @staticmethod
    def _duration(watch, energy: float, speed: float) -> float | None:
        """The contact's duration were all of `energy` stored in it at its deepest, approached at `speed`: Hertz's
        deepest overlap ((n + 1) E / k)^(1 / (n + 1)) over the speed, times HERTZ_DURATION (an upper bound); None
        where the element does not say its k and exponent, or nothing moves."""
        try:
            k, exponent = watch.unit.instance.get("k", "exponent")
        except Exception:  # noqa: BLE001 (a contact element of another maker: no law to size by)
            return None
        if not (k > 0 and exponent > 0 and energy > 0 and speed > 0):
            return None
        deepest = ((exponent + 1) * energy / k) ** (1 / (exponent + 1))
        duration = HERTZ_DURATION * deepest / speed
        return duration if math.isfinite(duration) and duration > 0 else None
