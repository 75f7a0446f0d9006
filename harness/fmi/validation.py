"""validate: fmpy's model-description validation and quick runtime conformance checks for any FMU;
for an FMU made from an object file the object's proof (harness.objects.proof: numeric route,
orders, energy, tolerance, Model Exchange with CVode); for the three thesis pendulums also the
hand-written derivation (harness.objects.thesis.lagrange) and the exact elliptic solution."""
from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.errors import HarnessError
from harness.fmi.calls import is_float
from harness.fmi.fmu_instance import ERROR, OK, FmuInstance, read_description
from harness.objects.proof import object_file_in, prove
from harness.objects.thesis.reference import exact_simple_pendulum, slope

PENDULUMS = ("SimplePendulum", "DoublePendulum", "SpringPendulum")


@dataclass
class Check:
    fmu: str
    name: str
    passed: bool
    detail: str

    def __str__(self) -> str:
        return f"  {'PASS' if self.passed else 'FAIL'}  {self.name}: {self.detail}"


def _model_description_checks(path: Path) -> list[Check]:
    from fmpy.validation import validate_fmu
    try:
        read_description(path)
    except HarnessError as error:
        return [Check(path.name, "modelDescription (fmpy)", False, str(error))]
    problems = validate_fmu(str(path))
    detail = "no problems" if not problems else "; ".join(problems[:5]) + (" ..." if len(problems) > 5 else "")
    return [Check(path.name, "modelDescription (fmpy)", not problems, detail)]


def _finite_outputs(instance: FmuInstance) -> tuple[bool, str]:
    names = [v.name for v in instance.model_description.modelVariables if v.causality == "output"]
    values = instance.get(*names)
    bad = [n for n, v in zip(names, values) if not math.isfinite(v)]
    return not bad, f"{len(names)} outputs finite" if not bad else f"non-finite: {', '.join(bad)}"


def _runtime_checks(path: Path) -> list[Check]:
    checks = []
    md = read_description(path)
    step = md.defaultExperiment.stepSize if md.defaultExperiment and md.defaultExperiment.stepSize else 0.01
    step = float(step)

    def check(name: str, passed: bool, detail: str) -> None:
        checks.append(Check(path.name, name, bool(passed), detail))

    with FmuInstance(path) as fmu:
        status = fmu.do_step(0.0, step)
        check("illegal call refused", status == ERROR,
              f"{fmu.prefix}DoStep before initialization returned status {status}")
    with FmuInstance(path) as fmu:
        fmu.initialize()
        statuses = [fmu.do_step(i * step, step) for i in range(10)]
        check("Co-Simulation steps", all(s == OK for s in statuses),
              f"10 steps of {step:g} s: statuses {set(statuses)}")
        check("outputs finite", *_finite_outputs(fmu))
        check("time exact", fmu.last_successful_time() == 9 * step + step,
              f"after {fmu.prefix}DoStep({9 * step!r}, {step!r}) the FMU's time is {fmu.last_successful_time()!r}")
        if md.coSimulation.canGetAndSetFMUstate:
            names = [v.name for v in md.modelVariables if v.causality == "output" and is_float(v)]
            state = fmu.get_state()
            data = fmu.serialize(state) if md.coSimulation.canSerializeFMUstate else None
            for i in range(10, 15):
                fmu.do_step(i * step, step)
            expected = fmu.get(*names)
            fmu.set_state(state)
            for i in range(10, 15):
                fmu.do_step(i * step, step)
            check("FMU state round trip", fmu.get(*names) == expected, "get/set continues bit-identically")
            if data is not None:
                fmu.set_state(fmu.deserialize(data))
                for i in range(10, 15):
                    fmu.do_step(i * step, step)
                check("serialized FMU state", fmu.get(*names) == expected,
                      f"{len(data)} bytes restore and continue bit-identically")
            fmu.free_state(state)
        check("reset", fmu.role("reset") == OK, f"{fmu.prefix}Reset returns the instance to its start values")
    if md.modelExchange is not None:
        with FmuInstance(path, kind="ME") as fmu:
            fmu.initialize()
            n = md.numberOfContinuousStates
            derivatives = (ctypes.c_double * max(n, 1))()
            status = max(fmu.role("continuous_time_mode"), fmu.role("derivatives", derivatives, n))
            finite = all(math.isfinite(v) for v in derivatives[:n])
            check("Model Exchange", status == OK and finite, f"{n} state derivatives, status {status}")
    return checks


def _physics_checks(path: Path, name: str) -> list[Check]:
    from harness.objects.thesis.lagrange import derived_model, random_point
    checks = []
    names, reference, positions, q, qd = derived_model(name)
    rng = np.random.default_rng(7)
    worst = 0.0
    with FmuInstance(path, kind="ME") as fmu:
        n = 2 * len(q)
        derivatives = (ctypes.c_double * n)()
        for _ in range(20):
            point = random_point(name, rng)
            fmu.reset()
            fmu.initialize(**point)
            fmu.role("derivatives", derivatives, n)
            expected = np.array(reference(*[point[k] for k in names])[:len(q)])
            worst = max(worst, float(np.max(np.abs(np.array(derivatives[len(q):]) - expected)
                                            / (1 + np.abs(expected)))))
    checks.append(Check(path.name, "right-hand side = Euler-Lagrange (SymPy)", worst < 1e-10,
                        f"largest relative deviation {worst:.1e} at 20 random states, parameters and forces"))
    if name == "SimplePendulum":
        for solver, order, hs in (("rk4", 4, [0.08, 0.04, 0.02, 0.01]), ("ab4", 4, [0.04, 0.02, 0.01, 0.005]),
                                  ("heun", 2, [0.02, 0.01, 0.005, 0.0025])):
            errors = []
            for h in hs:
                with FmuInstance(path) as fmu:
                    fmu.initialize(solver=solver, h=h)
                    fmu.do_step(0.0, 2.0)
                    phi, omega = fmu.get("phi", "omega")
                exact_phi, exact_omega = exact_simple_pendulum(0.5, 2.0)
                errors.append(max(abs(phi - exact_phi), abs(omega - exact_omega) / math.sqrt(9.81)))
            measured = slope(hs, errors)
            checks.append(Check(path.name, f"order of {solver} (exact elliptic solution)", abs(measured - order) <= 0.3,
                                f"{measured:.2f} against the exact elliptic solution (theory {order})"))
    return checks


def validate(path: str | Path) -> list[Check]:
    path = Path(path)
    if not path.is_file():
        raise HarnessError(f"{path}: no such FMU file")
    checks = _model_description_checks(path)
    if not checks[0].passed:
        return checks
    try:
        checks += _runtime_checks(path)
        spec = object_file_in(path)
        if spec is not None:
            checks += [Check(path.name, proof.name, proof.passed, proof.detail) for proof in prove(path, spec)]
        model = read_description(path).modelName
        if model in PENDULUMS:
            checks += _physics_checks(path, model)
    except HarnessError as error:
        checks.append(Check(path.name, "runtime", False, str(error)))
    return checks
