"""How the units advance one macro step together: the exchange of outputs to inputs (held or
extrapolated linearly) and the two orders of stepping, Jacobi and Gauss-Seidel.

In FMI 2.0 an input and its derivative are values at the start of the receiving step. With linear
extrapolation a source that has not stepped yet hands over y(t) and its output derivative; in
Gauss-Seidel a source that has already stepped hands over y(t) with the slope (y(t+H) - y(t))/H,
which is second-order accurate without making a receiver such as the Spring advance y(t+H) again.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from harness.cosim.algorithm_registry import NAMES
from harness.cosim.structure import Connection
from harness.cosim.unit import Unit
from harness.errors import HarnessError
from harness.fmi.fmu_instance import DISCARD, OK


class Outcome(NamedTuple):
    status: int  # OK, or DISCARD
    culprit: Unit | None = None  # the unit that discarded


DONE = Outcome(OK)


class Exchange:
    """Which outputs feed which inputs, and how they are handed over (held or linear)."""

    def __init__(self, units: list[Unit], linear: bool):
        self.units, self.linear = units, linear
        index = {u.name: k for k, u in enumerate(units)}
        # For each receiving unit: (source index, source output indices, input indices), vectorised.
        self.routes: list[list[tuple[int, np.ndarray, np.ndarray]]] = []
        for unit in units:
            grouped: dict[int, tuple[list[int], list[int]]] = {}
            for k, c in enumerate(unit.inputs):
                if c.source not in index:
                    raise HarnessError(f"connection {c}: no component {c.source!r}")
                source = units[index[c.source]]
                if c.output not in source.real_outputs:
                    raise HarnessError(f"connection {c}: {c.source} has no Real output {c.output!r}")
                _check_units(source, c.output, unit, c.input, c)
                outs, ins = grouped.setdefault(index[c.source], ([], []))
                outs.append(source.real_outputs.index(c.output))
                ins.append(k)
            self.routes.append([(s, np.array(o), np.array(i)) for s, (o, i) in grouped.items()])
        # per unit: what is added to its routed inputs (the energy correction), or None
        self.corrections: list[np.ndarray | None] = [None] * len(units)

    def feed(self, k: int, H: float, stepped: list[bool]) -> None:
        """Sets the inputs of unit k for the step [t, t + H]; stepped[j]: unit j is already at t + H."""
        unit = self.units[k]
        if not unit.n_in:
            return
        linear = self.linear
        for j, outs, ins in self.routes[k]:
            source = self.units[j]
            if stepped[j]:
                if linear:
                    unit.u_view[ins] = source.y_now[outs]
                    unit.du_view[ins] = (source.y_next_view[outs] - source.y_now[outs]) / H
                else:
                    unit.u_view[ins] = source.y_next_view[outs]
            else:
                unit.u_view[ins] = source.y_now[outs]
                if linear:
                    unit.du_view[ins] = source.dy_now[outs]
        if self.corrections[k] is not None:
            unit.u_view += self.corrections[k]
        unit.write_inputs(linear)

    def feed_between(self, k: int, H: float, ends: list[np.ndarray]) -> None:
        """Sets the inputs of unit k to vary linearly from their sources' outputs now to `ends` (each
        source's outputs at t + H, as guessed)."""
        unit = self.units[k]
        if not unit.n_in:
            return
        for j, outs, ins in self.routes[k]:
            source = self.units[j]
            unit.u_view[ins] = source.y_now[outs]
            unit.du_view[ins] = (ends[j][outs] - source.y_now[outs]) / H
        if self.corrections[k] is not None:
            unit.u_view += self.corrections[k]
        unit.write_inputs(True)

    def settle(self, tolerance: float = 1e-14, passes: int = 50) -> None:
        """Copies connected outputs to inputs until they settle (inside initialization mode), so
        that forces at t = 0 are consistent."""
        for _ in range(passes):
            change = 0.0
            for unit in self.units:
                unit.read_outputs(False)
                unit.y_now[:] = unit.y_next_view
            for k, unit in enumerate(self.units):
                if not unit.n_in:
                    continue
                before = unit.u_view.copy()
                for j, outs, ins in self.routes[k]:
                    unit.u_view[ins] = self.units[j].y_now[outs]
                unit.write_inputs(False)
                change = max(change, float(np.max(np.abs(unit.u_view - before))))
            if change <= tolerance:
                return

    def accept(self) -> None:
        for unit in self.units:
            unit.accept(self.linear)


def _check_units(source: Unit, output: str, target: Unit, input_: str, connection: Connection) -> None:
    a = source.instance.variables[output].unit
    b = target.instance.variables[input_].unit
    if a and b and a != b:
        raise HarnessError(f"connection {connection}: units differ ({a} to {b})")


class Jacobi:
    """Every unit takes the inputs of the step's start, then all step."""

    def __init__(self, exchange: Exchange):
        self.exchange = exchange
        self.not_stepped = [False] * len(exchange.units)

    def step(self, t: float, H: float) -> Outcome:
        exchange = self.exchange
        for k in range(len(exchange.units)):
            exchange.feed(k, H, self.not_stepped)
        for unit in exchange.units:
            if unit.step(t, H) == DISCARD:
                return Outcome(DISCARD, unit)
        for unit in exchange.units:
            unit.read_outputs(exchange.linear)
        exchange.accept()
        return DONE


class GaussSeidel:
    """The units step in the order the system lists them; each takes what those before it reached."""

    def __init__(self, exchange: Exchange):
        self.exchange = exchange

    def step(self, t: float, H: float) -> Outcome:
        exchange = self.exchange
        stepped = [False] * len(exchange.units)
        for k, unit in enumerate(exchange.units):
            exchange.feed(k, H, stepped)
            if unit.step(t, H) == DISCARD:
                return Outcome(DISCARD, unit)
            unit.read_outputs(exchange.linear)
            stepped[k] = True
        exchange.accept()
        return DONE


# the implementation of each registered algorithm (harness/cosim/algorithm_registry.py)
ALGORITHMS = {"jacobi": Jacobi, "gauss-seidel": GaussSeidel}
if tuple(ALGORITHMS) != NAMES:
    raise ImportError(f"harness.cosim.algorithms implements {tuple(ALGORITHMS)}, the registry names {NAMES}")
