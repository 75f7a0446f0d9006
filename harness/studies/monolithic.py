"""The monolithic reference of any scene of objects joined by Springs: one system of equations,
integrated as a whole, against which the co-simulation's coupling error is measured.

Every object comes from the object file its FMU carries, through Lagrange's equations
(`harness.objects.derivation`, lambdified, never the generated C):

    M(q, t) a = f(q, v, t) + B(q, t) F - M d v,

with F its force inputs. A Spring is a massless element, coded here from its contract
(SPEC 4): with e = (b - a) / |b - a|, Fa = (k (|b - a| - l0) + c (b_v - a_v) . e) e and Fb = -Fa,
for l0 = 0 simply k (b - a) + c ((b_v - a_v) . e) e. Adding the springs' potential
k/2 (r - l0)^2 and their Rayleigh damping c/2 ((b_v - a_v) . e)^2 to the objects' Lagrangians gives
exactly these forces at the points the springs join, so the scene's connections (positions and
velocities into the springs, forces back) are one system of equations with no delay: the springs'
outputs are evaluated from the objects' outputs at the same instant, then the objects'
accelerations from those forces. An input no connection feeds keeps its start value.

Objects of one kind are evaluated together (numpy arrays over the instances), so a chain of a
thousand pendulums costs one evaluation per kind, not a thousand. DOP853 at rtol = atol = 1e-12
integrates it.

This reference measures the coupling (and the methods' error), not the objects' equations: those
are proven against an independent numeric route by `harness validate`.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sympy as sp

from harness.cosim.structure import System
from harness.errors import HarnessError
from harness.fmi.fmu_instance import float_start_values

REFERENCE_BUDGET = 2_000_000  # right-hand-side evaluations of one monolithic reference
SPRING = "Spring"
SPRING_INPUTS = ("a_x", "a_y", "a_vx", "a_vy", "b_x", "b_y", "b_vx", "b_vy")
SPRING_OUTPUTS = ("Fa_x", "Fa_y", "Fb_x", "Fb_y", "E_pot")
SPRING_PARAMETERS = ("k", "c", "l0")


class _OverBudget(Exception):
    pass


class _FmuFacts:
    """What the reference reads from each FMU file, once per file however many components use it: its
    description, whether it is a Spring, and the object file it carries."""

    def __init__(self, system: System):
        self.system = system
        self._read: dict[Path, tuple] = {}

    def __call__(self, component) -> tuple[object, bool, tuple[str, str] | None]:
        from harness.fmi.fmu_instance import read_description
        path = Path(component.fmu)
        if path not in self._read:
            description = read_description(path)
            interface = description.coSimulation or description.modelExchange
            spring = interface.modelIdentifier == SPRING and {v.name for v in description.modelVariables} >= \
                set(SPRING_INPUTS + SPRING_OUTPUTS + SPRING_PARAMETERS)
            self._read[path] = (description, spring, None if spring else _carried_object_file(component, self.system))
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
    """A scene of objects joined by Springs as one system of equations (see the module's text).
    `from_system` refuses, by name, any component or connection it cannot take in."""

    def __init__(self, system: System):
        self.system = system
        self.kinds: dict[str, _Kind] = {}
        self.where: dict[str, tuple[str, int]] = {}  # component -> (kind or SPRING, row)
        self.springs: list[str] = []
        self.fmi_versions: dict[str, str] = {}  # component -> its FMU's FMI version
        spring_values, start = [], []
        offset = 0
        facts = _FmuFacts(system)
        for component in system.components:
            description, spring, object_file = facts(component)
            self.fmi_versions[component.name] = description.fmiVersion
            values = float_start_values(description, component.start)
            if spring:
                self.where[component.name] = (SPRING, len(self.springs))
                self.springs.append(component.name)
                spring_values.append(values)
                continue
            functions = _kind_functions(*object_file)
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
        self.start = np.array(start, dtype=float)
        self.spring_parameters = np.array([[v[p] for p in SPRING_PARAMETERS] for v in spring_values]).reshape(-1, 3)
        self.spring_inputs = np.array([[v.get(i, 0.0) for i in SPRING_INPUTS] for v in spring_values]).reshape(-1, 8)
        self._route()
        self.evaluations = 0

    def _route(self) -> None:
        """Index arrays: object outputs into spring inputs, spring forces into object inputs."""
        kinds = list(self.kinds)
        # every object output is one entry of a flat signal vector: kind by kind, output by output, row by row
        self.signal_start, at = {}, 0
        for name in kinds:
            kind = self.kinds[name]
            self.signal_start[name] = at
            at += len(kind.functions["output_names"]) * len(kind.names)
        into_springs: list[tuple[int, int]] = []  # (signal, flat spring input)
        into_objects: dict[str, list[tuple[int, int]]] = {name: [] for name in kinds}  # (flat force, flat input)
        refuse = f"{self.system.name}: the monolithic reference joins objects through Springs only"
        for c in self.system.connections:
            (source_kind, source_row), (target_kind, target_row) = self.where[c.source], self.where[c.target]
            if source_kind != SPRING and target_kind == SPRING:
                kind = self.kinds[source_kind]
                names = kind.functions["output_names"]
                if c.output not in names or c.input not in SPRING_INPUTS[:8]:
                    raise HarnessError(f"{refuse}: connection {c} does not lead a position or velocity into a Spring")
                signal = self.signal_start[source_kind] + names.index(c.output) * len(kind.names) + source_row
                into_springs.append((signal, target_row * 8 + SPRING_INPUTS.index(c.input)))
            elif source_kind == SPRING and target_kind != SPRING:
                kind = self.kinds[target_kind]
                if c.output not in SPRING_OUTPUTS[:4] or c.input not in kind.functions["inputs"]:
                    raise HarnessError(f"{refuse}: connection {c} does not lead a Spring's force into a force input")
                into_objects[target_kind].append((source_row * 4 + SPRING_OUTPUTS.index(c.output),
                                                  target_row * len(kind.functions["inputs"])
                                                  + kind.functions["inputs"].index(c.input)))
            else:
                what = "two Springs" if source_kind == SPRING else "two objects"
                raise HarnessError(f"{refuse}: connection {c} joins {what} directly")
        self.spring_from = np.array([s for s, _ in into_springs], dtype=int)
        self.spring_to = np.array([d for _, d in into_springs], dtype=int)
        self.object_from = {k: np.array([s for s, _ in v], dtype=int) for k, v in into_objects.items()}
        self.object_to = {k: np.array([d for _, d in v], dtype=int) for k, v in into_objects.items()}

    # ---- the equations
    def _spring_forces(self, inputs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Forces (springs, 4: Fa_x Fa_y Fb_x Fb_y) and potentials for inputs (springs, 8)."""
        k, c, l0 = self.spring_parameters.T
        d = inputs[:, 4:6] - inputs[:, 0:2]
        dv = inputs[:, 6:8] - inputs[:, 2:4]
        r = np.hypot(d[:, 0], d[:, 1])
        if np.any((r == 0) & (l0 > 0)):
            raise HarnessError(f"{self.system.name}: a Spring of rest length > 0 has both ends at one point: "
                               "its direction is undefined")
        e = d / np.where(r > 0, r, 1.0)[:, None]  # 0 where r = 0 (then l0 = 0: the force is k d)
        rate = np.sum(dv * e, axis=1)
        force_a = np.where((l0 == 0)[:, None], k[:, None] * d + (c * rate)[:, None] * e,
                           (k * (r - l0) + c * rate)[:, None] * e)
        return np.concatenate([force_a, -force_a], axis=1), k / 2 * (r - l0) ** 2

    def _evaluate(self, y: np.ndarray, t: float):
        """For states y: each kind's outputs (outputs, instances), the springs' forces and potentials,
        and each kind's inputs (instances, inputs) with the forces routed in."""
        outputs = {name: kind.outputs(y, t, kind.U) for name, kind in self.kinds.items()}
        signal = np.concatenate([o.reshape(-1) for o in outputs.values()]) if outputs else np.zeros(0)
        spring_in = self.spring_inputs.reshape(-1).copy()
        spring_in[self.spring_to] = signal[self.spring_from]
        forces, potentials = self._spring_forces(spring_in.reshape(-1, 8))
        flat_forces = forces.reshape(-1)
        inputs = {}
        for name, kind in self.kinds.items():
            u = kind.U.reshape(-1).copy()
            u[self.object_to[name]] = flat_forces[self.object_from[name]]
            inputs[name] = u.reshape(kind.U.shape)
        return outputs, forces, potentials, inputs

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        self.evaluations += 1
        if self.evaluations > REFERENCE_BUDGET:
            raise _OverBudget
        _, _, _, inputs = self._evaluate(y, t)
        dy = np.empty_like(y)
        for name, kind in self.kinds.items():
            dy[kind.q_index] = y[kind.v_index]
            dy[kind.v_index] = kind.accelerations(y, t, inputs[name])
        return dy

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
    def solve(self, times: np.ndarray) -> dict[str, np.ndarray]:
        """Every state and Real output the reference determines, as `<component>.<variable>`
        columns at `times` (the Springs' forces and potential included)."""
        from scipy.integrate import solve_ivp
        times = np.asarray(times, dtype=float)
        self.evaluations = 0
        states = np.zeros((len(times), len(self.start)))
        if len(self.start) and len(times):
            try:
                solution = solve_ivp(self.rhs, (times[0], times[-1]), self.start, method="DOP853", rtol=1e-12,
                                     atol=1e-12, t_eval=times)
            except _OverBudget:
                raise HarnessError(f"{self.system.name}: the monolithic reference needs more than "
                                   f"{REFERENCE_BUDGET:.0e} evaluations at rtol 1e-12 (the coupling is stiff, or the "
                                   "motion blows up)") from None
            if not solution.success or solution.y.shape[1] != len(times) or not np.all(np.isfinite(solution.y)):
                raise HarnessError(f"{self.system.name}: the monolithic reference could not be computed "
                                   f"({solution.message}); the coupling is stiff or the motion blows up")
            states = solution.y.T
        columns: dict[str, np.ndarray] = {"time": times}
        for name, kind in self.kinds.items():
            spec = kind.functions["spec"]
            for row, component in enumerate(kind.names):
                for j, c in enumerate(spec.coordinates):
                    columns[f"{component}.{c.name}"] = states[:, kind.q_index[row, j]]
                    columns[f"{component}.{c.velocity}"] = states[:, kind.v_index[row, j]]
                for output in kind.functions["output_names"]:
                    columns[f"{component}.{output}"] = np.empty(len(times))
        for component in self.springs:
            for output in SPRING_OUTPUTS:
                columns[f"{component}.{output}"] = np.empty(len(times))
        for i, (t, y) in enumerate(zip(times, states)):
            outputs, forces, potentials, _ = self._evaluate(y, t)
            for name, kind in self.kinds.items():
                for j, output in enumerate(kind.functions["output_names"]):
                    for row, component in enumerate(kind.names):
                        columns[f"{component}.{output}"][i] = outputs[name][j, row]
            for row, component in enumerate(self.springs):
                for j, output in enumerate(SPRING_OUTPUTS[:4]):
                    columns[f"{component}.{output}"][i] = forces[row, j]
                columns[f"{component}.E_pot"][i] = potentials[row]
        return columns

    def point_columns(self) -> list[tuple[str, str]]:
        """(x, y) column pairs of every object point with position outputs: what the coupling error
        is measured on."""
        pairs = []
        for kind in self.kinds.values():
            for component in kind.names:
                for point in kind.functions["spec"].points:
                    if "x" in point.outputs and "y" in point.outputs:
                        pairs.append((f"{component}.{point.outputs['x']}", f"{component}.{point.outputs['y']}"))
        return pairs


def _carried_object_file(component, system: System) -> tuple[str, str]:
    """The text of the object file the component's FMU carries, and where it is."""
    import zipfile

    from harness.objects.proof import object_file_in
    spec = object_file_in(component.fmu)
    if spec is None:
        raise HarnessError(f"{system.name}: {component.name} ({component.fmu.name}) is neither a Spring nor made from "
                           "an object file: the monolithic reference needs every object's energies")
    with zipfile.ZipFile(component.fmu) as archive:
        member = next(n for n in archive.namelist() if n.startswith("sources/") and n.endswith(".toml"))
        return archive.read(member).decode("utf-8", errors="replace"), f"{component.fmu.name}:{member}"


def largest_point_error(result, reference: dict[str, np.ndarray], pairs: list[tuple[str, str]]) -> float:
    """The largest distance of any object point in `result` (a TimeTable) from the reference."""
    return float(max((np.max(np.hypot(result[x] - reference[x], result[y] - reference[y])) for x, y in pairs),
                     default=0.0))
