"""Controls over a macro step: each wraps a stepper (an algorithm, or another control) and rolls the
units back through FMU states (`Snapshot`, released as soon as it has served).

* `Iteration`: repeats a macro step with the inputs interpolated towards the last pass's outputs
  until they settle.
* `RetryOnDiscard`: after a discard, rolls back and covers the step in halves.
* `StepDoubling`: chooses the macro steps inside a communication interval by comparing one step
  with two half steps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from harness.cosim.algorithms import DONE, Exchange, Outcome
from harness.cosim.unit import Snapshot
from harness.fmi.fmu_instance import DISCARD, ERROR


def ends_interval(t: float, t_end: float, step: float) -> bool:
    """Whether a step from t is the interval's last: it reaches t_end to 1e-12 of the room left, or to a few
    roundings of t_end (so that the time's rounding never leaves a sliver of an interval to step)."""
    return (t_end - t) - step <= max(1e-12 * (t_end - t), 8 * math.ulp(t_end))


class Stepper(Protocol):
    def step(self, t: float, H: float) -> Outcome: ...


@dataclass
class Tally:
    """What the parts count over a run."""
    macro_steps: int = 0
    retries: int = 0  # macro steps redone: after a discard, or rejected by step doubling
    iterations: int = 0  # passes of iterated macro steps
    unconverged: int = 0  # iterated macro steps that reached the most passes allowed


class Iteration:
    """Fixed-point iteration of one macro step: every input varies linearly from its source's value
    at t to the source's value at t + H from the previous pass (the first pass uses the
    extrapolation), until the outputs at t + H change by less than tolerance (1 + |y|)."""

    def __init__(self, exchange: Exchange, tolerance: float, max_iterations: int, tally: Tally):
        self.exchange, self.tolerance, self.max_iterations, self.tally = exchange, tolerance, max_iterations, tally

    def step(self, t: float, H: float) -> Outcome:
        exchange, units = self.exchange, self.exchange.units
        with Snapshot(units) as start:
            guess = [u.y_now + H * u.dy_now if exchange.linear else u.y_now.copy() for u in units]
            for iteration in range(1, self.max_iterations + 1):
                self.tally.iterations += 1
                for k in range(len(units)):
                    exchange.feed_between(k, H, guess)
                for unit in units:
                    if unit.step(t, H) == DISCARD:
                        return Outcome(DISCARD, unit)
                change = 0.0
                for unit, g in zip(units, guess):
                    unit.read_outputs(exchange.linear)
                    change = max(change, float(np.max(np.abs(unit.y_next_view - g) / (1.0 + np.abs(unit.y_next_view)),
                                                      initial=0.0)))
                if change <= self.tolerance or iteration == self.max_iterations:
                    self.tally.unconverged += change > self.tolerance
                    exchange.accept()
                    return DONE
                guess = [unit.y_next_view.copy() for unit in units]
                start.restore()
        raise AssertionError("unreachable")


class RetryOnDiscard:
    """[t, t + H] in one macro step or, after a discard, rolled back and done in halves, down to
    H / 2^max_halvings."""

    def __init__(self, stepper: Stepper, exchange: Exchange, max_halvings: int, tally: Tally):
        self.stepper, self.units, self.max_halvings, self.tally = stepper, exchange.units, max_halvings, tally

    def step(self, t: float, H: float, depth: int = 0) -> Outcome:
        with Snapshot(self.units, self.stepper) as start:
            outcome = self.stepper.step(t, H)
            if outcome.status != DISCARD or depth >= self.max_halvings:
                return outcome
            start.restore()
        self.tally.retries += 1
        outcome = self.step(t, H / 2, depth + 1)
        if outcome.status == DISCARD:
            return outcome
        return self.step(t + H / 2, H / 2, depth + 1)


class StepDoubling:
    """An interval [t, t_end] in macro steps chosen by step doubling: one step of h against two of
    h/2 from the same state (rolled back in between); the difference, divided by 2^p - 1, estimates
    the coupling error of the two half steps, which are kept when it is within
    tolerance (1 + |y|) h / duration. Controlling the error per unit step keeps the sum of the local
    errors, and so the global error, near the tolerance."""

    def __init__(self, stepper: Stepper, exchange: Exchange, tolerance: float, duration: float, order: int,
                 tally: Tally):
        self.stepper, self.units = stepper, exchange.units
        self.tolerance, self.duration, self.order, self.tally = tolerance, duration, order, tally
        self.proposal: float | None = None  # the step to try first in the next interval

    def _outputs(self) -> np.ndarray:
        return np.concatenate([unit.y_now for unit in self.units])

    def advance(self, t: float, t_end: float) -> Outcome:
        """Reaches t_end; DISCARD with the culprit, or ERROR, when the step falls below
        (t_end - t) / 2^20."""
        smallest = (t_end - t) / 2 ** 20
        h = min(self.proposal or (t_end - t), t_end - t)
        steps_before = self.tally.macro_steps  # a failed interval adds none: its steps reach no recorded row
        while t < t_end:
            last = h >= t_end - t
            step = t_end - t if last else h
            with Snapshot(self.units, self.stepper) as start:
                outcome = self.stepper.step(t, step)
                if outcome.status != DISCARD:
                    full = self._outputs()
                    start.restore()
                    outcome = self.stepper.step(t, step / 2)
                    if outcome.status != DISCARD:
                        outcome = self.stepper.step(t + step / 2, step / 2)
                if outcome.status == DISCARD:
                    error = math.inf
                else:
                    half = self._outputs()
                    error = float(np.max(np.abs(half - full) / (1.0 + np.abs(half)))) / (2 ** self.order - 1) \
                        / (self.tolerance * step / self.duration)
                # local error ~ h^(p+1) against a bound ~ h: the step scales with error^(-1/p)
                factor = 2.0 if error == 0 else min(2.0, max(0.2, 0.9 * error ** (-1.0 / self.order)))
                if error <= 1.0:
                    t = t_end if last else t + step
                    self.tally.macro_steps += 2
                    if not last or step >= h:
                        h = step * factor
                    continue
                start.restore()
            self.tally.retries += 1
            h = step * min(factor, 0.5)
            if h < smallest:
                self.tally.macro_steps = steps_before
                return outcome if outcome.status == DISCARD else Outcome(ERROR)
        self.proposal = h
        return DONE
