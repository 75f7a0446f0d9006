"""Every FMU's ModelStructure says truthfully what depends on what, in FMI 2.0 and FMI 3.0, measured on
the binaries at a generic point (parameters, states, inputs and time away from special values, the
damping on): nudging one known at a time, the unknowns that move are exactly the ones that list it,
so an importer sees every real direct feedthrough and no false one (a false one makes a master such
as OMSimulator solve an algebraic loop the scene does not have).

* Model Exchange: outputs and state derivatives against the states, the inputs and time; the FMU's
  directional derivatives agree with central differences and are zero wherever nothing is listed.
* Co-Simulation: outputs and state derivatives at the end of a step against the inputs set for it. A
  direct dependency is one that stays as the step shrinks (from 1e-3 to 1e-5 s); what an input does
  through the states fades with the step (a position moves by F H^2 / 2m).
* Initialization Mode (both interfaces): the initial unknowns against the knowns of the standard:
  inputs, variables with initial = "exact" (parameters, the states' start values) and the start time.

FMI 2.0 has no variable for time here (its independent variable is implicit, known at every instant): an
unknown that depends on time lists the states and inputs it depends on beside it. Every output lists its
dependencies in both versions; only the state derivatives of objects with constraints may list none.
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model, FMU2Slave
from fmpy.fmi3 import FMU3Model, FMU3Slave

from harness.fmi.fmus import build_dir
from harness.objects.registry import handwritten_names, object_names

NAMES = [*object_names(), *handwritten_names()]
START_TIME = 0.2718  # not a multiple of the Kapitza drive's half period (0.01 s), where its anchor rests
GENERIC = {"d": 0.3, "c": 0.7,  # damping on, so that the velocities' dependencies show
           "R_a": 1.0, "R_b": 1.0}  # a Contact's bodies overlap wherever its inputs put the centres
                                    # (at most 1.8 m apart)
MOVED = 1e-11  # a change above this, relative to max(1, |value|), counts as moving


@dataclass
class Structure:
    """What a model description declares, read with fmpy (not with this project's writer)."""
    md: object
    running: dict[str, set[str] | None]   # outputs and state derivatives -> the knowns listed (None: no list)
    initial: dict[str, set[str] | None]   # initial unknowns -> the knowns listed
    states: list[str]
    inputs: list[str]

    @property
    def variables(self):
        return {v.name: v for v in self.md.modelVariables}


def structure(path: Path) -> Structure:
    md = read_model_description(str(path))

    def listed(unknowns):
        return {u.variable.name: None if u.dependencies is None else {v.name for v in u.dependencies}
                for u in unknowns}
    running = listed(md.outputs) | listed(md.derivatives)
    states = [d.variable.derivative.name for d in md.derivatives]
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    return Structure(md, running, listed(md.initialUnknowns), states, inputs)


@pytest.fixture(scope="module")
def fmus(fmu_paths, tmp_path_factory) -> dict[tuple[str, str], tuple[Structure, str]]:
    """(name, FMI version) -> the description and the extracted FMU."""
    found = {}
    for name in NAMES:
        for version, path in (("2.0", fmu_paths[name]), ("3.0", build_dir() / "fmus" / "fmi3" / f"{name}.fmu")):
            found[name, version] = (structure(path), extract(str(path), str(tmp_path_factory.mktemp(name))))
    return found


class Instance:
    """One instance through fmpy, the same few calls for both FMI versions and both interfaces."""

    CLASSES = {("2.0", "ME"): FMU2Model, ("2.0", "CS"): FMU2Slave, ("3.0", "ME"): FMU3Model, ("3.0", "CS"): FMU3Slave}

    def __init__(self, described: Structure, folder: str, version: str, kind: str):
        md = described.md
        self.version, self.kind, self.variables = version, kind, described.variables
        self.fmu = self.CLASSES[version, kind](
            guid=md.guid if version == "2.0" else md.instantiationToken, unzipDirectory=folder, instanceName="deps",
            modelIdentifier=(md.modelExchange if kind == "ME" else md.coSimulation).modelIdentifier)
        self.fmu.instantiate()

    def _floats(self, name: str) -> bool:
        return self.variables[name].type in ("Real", "Float64")

    def set(self, values: dict[str, float]) -> None:
        for floats in (True, False):
            chosen = {n: v for n, v in values.items() if self._floats(n) == floats}
            if not chosen:
                continue
            references = [self.variables[n].valueReference for n in chosen]
            if floats:
                (self.fmu.setReal if self.version == "2.0" else self.fmu.setFloat64)(references, list(chosen.values()))
            else:
                (self.fmu.setInteger if self.version == "2.0" else self.fmu.setInt64)(
                    references, [int(v) for v in chosen.values()])

    def get(self, names: list[str]) -> dict[str, float]:
        found = {}
        for name in names:
            variable = self.variables[name]
            if self._floats(name):
                value = (self.fmu.getReal if self.version == "2.0" else self.fmu.getFloat64)([variable.valueReference])
            elif self.version == "2.0":
                value = self.fmu.getInteger([variable.valueReference])
            else:
                value = (self.fmu.getUInt64 if variable.type == "UInt64"
                         else self.fmu.getInt64)([variable.valueReference])
            found[name] = float(value[0])
        return found

    def initialize(self, settings: dict[str, float], inputs: dict[str, float], start_time: float = START_TIME) -> None:
        """Parameters and start values before Initialization Mode, the inputs in it."""
        self.set(settings)
        if self.version == "2.0":
            self.fmu.setupExperiment(startTime=start_time)
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=start_time)
        self.set(inputs)
        self.fmu.exitInitializationMode()

    def continuous_time(self) -> None:
        if self.version == "2.0":
            self.fmu.newDiscreteStates()
        else:
            self.fmu.updateDiscreteStates()
        self.fmu.enterContinuousTimeMode()

    def set_states(self, x: np.ndarray) -> None:
        if len(x):
            self.fmu.setContinuousStates((ctypes.c_double * len(x))(*x), len(x))

    def directional(self, unknowns: list[str], known: str) -> list[float]:
        references = [self.variables[n].valueReference for n in unknowns]
        return list(self.fmu.getDirectionalDerivative(references, [self.variables[known].valueReference], [1.0]))

    def save(self):
        return self.fmu.getFMUstate() if self.version == "2.0" else self.fmu.getFMUState()

    def restore(self, state) -> None:
        (self.fmu.setFMUstate if self.version == "2.0" else self.fmu.setFMUState)(state)

    def close(self) -> None:
        self.fmu.terminate()
        self.fmu.freeInstance()


def constrained(described: Structure) -> bool:
    """An object with constraints: what its accelerations and forces depend on switches at contacts, so
    they list no dependencies (FMI: depends on every known), and a start must respect its constraints."""
    return described.md.numberOfEventIndicators > 0 and bool(described.states)


def generic_point(described: Structure, folder: str) -> tuple[dict[str, float], dict[str, float]]:
    """Settings (parameters and the states' start values) and inputs away from special values. An object
    with constraints gets offsets growing in the states' order, so that a row of touching balls parts
    (the cradle), and starts where its file does where the offsets break a constraint (a rigid rod)."""
    variables, rng = described.variables, np.random.default_rng(7)
    settings = {name: value for name, value in GENERIC.items() if name in variables}
    offsets = rng.uniform(0.1, 0.3, len(described.states))
    for name, offset in zip(described.states, np.sort(offsets) if constrained(described) else offsets):
        settings[name] = float(variables[name].start) + offset
    inputs = {name: float(rng.uniform(0.5, 1.5)) for name in described.inputs}
    if constrained(described) and not starts(described, folder, settings, inputs):
        settings.update({name: float(variables[name].start) for name in described.states})
    return settings, inputs


def starts(described: Structure, folder: str, settings: dict[str, float], inputs: dict[str, float]) -> bool:
    """Whether the FMU (FMI 2.0 Model Exchange) accepts the start."""
    instance = Instance(described, folder, described.md.fmiVersion, "ME")
    try:
        instance.initialize(settings, inputs)
        return True
    except FMICallException:
        return False
    finally:
        instance.fmu.freeInstance()


def nudged(variable, value: float) -> float:
    """A small change of a Real; another allowed value of an integer or enumeration."""
    if variable.type in ("Real", "Float64"):
        return value + 1e-4 * max(1.0, abs(value))
    highest = len(variable.declaredType.items) if variable.type == "Enumeration" else int(variable.max)
    return value + 1 if value + 1 <= highest else value - 1


def moved(before: dict[str, float], after: dict[str, float]) -> set[str]:
    return {n for n, value in after.items() if abs(value - before[n]) > MOVED * max(1.0, abs(before[n]))}


def mismatches(version: str, declared: dict[str, set[str] | None], observed: dict[str, set[str]],
               knowns: set[str], switching: bool = False) -> list[str]:
    """Where the listed knowns (restricted to `knowns`, those nudged) differ from the observed ones. An
    unlisted unknown must depend on time, where time is nudged; else it says nothing to compare. Where
    dependencies switch at contacts (`switching`), an unknown may list more than moves it at this point
    (a contact's stiffness acts only while it overlaps), or nothing (it may depend on every known)."""
    found = []
    for unknown, listed in declared.items():
        seen = observed.get(unknown, set())
        if version == "2.0" and listed is not None:  # time is implicit: never listed
            seen = seen - {"time"}
        if listed is None:
            if "time" in knowns and not (version == "2.0" and "time" in seen) and not switching:
                found.append(f"{unknown}: lists no dependencies, though it does not depend on time (moves with "
                             f"{sorted(seen)})")
        elif (listed & knowns) != seen and not (switching and seen <= listed):
            found.append(f"{unknown}: lists {sorted(listed & knowns)}, moves with {sorted(seen)}")
    return found


def every_fmu(test):
    """Run `test` for each FMU in both FMI versions."""
    return pytest.mark.parametrize("name", NAMES)(pytest.mark.parametrize("version", ["2.0", "3.0"])(test))


def started(fmus, name: str, version: str, kind: str):
    """The FMU's description, its generic point and an instance of it past Initialization Mode there."""
    described, folder = fmus[name, version]
    settings, inputs = generic_point(described, folder)
    instance = Instance(described, folder, version, kind)
    instance.initialize(settings, inputs)
    return described, settings, inputs, instance


@every_fmu
def test_model_exchange_lists_exactly_what_moves_the_unknowns(fmus, name, version):
    described, settings, inputs, instance = started(fmus, name, version, "ME")
    unknowns = sorted(described.running)
    reals = [n for n in unknowns if described.variables[n].type in ("Real", "Float64")]
    try:
        instance.continuous_time()
        x0 = np.array([settings[s] for s in described.states])

        def evaluate(x: np.ndarray, u: dict[str, float], t: float) -> dict[str, float]:
            instance.fmu.setTime(t)
            instance.set_states(x)
            instance.set(u)
            return instance.get(unknowns)
        base = evaluate(x0, inputs, START_TIME)
        # what moves with no nudge at all counts calls, not a function of the knowns: the counters
        restless = moved(base, evaluate(x0, inputs, START_TIME))
        observed: dict[str, set[str]] = {}
        problems = [f"{n}: moves on its own but lists {sorted(described.running[n])}" for n in restless
                    if described.running[n] != set()]
        for known in [*described.states, *described.inputs, "time"]:
            def at(step: float) -> dict[str, float]:
                x, u, t = x0.copy(), dict(inputs), START_TIME
                if known in described.states:
                    x[described.states.index(known)] += step
                elif known in u:
                    u[known] += step
                else:
                    t += step
                return evaluate(x, u, t)
            for unknown in moved(base, at(1e-4)) - restless:
                observed.setdefault(unknown, set()).add(known)
            if known == "time":
                continue
            if constrained(described):  # no partial derivatives (refused by name in test_constraints)
                continue
            # the FMU's own Jacobian column against a central difference of its values
            plus, minus = at(1e-5), at(-1e-5)
            evaluate(x0, inputs, START_TIME)
            for unknown, exact in zip(reals, instance.directional(reals, known)):
                difference = (plus[unknown] - minus[unknown]) / 2e-5
                if abs(exact - difference) > 1e-5 * max(1.0, abs(difference)):
                    problems.append(f"d{unknown}/d{known}: directional derivative {exact:.9g}, difference "
                                    f"{difference:.9g}")
                listed = described.running[unknown]
                if abs(exact) > 1e-10 * max(1.0, abs(difference)) and listed is not None and known not in listed:
                    problems.append(f"d{unknown}/d{known} = {exact:.3g} but {unknown} does not list {known}")
        knowns = {*described.states, *described.inputs, "time"}
        problems += mismatches(version, {n: d for n, d in described.running.items() if n not in restless}, observed,
                               knowns, constrained(described))
        assert not problems, "\n".join(problems)
        assert observed, "no nudge reached the model"
    finally:
        instance.close()


@every_fmu
def test_co_simulation_lists_exactly_the_direct_feedthrough(fmus, name, version):
    described, _, inputs, instance = started(fmus, name, version, "CS")
    unknowns = sorted(described.running)
    try:
        start = instance.save()

        def sensitivities(H: float) -> dict[str, dict[str, float]]:
            """d(unknown at the end of a step of H) / d(input set for the step), per input."""
            def step(u: dict[str, float]) -> dict[str, float]:
                instance.restore(start)
                instance.set(u)
                instance.fmu.doStep(START_TIME, H)
                return instance.get(unknowns)
            base = step(inputs)
            found = {}
            for known in described.inputs:
                after = step({**inputs, known: inputs[known] + 1e-4})
                found[known] = {n: (after[n] - base[n]) / 1e-4 for n in unknowns}
            return found
        long, short = sensitivities(1e-3), sensitivities(1e-5)
        observed: dict[str, set[str]] = {}
        for known in described.inputs:
            for unknown in unknowns:
                s_long, s_short = abs(long[known][unknown]), abs(short[known][unknown])
                if s_short > 1e-3 and s_short > 0.1 * s_long:  # does not fade with the step
                    observed.setdefault(unknown, set()).add(known)
        problems = mismatches(version, described.running, observed, set(described.inputs), constrained(described))
        assert not problems, "\n".join(problems)
        # every FMU here has one: a force to an acceleration, an end to the spring force
        assert observed, "no input feeds through to anything: the classification saw nothing"
    finally:
        instance.close()


@pytest.mark.parametrize("kind", ["ME", "CS"])
@every_fmu
def test_initialization_lists_exactly_what_moves_the_initial_unknowns(fmus, name, version, kind):
    described, folder = fmus[name, version]
    settings, inputs = generic_point(described, folder)
    variables = described.variables
    unknowns = sorted(described.initial)

    def initial_values(changed: dict[str, float], start_time: float = START_TIME) -> dict[str, float] | None:
        """The initial unknowns, or None for a start the FMU refuses (a nudge that breaks a rigid rod)."""
        instance = Instance(described, folder, version, kind)
        chosen = {**settings, **inputs, **changed}
        try:
            instance.initialize({n: v for n, v in chosen.items() if n not in inputs},
                                {n: v for n, v in chosen.items() if n in inputs}, start_time)
        except FMICallException:
            instance.fmu.freeInstance()
            assert constrained(described), f"{sorted(changed)}: a nudged start refused"
            return None
        try:
            return instance.get(unknowns)
        finally:
            instance.close()
    base = initial_values({})
    exact = [v.name for v in described.md.modelVariables
             if v.causality == "parameter" or (v.initial == "exact" and v.causality != "input")]
    observed: dict[str, set[str]] = {}
    for known in [*exact, *described.inputs]:
        value = settings.get(known, inputs.get(known))
        if value is None:
            value = float(variables[known].start)
        nudged_values = initial_values({known: nudged(variables[known], value)})
        for unknown in moved(base, nudged_values) if nudged_values is not None else ():
            observed.setdefault(unknown, set()).add(known)
    for unknown in moved(base, initial_values({}, START_TIME + 1e-4)):
        observed.setdefault(unknown, set()).add("time")
    problems = mismatches(version, described.initial, observed, {*exact, *described.inputs, "time"},
                          constrained(described))
    assert not problems, "\n".join(problems)


@every_fmu
def test_every_output_lists_its_dependencies(fmus, name, version):
    """An output without a list reads as depending on every known, the inputs among them: an importer then sees
    a feedthrough from every input (OMSimulator solves an algebraic loop the scene does not have). Every output
    lists its own, those that move with time (the Kapitza pendulum's shaken anchor) and the constraints' forces
    (every state and input) included."""
    described, _ = fmus[name, version]
    outputs = [u.variable.name for u in described.md.outputs]
    assert outputs and not [n for n in outputs if described.running[n] is None]
