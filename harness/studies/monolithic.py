"""The monolithic reference of any scene of objects joined by Springs and Contacts: one system of
equations, integrated as a whole, against which the co-simulation's coupling error is measured.

Every object comes from the object file its FMU carries, through Lagrange's equations
(`harness.objects.derivation`, lambdified, never the generated C):

    M(q, t) a = f(q, v, t) + B(q, t) F - M d v,

with F its force inputs. The Spring and the Contact are massless elements, coded here from their
contracts (SPEC 4 and 10), not from their C. A Spring, with e = (b - a) / |b - a|:
Fa = (k (|b - a| - l0) + c (b_v - a_v) . e) e and Fb = -Fa, for l0 = 0 simply k (b - a) + c ((b_v - a_v) . e) e.
A Contact between bodies of radii R_a and R_b, with the overlap delta = R_a + R_b - |b - a|:
Fb = k delta^n (1 + c d(delta)/dt) e while delta > 0 and that is positive, else 0, and Fa = -Fb.
Adding the springs' potential k/2 (r - l0)^2 (a contact's k delta^(n+1)/(n+1)) and their damping to
the objects' Lagrangians gives exactly these forces at the points the elements join, so the scene's
connections (positions and velocities into the elements, forces back) are one system of equations
with no delay: the elements' outputs are evaluated from the objects' outputs at the same instant,
then the objects' accelerations from those forces. An input no connection feeds keeps its start
value.

Objects of one kind are evaluated together (numpy arrays over the instances), so a chain of a
thousand pendulums costs one evaluation per kind, not a thousand. DOP853 at rtol = atol = 1e-12
integrates it. A contact's force has no second derivative where its overlap begins and ends: each
onset and end is located as an event (the gap's zero) and the integration starts again there, so no
step of the reference straddles one (`events` lists them).

This reference measures the coupling (and the methods' error), not the objects' equations: those
are proven against an independent numeric route by `harness validate`.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import sympy as sp

from harness.cosim.structure import System
from harness.errors import HarnessError
from harness.fmi.fmu_instance import float_start_values

REFERENCE_BUDGET = 2_000_000  # right-hand-side evaluations of one monolithic reference
MAX_EVENTS = 100_000  # contact onsets and ends in one reference
CONTACT_ROUNDING = 1e-13  # an overlap begins below -1e-13 m (the Contact's event indicator is gap + 1e-13 m)


@dataclass(frozen=True)
class ElementLaw:
    """A massless element's contract: its inputs (the two points), its outputs (the force components
    first), its parameters, and the law from parameters (elements, p) and inputs (elements, i) to
    outputs (elements, o)."""
    identifier: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    forces: int  # the first `forces` outputs are force components
    parameters: tuple[str, ...]
    law: Callable[[np.ndarray, np.ndarray, str], np.ndarray]


def _spring_law(parameters: np.ndarray, inputs: np.ndarray, scene: str) -> np.ndarray:
    """Fa_x Fa_y Fb_x Fb_y E_pot of Springs."""
    k, c, l0 = parameters.T
    d = inputs[:, 4:6] - inputs[:, 0:2]
    dv = inputs[:, 6:8] - inputs[:, 2:4]
    r = np.hypot(d[:, 0], d[:, 1])
    if np.any((r == 0) & (l0 > 0)):
        raise HarnessError(f"{scene}: a Spring of rest length > 0 has both ends at one point: its direction is "
                           "undefined")
    e = d / np.where(r > 0, r, 1.0)[:, None]  # 0 where r = 0 (then l0 = 0: the force is k d)
    rate = np.sum(dv * e, axis=1)
    force_a = np.where((l0 == 0)[:, None], k[:, None] * d + (c * rate)[:, None] * e,
                       (k * (r - l0) + c * rate)[:, None] * e)
    return np.column_stack([force_a, -force_a, k / 2 * (r - l0) ** 2])


def _contact_law(parameters: np.ndarray, inputs: np.ndarray, scene: str) -> np.ndarray:
    """Fa_x Fa_y Fa_z Fb_x Fb_y Fb_z gap gap_rate E_pot of Contacts."""
    k, n, c, radius_a, radius_b = parameters.T
    d = inputs[:, 6:9] - inputs[:, 0:3]
    w = inputs[:, 9:12] - inputs[:, 3:6]
    r = np.sqrt(np.sum(d * d, axis=1))
    if np.any(r == 0):
        raise HarnessError(f"{scene}: a Contact has both centres at one point: the direction of its push is undefined")
    e = d / r[:, None]
    gap, rate = r - radius_a - radius_b, np.sum(w * e, axis=1)
    overlap = np.maximum(-gap, 0.0)
    push = np.maximum(k * overlap ** n * (1.0 - c * rate), 0.0)
    return np.column_stack([-push[:, None] * e, push[:, None] * e, gap, rate, k * overlap ** (n + 1) / (n + 1)])


ELEMENT_LAWS = {law.identifier: law for law in (
    ElementLaw("Spring", ("a_x", "a_y", "a_vx", "a_vy", "b_x", "b_y", "b_vx", "b_vy"),
               ("Fa_x", "Fa_y", "Fb_x", "Fb_y", "E_pot"), 4, ("k", "c", "l0"), _spring_law),
    ElementLaw("Contact", ("a_x", "a_y", "a_z", "a_vx", "a_vy", "a_vz", "b_x", "b_y", "b_z", "b_vx", "b_vy", "b_vz"),
               ("Fa_x", "Fa_y", "Fa_z", "Fb_x", "Fb_y", "Fb_z", "gap", "gap_rate", "E_pot"), 6,
               ("k", "exponent", "c", "R_a", "R_b"), _contact_law))}


@dataclass
class _Elements:
    """The instances of one element law: arrays over the instances (rows)."""
    law: ElementLaw
    names: list[str] = field(default_factory=list)
    parameters: list[list[float]] = field(default_factory=list)
    inputs: list[list[float]] = field(default_factory=list)  # start values, overwritten where fed

    def freeze(self) -> None:
        self.P = np.array(self.parameters, dtype=float).reshape(len(self.names), len(self.law.parameters))
        self.U = np.array(self.inputs, dtype=float).reshape(len(self.names), len(self.law.inputs))


class _OverBudget(Exception):
    pass


class _FmuFacts:
    """What the reference reads from each FMU file, once per file however many components use it: its
    description, the element law it follows (a Spring's, a Contact's) or else the object file it carries."""

    def __init__(self, system: System):
        self.system = system
        self._read: dict[Path, tuple] = {}

    def __call__(self, component) -> tuple[object, ElementLaw | None, tuple[str, str] | None]:
        from harness.fmi.fmu_instance import read_description
        path = Path(component.fmu)
        if path not in self._read:
            description = read_description(path)
            interface = description.coSimulation or description.modelExchange
            law = ELEMENT_LAWS.get(interface.modelIdentifier)
            if law is not None and not {v.name for v in description.modelVariables} >= \
                    set(law.inputs + law.outputs + law.parameters):
                law = None
            self._read[path] = (description, law, None if law else _carried_object_file(component, self.system))
        return self._read[path]


@functools.lru_cache(maxsize=32)
def _kind_functions(text: str, origin: str):
    """The lambdified equations of one object file (cached by its text: deriving takes seconds)."""
    from harness.objects.derivation import derive
    from harness.objects.object_file import read_object_file
    spec = read_object_file(origin, text)
    d = derive(spec)
    parameters = spec.parameter_symbols()
    arguments = parameters + spec.q + spec.v + [spec.time] + d.inputs
    point_outputs: list[tuple[str, sp.Expr]] = []
    for point, position, velocity in zip(spec.points, d.positions, d.velocities):
        for axis, expr in zip("xyz", position):
            if axis in point.outputs:
                point_outputs.append((point.outputs[axis], expr))
        for axis, expr in zip("xyz", velocity):
            if f"v_{axis}" in point.outputs:
                point_outputs.append((point.outputs[f"v_{axis}"], expr))
    outputs = point_outputs + [("E_kin", d.T), ("E_pot", d.U), ("E", d.T + d.U)]
    return dict(
        spec=spec, n=d.n, parameters=[str(p) for p in parameters], inputs=[str(i) for i in d.inputs],
        dynamics=sp.lambdify(arguments, list(d.M) + list(d.f + d.Q), "numpy", cse=True),
        output_names=[name for name, _ in outputs],
        outputs=sp.lambdify(arguments, [expr for _, expr in outputs], "numpy", cse=True))


@dataclass
class _Kind:
    """The instances of one object kind: arrays over the instances (rows)."""
    functions: dict
    names: list[str] = field(default_factory=list)
    parameters: list[list[float]] = field(default_factory=list)
    damping: list[float] = field(default_factory=list)
    inputs: list[list[float]] = field(default_factory=list)  # start values, overwritten where fed
    offsets: list[int] = field(default_factory=list)  # where each instance's q, v start in the state

    def freeze(self) -> None:
        n = self.functions["n"]
        self.P = np.array(self.parameters, dtype=float).reshape(len(self.names), -1)
        self.D = np.array(self.damping, dtype=float)
        self.U = np.array(self.inputs, dtype=float).reshape(len(self.names), -1)
        self.q_index = np.array(self.offsets)[:, None] + np.arange(n)[None, :]
        self.v_index = self.q_index + n

    def arguments(self, y: np.ndarray, t: float, inputs: np.ndarray) -> list:
        return [*self.P.T, *y[self.q_index].T, *y[self.v_index].T, t, *inputs.T]

    def outputs(self, y: np.ndarray, t: float, inputs: np.ndarray) -> np.ndarray:
        """(outputs, instances) for the states y."""
        values = self.functions["outputs"](*self.arguments(y, t, inputs))
        return np.array([np.broadcast_to(np.asarray(v, dtype=float), (len(self.names),)) for v in values])

    def accelerations(self, y: np.ndarray, t: float, inputs: np.ndarray) -> np.ndarray:
        n, rows = self.functions["n"], len(self.names)
        entries = self.functions["dynamics"](*self.arguments(y, t, inputs))
        values = np.array([np.broadcast_to(np.asarray(e, dtype=float), (rows,)) for e in entries])
        M = values[:n * n].T.reshape(rows, n, n)
        rhs = values[n * n:].T
        a = rhs / M[:, 0, 0:1] if n == 1 else np.linalg.solve(M, rhs[:, :, None])[:, :, 0]
        return a - self.D[:, None] * y[self.v_index]


class MonolithicScene:
    """A scene of objects joined by Springs and Contacts as one system of equations (see the module's
    text). `from_system` refuses, by name, any component or connection it cannot take in."""

    def __init__(self, system: System):
        self.system = system
        self.kinds: dict[str, _Kind] = {}
        self.elements: dict[str, _Elements] = {}  # by law
        self.where: dict[str, tuple[str, int]] = {}  # component -> (kind or element law, row)
        self.events: list[tuple[float, str, str]] = []  # (time, contact, "onset" or "end") of the last solve
        start = []
        offset = 0
        facts = _FmuFacts(system)
        for component in system.components:
            description, law, object_file = facts(component)
            values = float_start_values(description, component.start)
            if law is not None:
                elements = self.elements.setdefault(law.identifier, _Elements(law))
                self.where[component.name] = (law.identifier, len(elements.names))
                elements.names.append(component.name)
                elements.parameters.append([values[p] for p in law.parameters])
                elements.inputs.append([values.get(i, 0.0) for i in law.inputs])
                continue
            functions = _kind_functions(*object_file)
            if functions["spec"].constraints:
                raise HarnessError(f"{system.name}: {component.name} ({component.fmu.name}) has constraints of its own "
                                   f"({', '.join(c.name for c in functions['spec'].constraints)}): the monolithic "
                                   "reference joins free objects (Lagrange's equations of the second kind) only")
            model = component.start.get("model", "nonlinear")
            if model not in ("nonlinear", 1, 1.0):
                raise HarnessError(f"{system.name}: {component.name}.model = {model!r}: the monolithic reference "
                                   "is the nonlinear model")
            kind = self.kinds.setdefault(functions["spec"].identifier, _Kind(functions))
            self.where[component.name] = (functions["spec"].identifier, len(kind.names))
            kind.names.append(component.name)
            kind.parameters.append([values[p] for p in functions["parameters"]])
            kind.damping.append(values.get("d", 0.0))
            kind.inputs.append([values.get(i, 0.0) for i in functions["inputs"]])
            kind.offsets.append(offset)
            spec = functions["spec"]
            start += [values[c.name] for c in spec.coordinates] + [values[c.velocity] for c in spec.coordinates]
            offset += 2 * functions["n"]
        for kind in self.kinds.values():
            kind.freeze()
        for elements in self.elements.values():
            elements.freeze()
        self.start = np.array(start, dtype=float)
        contacts = self.elements.get("Contact")
        self.contacts = list(contacts.names) if contacts else []
        self._route()
        self.evaluations = 0

    def _route(self) -> None:
        """Index arrays: object outputs into element inputs, element forces into object inputs."""
        kinds = list(self.kinds)
        # every object output is one entry of a flat signal vector: kind by kind, output by output, row by row
        self.signal_start, at = {}, 0
        for name in kinds:
            kind = self.kinds[name]
            self.signal_start[name] = at
            at += len(kind.functions["output_names"]) * len(kind.names)
        # every element force is one entry of a flat force vector: law by law, row by row, component by component
        self.force_start, at = {}, 0
        for law, elements in self.elements.items():
            self.force_start[law] = at
            at += elements.law.forces * len(elements.names)
        into_elements: dict[str, list[tuple[int, int]]] = {law: [] for law in self.elements}  # (signal, flat input)
        into_objects: dict[str, list[tuple[int, int]]] = {name: [] for name in kinds}  # (flat force, flat input)
        refuse = f"{self.system.name}: the monolithic reference joins objects through Springs and Contacts only"
        for c in self.system.connections:
            (source_kind, source_row), (target_kind, target_row) = self.where[c.source], self.where[c.target]
            if source_kind not in self.elements and target_kind in self.elements:
                kind, law = self.kinds[source_kind], self.elements[target_kind].law
                names = kind.functions["output_names"]
                if c.output not in names or c.input not in law.inputs:
                    raise HarnessError(f"{refuse}: connection {c} does not lead a position or velocity into a "
                                       f"{law.identifier}")
                signal = self.signal_start[source_kind] + names.index(c.output) * len(kind.names) + source_row
                into_elements[target_kind].append((signal, target_row * len(law.inputs) + law.inputs.index(c.input)))
            elif source_kind in self.elements and target_kind not in self.elements:
                kind, law = self.kinds[target_kind], self.elements[source_kind].law
                if c.output not in law.outputs[:law.forces] or c.input not in kind.functions["inputs"]:
                    raise HarnessError(f"{refuse}: connection {c} does not lead a {law.identifier}'s force into a "
                                       "force input")
                into_objects[target_kind].append((self.force_start[source_kind] + source_row * law.forces
                                                  + law.outputs.index(c.output),
                                                  target_row * len(kind.functions["inputs"])
                                                  + kind.functions["inputs"].index(c.input)))
            else:
                what = "two elements" if source_kind in self.elements else "two objects"
                raise HarnessError(f"{refuse}: connection {c} joins {what} directly")
        self.element_from = {k: np.array([s for s, _ in v], dtype=int) for k, v in into_elements.items()}
        self.element_to = {k: np.array([d for _, d in v], dtype=int) for k, v in into_elements.items()}
        self.object_from = {k: np.array([s for s, _ in v], dtype=int) for k, v in into_objects.items()}
        self.object_to = {k: np.array([d for _, d in v], dtype=int) for k, v in into_objects.items()}

    # ---- the equations
    def _evaluate(self, y: np.ndarray, t: float):
        """For states y: each kind's outputs (outputs, instances), each element law's outputs (instances,
        outputs), and each kind's inputs (instances, inputs) with the forces routed in."""
        outputs = {name: kind.outputs(y, t, kind.U) for name, kind in self.kinds.items()}
        signal = np.concatenate([o.reshape(-1) for o in outputs.values()]) if outputs else np.zeros(0)
        element_outputs, forces = {}, []
        for law, elements in self.elements.items():
            element_in = elements.U.reshape(-1).copy()
            element_in[self.element_to[law]] = signal[self.element_from[law]]
            values = elements.law.law(elements.P, element_in.reshape(elements.U.shape), self.system.name)
            element_outputs[law] = values
            forces.append(values[:, :elements.law.forces].reshape(-1))
        flat_forces = np.concatenate(forces) if forces else np.zeros(0)
        inputs = {}
        for name, kind in self.kinds.items():
            u = kind.U.reshape(-1).copy()
            u[self.object_to[name]] = flat_forces[self.object_from[name]]
            inputs[name] = u.reshape(kind.U.shape)
        return outputs, element_outputs, inputs

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        self.evaluations += 1
        if self.evaluations > REFERENCE_BUDGET:
            raise _OverBudget
        _, _, inputs = self._evaluate(y, t)
        dy = np.empty_like(y)
        for name, kind in self.kinds.items():
            dy[kind.q_index] = y[kind.v_index]
            dy[kind.v_index] = kind.accelerations(y, t, inputs[name])
        return dy

    def gaps(self, t: float, y: np.ndarray) -> np.ndarray:
        """The Contacts' gaps at (t, y), in the order of `contacts`."""
        if not self.contacts:
            return np.zeros(0)
        law = self.elements["Contact"].law
        return self._evaluate(y, t)[1]["Contact"][:, law.outputs.index("gap")]

    def eigenvalues(self, t: float = 0.0) -> np.ndarray:
        """Eigenvalues [1/s] of the scene's equations linearized at its start (central differences)."""
        y0 = self.start
        columns = []
        for j in range(len(y0)):
            step = 1e-6 * max(1.0, abs(y0[j]))
            up, down = y0.copy(), y0.copy()
            up[j] += step
            down[j] -= step
            columns.append((self.rhs(t, up) - self.rhs(t, down)) / (2 * step))
        return np.linalg.eigvals(np.column_stack(columns)) if columns else np.zeros(0)

    # ---- the solution
    def _integrate(self, times: np.ndarray) -> np.ndarray:
        """The states at `times`: DOP853 from event to event, each Contact's onset and end located as the
        zero of its gap (only the crossing the contact waits for counts, so a restart on a zero is not
        taken for the next event)."""
        from scipy.integrate import solve_ivp
        states = np.zeros((len(times), len(self.start)))
        t, y = times[0], self.start.copy()
        touching = list(self.gaps(t, y) + CONTACT_ROUNDING < 0)

        def gap_event(i: int):
            def event(s: float, state: np.ndarray) -> float:
                # bodies that merely touch (a cradle at rest: a gap of 0 to the last bit) are apart, as in the FMUs
                return self.gaps(s, state)[i] + CONTACT_ROUNDING
            event.direction = 1.0 if touching[i] else -1.0
            event.terminal = True
            return event

        filled = 0
        while True:
            events = [gap_event(i) for i in range(len(self.contacts))]
            solution = solve_ivp(self.rhs, (t, times[-1]), y, method="DOP853", rtol=1e-12, atol=1e-12,
                                 t_eval=times[filled:], events=events or None)
            reached = np.asarray(solution.y, dtype=float).reshape(len(y), -1)  # a list where no grid point was reached
            if not solution.success or not np.all(np.isfinite(reached)):
                raise HarnessError(f"{self.system.name}: the monolithic reference could not be computed "
                                   f"({solution.message}); the coupling is stiff or the motion blows up")
            states[filled:filled + reached.shape[1]] = reached.T
            filled += reached.shape[1]
            if solution.status != 1:  # the end: no event stopped it
                break
            i = next(k for k, found in enumerate(solution.t_events) if len(found))
            t, y = float(solution.t_events[i][0]), solution.y_events[i][0]
            self.events.append((t, self.contacts[i], "end" if touching[i] else "onset"))
            touching[i] = not touching[i]
            if len(self.events) > MAX_EVENTS:
                raise HarnessError(f"{self.system.name}: the monolithic reference met more than {MAX_EVENTS} contact "
                                   "onsets and ends (bodies that keep touching and parting)")
            while filled < len(times) and times[filled] <= t:  # a grid point on the event itself
                states[filled] = y
                filled += 1
            if filled == len(times):
                break
        if filled != len(times):
            raise HarnessError(f"{self.system.name}: the monolithic reference stopped short of {times[-1]:g} s")
        return states

    def solve(self, times: np.ndarray) -> dict[str, np.ndarray]:
        """Every state and Real output the reference determines, as `<component>.<variable>`
        columns at `times` (the elements' outputs included); `events` then lists the contacts' onsets and ends."""
        times = np.asarray(times, dtype=float)
        self.evaluations = 0
        self.events = []
        states = np.zeros((len(times), len(self.start)))
        if len(self.start) and len(times):
            try:
                # a trial step deep into a contact can overflow the force; the step control rejects it (NaN
                # error), and the solution is checked for finite values at the end
                with np.errstate(over="ignore", invalid="ignore"):
                    states = self._integrate(times)
            except _OverBudget:
                raise HarnessError(f"{self.system.name}: the monolithic reference needs more than "
                                   f"{REFERENCE_BUDGET:.0e} evaluations at rtol 1e-12 (the coupling is stiff, or the "
                                   "motion blows up)") from None
        columns: dict[str, np.ndarray] = {"time": times}
        for name, kind in self.kinds.items():
            spec = kind.functions["spec"]
            for row, component in enumerate(kind.names):
                for j, c in enumerate(spec.coordinates):
                    columns[f"{component}.{c.name}"] = states[:, kind.q_index[row, j]]
                    columns[f"{component}.{c.velocity}"] = states[:, kind.v_index[row, j]]
                for output in kind.functions["output_names"]:
                    columns[f"{component}.{output}"] = np.empty(len(times))
        for elements in self.elements.values():
            for component in elements.names:
                for output in elements.law.outputs:
                    columns[f"{component}.{output}"] = np.empty(len(times))
        outputs, element_outputs = self._evaluate_rows(states, times)
        for name, kind in self.kinds.items():
            for j, output in enumerate(kind.functions["output_names"]):
                for row, component in enumerate(kind.names):
                    columns[f"{component}.{output}"] = outputs[name][j, :, row]
        for law, elements in self.elements.items():
            for row, component in enumerate(elements.names):
                for j, output in enumerate(elements.law.outputs):
                    columns[f"{component}.{output}"] = element_outputs[law][:, row, j]
        return columns

    def _evaluate_rows(self, states: np.ndarray, times: np.ndarray):
        """`_evaluate`'s outputs at every row of `states` (rows, states) at once: each kind's (outputs, rows,
        instances) and each element law's (rows, instances, outputs). The rows become instances of the same
        equations, so a grid of 30,000 points costs a few array evaluations, not 30,000 calls."""
        rows = len(times)
        signals, outputs = [], {}
        for name, kind in self.kinds.items():
            count = len(kind.names)
            q = states[:, kind.q_index].reshape(rows * count, -1)
            v = states[:, kind.v_index].reshape(rows * count, -1)
            values = kind.functions["outputs"](*np.tile(kind.P, (rows, 1)).T, *q.T, *v.T, np.repeat(times, count),
                                               *np.tile(kind.U, (rows, 1)).T)
            table = np.array([np.broadcast_to(np.asarray(value, dtype=float), (rows * count,)) for value in values])
            outputs[name] = table.reshape(len(values), rows, count)
            signals.append(outputs[name].transpose(1, 0, 2).reshape(rows, -1))
        signal = np.concatenate(signals, axis=1) if signals else np.zeros((rows, 0))
        element_outputs = {}
        for law, elements in self.elements.items():
            count = len(elements.names)
            element_in = np.tile(elements.U.reshape(-1), (rows, 1))
            element_in[:, self.element_to[law]] = signal[:, self.element_from[law]]
            values = elements.law.law(np.tile(elements.P, (rows, 1)), element_in.reshape(rows * count, -1),
                                      self.system.name)
            element_outputs[law] = values.reshape(rows, count, -1)
        return outputs, element_outputs

    def point_columns(self, x: str = "x", y: str = "y") -> list[tuple[str, str]]:
        """(x, y) column pairs of every object point with position outputs: what the coupling error
        is measured on; ("v_x", "v_y") gives its velocities' pairs."""
        pairs = []
        for kind in self.kinds.values():
            for component in kind.names:
                for point in kind.functions["spec"].points:
                    if x in point.outputs and y in point.outputs:
                        pairs.append((f"{component}.{point.outputs[x]}", f"{component}.{point.outputs[y]}"))
        return pairs


def _carried_object_file(component, system: System) -> tuple[str, str]:
    """The text of the object file the component's FMU carries, and where it is."""
    import zipfile

    from harness.objects.proof import object_file_in
    spec = object_file_in(component.fmu)
    if spec is None:
        raise HarnessError(f"{system.name}: {component.name} ({component.fmu.name}) is neither an element (Spring, "
                           "Contact) nor made from an object file: the monolithic reference needs every object's "
                           "energies")
    with zipfile.ZipFile(component.fmu) as archive:
        member = next(n for n in archive.namelist() if n.startswith("sources/") and n.endswith(".toml"))
        return archive.read(member).decode("utf-8", errors="replace"), f"{component.fmu.name}:{member}"


def largest_point_error(result, reference: dict[str, np.ndarray], pairs: list[tuple[str, str]]) -> float:
    """The largest distance of any object point in `result` (a TimeTable) from the reference."""
    return float(max((np.max(np.hypot(result[x] - reference[x], result[y] - reference[y])) for x, y in pairs),
                     default=0.0))
