"""Coupling error: what each master configuration costs and how accurate it is on a system of two
simple pendulums whose bobs are joined by a Spring (the coupled-pendulums scene).

The reference is monolithic: both pendulums' and the spring's equations in one right-hand side,
coded here independently of the FMUs, integrated by scipy's DOP853 at rtol = atol = 1e-12, with the
parameters and start values the system gives its components. `error` is the largest Euclidean
distance of either bob from the reference over the communication points; cost is right-hand-side
evaluations summed over the components (rolled-back passes included), fmi2DoStep calls, and
seconds of the master's run (median of repeats; loading and instantiating not included).
"""
from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.cosim.master import Master, MasterOptions
from harness.cosim.structure import System
from harness.errors import HarnessError
from harness.fmi.simulation import communication_grid
from harness.studies.records import columns_of, read_records, write_records
from harness.studies.sweep import run_sweep

REFERENCE_BUDGET = 2_000_000  # right-hand-side evaluations of one monolithic reference


class _OverBudget(Exception):
    pass


CONFIGURATIONS = (("jacobi", "hold", None), ("jacobi", "linear", None), ("gauss-seidel", "hold", None),
                  ("gauss-seidel", "linear", None), ("jacobi", "linear", 1e-10), ("gauss-seidel", "linear", 1e-10))
STEPS = (0.04, 0.02, 0.01, 0.005, 0.0025)


@dataclass
class CouplingPoint:
    algorithm: str
    extrapolation: str
    iterate: float  # iteration tolerance; NaN for a single pass
    step: float
    error: float  # metres; inf when the run stopped early
    rhs_evals: int
    do_steps: int
    seconds: float

    @property
    def configuration(self) -> str:
        return f"{self.algorithm}, {self.extrapolation}" + ("" if math.isnan(self.iterate) else ", iterated")


@dataclass(frozen=True)
class CoupledPendulums:
    """The physical system behind a two-pendulum, one-spring System."""
    left: dict
    right: dict
    spring: dict
    names: tuple[str, str]

    @classmethod
    def from_system(cls, system: System) -> "CoupledPendulums":
        """The physics of `system`, which must be exactly this scene: two of the project's
        SimplePendulums, nonlinear, and one Spring whose ends read each bob's position and velocity
        and whose forces act on those bobs. Anything else has another reference (HarnessError)."""
        from harness.fmi.calls import is_float
        from harness.fmi.fmu_instance import read_description

        def values(component) -> tuple[str, dict]:
            description = read_description(component.fmu)
            merged = {v.name: float(v.start) for v in description.modelVariables
                      if is_float(v) and v.start is not None}
            merged.update({k: v for k, v in component.start.items() if not isinstance(v, str)})
            return description.coSimulation.modelIdentifier, merged
        needs = f"{system.name}: the coupling reference knows one scene only: two SimplePendulums whose bobs are " \
                f"joined by one Spring, forces fed back"
        kinds = {c.name: values(c) for c in system.components}
        pendulums = [name for name, (kind, _) in kinds.items() if kind == "SimplePendulum"]
        springs = [name for name, (kind, _) in kinds.items() if kind == "Spring"]
        if len(pendulums) != 2 or len(springs) != 1 or len(kinds) != 3:
            raise HarnessError(f"{needs}; this one has {', '.join(sorted(k for k, _ in kinds.values()))}")
        spring = springs[0]
        ends = {c.input[0]: c.source for c in system.connections if c.target == spring and c.input == f"{c.input[0]}_x"}
        if set(ends) != {"a", "b"} or set(ends.values()) != set(pendulums):
            raise HarnessError(f"{needs}; the Spring's ends a and b must read the two pendulums")
        expected = set()
        for end, pendulum in ends.items():
            expected |= {(pendulum, output, spring, f"{end}_{suffix}")
                         for output, suffix in (("x", "x"), ("y", "y"), ("v_x", "vx"), ("v_y", "vy"))}
            expected |= {(spring, f"F{end}_{axis}", pendulum, f"F_{axis}") for axis in "xy"}
        actual = {(c.source, c.output, c.target, c.input) for c in system.connections}
        if actual != expected:
            wrong = sorted(" -> ".join((f"{a}.{b}", f"{c}.{d}")) for a, b, c, d in actual ^ expected)
            raise HarnessError(f"{needs}; missing or extra: {', '.join(wrong[:4])}")
        _check_project_pendulums(system, pendulums, needs)
        newer = [c.name for c in system.components if read_description(c.fmu).fmiVersion != "2.0"]
        if newer:
            raise HarnessError(f"{system.name}: the coupling studies compare linear extrapolation and iterated steps, "
                               f"which hand inputs over with their derivatives; {', '.join(newer)} "
                               f"{'is an FMI 3.0 FMU' if len(newer) == 1 else 'are FMI 3.0 FMUs'}, which take none: "
                               "use the FMI 2.0 FMUs")
        p = {name: kinds[name][1] for name in pendulums}
        return cls(p[ends["a"]], p[ends["b"]], kinds[spring][1], (ends["a"], ends["b"]))

    def _bobs(self, y):
        a, b = self.left, self.right
        pa = np.array([a["anchor_x"] + a["L"] * np.sin(y[0]), a["anchor_y"] - a["L"] * np.cos(y[0])])
        pb = np.array([b["anchor_x"] + b["L"] * np.sin(y[2]), b["anchor_y"] - b["L"] * np.cos(y[2])])
        va = a["L"] * y[1] * np.array([np.cos(y[0]), np.sin(y[0])])
        vb = b["L"] * y[3] * np.array([np.cos(y[2]), np.sin(y[2])])
        return pa, pb, va, vb

    def rhs(self, t, y):
        a, b, s = self.left, self.right, self.spring
        pa, pb, va, vb = self._bobs(y)
        d = pb - pa
        r = math.hypot(*d)
        e = d / r
        force_on_a = (s["k"] * (r - s["l0"]) + s["c"] * float((vb - va) @ e)) * e
        # tangential component of the force, divided by m L: the angular acceleration it adds
        torque_a = (force_on_a[0] * math.cos(y[0]) + force_on_a[1] * math.sin(y[0])) / (a["m"] * a["L"])
        torque_b = -(force_on_a[0] * math.cos(y[2]) + force_on_a[1] * math.sin(y[2])) / (b["m"] * b["L"])
        return [y[1], -a["g"] / a["L"] * math.sin(y[0]) - a["d"] * y[1] + torque_a,
                y[3], -b["g"] / b["L"] * math.sin(y[2]) - b["d"] * y[3] + torque_b]

    def reference(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions (n, 2) of the bob at end a and at end b."""
        from scipy.integrate import solve_ivp
        start = [self.left["phi"], self.left["omega"], self.right["phi"], self.right["omega"]]
        evaluations = 0

        def counted(t, y):  # a stiff or exploding scene would keep DOP853 at rtol 1e-12 busy for hours
            nonlocal evaluations
            evaluations += 1
            if evaluations > REFERENCE_BUDGET:
                raise _OverBudget
            return self.rhs(t, y)
        try:
            solution = solve_ivp(counted, (times[0], times[-1]), start, method="DOP853", rtol=1e-12, atol=1e-12,
                                 t_eval=times)
        except _OverBudget:
            raise HarnessError(f"the monolithic reference of this scene needs more than {REFERENCE_BUDGET:.0e} "
                               "evaluations at rtol 1e-12 (the coupling is stiff, or the motion blows up)") from None
        if not solution.success or solution.y.shape[1] != len(times) or not np.all(np.isfinite(solution.y)):
            raise HarnessError(f"the monolithic reference of this scene could not be computed ({solution.message}); "
                               "the coupling is stiff or the motion blows up")
        bobs = [self._bobs(y) for y in solution.y.T]
        return np.array([b[0] for b in bobs]), np.array([b[1] for b in bobs])


def _check_project_pendulums(system: System, names: list[str], needs: str) -> None:
    """Each pendulum runs the nonlinear equations of the project's SimplePendulum object file."""
    from harness.objects.proof import object_file_in
    from harness.objects.registry import object_file
    from harness.objects.object_file import read_object_file
    project = read_object_file(object_file("SimplePendulum"))
    for component in system.components:
        if component.name not in names:
            continue
        model = component.start.get("model", "nonlinear")
        if model not in ("nonlinear", 1):
            raise HarnessError(f"{needs}; {component.name}.model = {model!r}: the reference is the nonlinear pendulum")
        carried = object_file_in(component.fmu)
        if carried is None or (carried.T, carried.U) != (project.T, project.U) or \
                [(p.position, p.outputs) for p in carried.points] != [(p.position, p.outputs) for p in project.points]:
            raise HarnessError(f"{needs}; {component.name}: {Path(component.fmu).name} does not carry the project's "
                               f"SimplePendulum energies and points (with their output names)")


def coupling_error(result, physics: CoupledPendulums) -> float:
    if result.stopped_at is not None:
        return math.inf
    a, b = physics.names
    ref_a, ref_b = physics.reference(result.time)
    return float(max(np.max(np.hypot(result[f"{a}.x"] - ref_a[:, 0], result[f"{a}.y"] - ref_a[:, 1])),
                     np.max(np.hypot(result[f"{b}.x"] - ref_b[:, 0], result[f"{b}.y"] - ref_b[:, 1]))))


def measure(job: tuple[System, tuple, float, float, int]) -> CouplingPoint:
    """One configuration at one communication step (runs in a worker)."""
    system, (algorithm, extrapolation, iterate), step, stop, repeats = job
    options = MasterOptions(stop=stop, step=step, algorithm=algorithm, extrapolation=extrapolation,
                            iterate_tol=iterate)
    times, result = [], None
    for _ in range(repeats):
        with Master(system, options) as master:  # loading and instantiating are not timed
            start = time.perf_counter()
            result = master.run()
            times.append(time.perf_counter() - start)
    # Every pass over a macro step steps each component once. A rolled-back pass restores the FMUs'
    # counters with their state, so its evaluations are counted at the kept pass's (fixed-step work).
    passes = result.iterations if iterate is not None else result.macro_steps + result.retries
    do_steps = passes * len(system.components)
    kept = sum(int(result[c][-1]) for c in result.columns if c.endswith(".n_rhs"))
    rhs = round(kept * passes / max(result.macro_steps, 1))
    return CouplingPoint(algorithm, extrapolation, math.nan if iterate is None else iterate, step,
                         coupling_error(result, CoupledPendulums.from_system(system)), rhs, do_steps,
                         statistics.median(times))


def coupling_sweep(system: System, stop: float | None = None, steps=STEPS, configurations=CONFIGURATIONS,
                   repeats: int = 3, scheduler: str | None = None, workers: int | None = None) -> list[CouplingPoint]:
    stop = stop if stop is not None else (system.stop or 10.0)
    communication_grid(0.0, stop, min(steps))  # a bad stop time fails here, before any work
    CoupledPendulums.from_system(system)
    jobs = [(system, configuration, step, stop, repeats) for configuration in configurations for step in steps]
    return run_sweep(measure, jobs, scheduler, workers)


def write_csv(points: list[CouplingPoint], path: Path) -> None:
    write_records(points, path, columns_of(CouplingPoint))


def read_csv(path: Path) -> list[CouplingPoint]:
    return read_records(path, CouplingPoint)
