"""Directional and adjoint derivatives: the generated exact Jacobian of the state derivatives and the
continuous outputs with respect to the states and inputs, in both FMI versions, checked against
central differences of the same binary's own derivatives and outputs; the Spring's hand-written one
too; and the refusals of what has no derivative (parameters as knowns, a NaN seed, wrong sizes)."""
from __future__ import annotations

import ctypes

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import (FMU2Model, FMU2Slave, defaultCallbacks, fmi2CallbackFunctions,
                       fmi2CallbackLoggerTYPE)
from fmpy.fmi3 import FMU3Model

from harness.fmi.fmus import FMU_NAMES, build_dir
from harness.objects.registry import constrained_names

LINEAR_OBJECTS = ("SimplePendulum", "DoublePendulum", "SpringPendulum", "Chain3")


class Log:
    def __init__(self):
        self.messages: list[str] = []

    def __call__(self, *args):
        self.messages.append(args[-1].decode())


@pytest.fixture(scope="module")
def extracted(fmu_paths, tmp_path_factory):
    """(path, folder) of every FMU of both versions, extracted once."""
    found = {}
    for name in FMU_NAMES:
        for version, path in ((2, build_dir() / "fmus" / f"{name}.fmu"),
                              (3, build_dir() / "fmus" / "fmi3" / f"{name}.fmu")):
            found[name, version] = (path, extract(str(path), str(tmp_path_factory.mktemp(f"{name}{version}"))))
    return found


class ModelExchange:
    """One Model Exchange instance in continuous-time mode, whichever the FMI version."""

    def __init__(self, extracted, name: str, version: int, start: dict[str, float], integers: dict[str, int],
                 time: float = 0.0):
        path, folder = extracted[name, version]
        self.md = read_model_description(str(path))
        self.version = version
        self.log = Log()
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        if version == 2:
            self.fmu = FMU2Model(guid=self.md.guid, unzipDirectory=folder,
                                 modelIdentifier=self.md.modelExchange.modelIdentifier, instanceName=name)
            callbacks = fmi2CallbackFunctions()
            callbacks.logger = fmi2CallbackLoggerTYPE(self.log)
            callbacks.allocateMemory = defaultCallbacks.allocateMemory
            callbacks.freeMemory = defaultCallbacks.freeMemory
            self.callbacks = callbacks  # kept alive as long as the instance
            self.fmu.instantiate(callbacks=callbacks)
            self.fmu.setupExperiment(startTime=0.0)
            self.set_integers = self.fmu.setInteger
        else:
            self.fmu = FMU3Model(guid=self.md.instantiationToken, unzipDirectory=folder,
                                 modelIdentifier=self.md.modelExchange.modelIdentifier, instanceName=name)
            self.fmu.instantiate(logMessage=self.log)
            self.set_integers = self.fmu.setInt64
        if integers:
            self.set_integers([self.vr[k] for k in integers], list(integers.values()))
        if version == 2:
            self.fmu.enterInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=0.0)
        self.set([self.vr[k] for k in start], list(start.values()))
        self.fmu.exitInitializationMode()
        if version == 2:
            self.fmu.newDiscreteStates()
        self.fmu.enterContinuousTimeMode()
        self.fmu.setTime(time)
        self.states = [d.variable.derivative.valueReference for d in self.md.derivatives]
        self.derivatives = [d.variable.valueReference for d in self.md.derivatives]
        self.inputs = [v.valueReference for v in self.md.modelVariables
                       if v.causality == "input" and v.type in ("Real", "Float64")]
        self.outputs = [v.valueReference for v in self.md.modelVariables if v.causality == "output"
                        and v.type in ("Real", "Float64") and v.variability == "continuous"]

    def set(self, refs, values):
        (self.fmu.setReal if self.version == 2 else self.fmu.setFloat64)(refs, values)

    def get(self, refs) -> np.ndarray:
        return np.array((self.fmu.getReal if self.version == 2 else self.fmu.getFloat64)(refs))

    def set_states(self, x) -> None:
        self.fmu.setContinuousStates((ctypes.c_double * len(x))(*x), len(x))

    def directional(self, unknowns, knowns, seed) -> np.ndarray:
        return np.array(self.fmu.getDirectionalDerivative(unknowns, knowns, seed))

    def jacobian(self, unknowns, knowns) -> np.ndarray:
        return np.array([self.directional(unknowns, [k], [1.0]) for k in knowns]).T

    def central_differences(self, unknowns, knowns) -> np.ndarray:
        columns = []
        for k in knowns:
            if k in self.states:
                x = self.get(self.states)
                i = self.states.index(k)
                step = 1e-6 * max(1.0, abs(x[i]))
                values = []
                for sign in (1, -1):
                    moved = x.copy()
                    moved[i] += sign * step
                    self.set_states(moved)
                    values.append(self.get(unknowns))
                self.set_states(x)
            else:
                u = self.get([k])[0]
                step = 1e-6 * max(1.0, abs(u))
                values = []
                for sign in (1, -1):
                    self.set([k], [u + sign * step])
                    values.append(self.get(unknowns))
                self.set([k], [u])
            columns.append((values[0] - values[1]) / (2 * step))
        return np.array(columns).T

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def moved_start(md, seed: int) -> dict[str, float]:
    """The start values of the states, each moved by a random amount: away from rest, where many
    entries of the Jacobian vanish."""
    rng = np.random.default_rng(seed)
    by_vr = {v.valueReference: v for v in md.modelVariables}
    start = {}
    for derivative in md.derivatives:
        state = by_vr[derivative.variable.derivative.valueReference]
        start[state.name] = float(state.start or 0.0) + rng.uniform(-0.3, 0.3)
    for v in md.modelVariables:
        if v.causality == "input" and v.type in ("Real", "Float64"):
            start[v.name] = rng.uniform(-2.0, 2.0)
    return start


def assert_jacobians_agree(exact: np.ndarray, differences: np.ndarray, names: list[str], knowns: list[str]):
    scale = np.maximum(1.0, np.max(np.abs(differences), axis=1, keepdims=True))
    deviation = np.abs(exact - differences) / scale
    i, j = np.unravel_index(np.argmax(deviation), deviation.shape)
    assert deviation[i, j] < 1e-7, (f"d{names[i]}/d{knowns[j]}: exact {exact[i, j]:.10g}, central differences "
                                    f"{differences[i, j]:.10g}")


@pytest.mark.parametrize("version", [2, 3])
# objects with constraints provide no partial derivatives (their refusal is tested in test_constraints)
@pytest.mark.parametrize("name, model", [(n, "nonlinear") for n in FMU_NAMES if n not in constrained_names()]
                         + [(n, "linear") for n in LINEAR_OBJECTS])
def test_the_exact_jacobian_equals_central_differences(extracted, name, model, version):
    md = read_model_description(str(extracted[name, version][0]))
    instance = ModelExchange(extracted, name, version, moved_start(md, 7), {"model": 2} if model == "linear" else {},
                             time=0.37)
    try:
        knowns = instance.states + instance.inputs
        unknowns = instance.derivatives + instance.outputs
        exact = instance.jacobian(unknowns, knowns)
        differences = instance.central_differences(unknowns, knowns)
        by_vr = {v.valueReference: v.name for v in md.modelVariables}
        assert np.count_nonzero(exact) >= len(unknowns)  # a Jacobian of zeros would pass nothing
        assert_jacobians_agree(exact, differences, [by_vr[u] for u in unknowns], [by_vr[k] for k in knowns])
        # a seed over several knowns is the sum of their columns
        seed = np.linspace(0.5, -1.5, len(knowns))
        combined = instance.directional(unknowns, knowns, list(seed))
        assert np.allclose(combined, exact @ seed, rtol=1e-12, atol=1e-12 * np.max(np.abs(exact)))
        if version == 3:  # the adjoint: seed^T J, one value per known
            weights = np.linspace(1.0, 2.0, len(unknowns))
            adjoint = instance.fmu.getAdjointDerivative(unknowns, knowns, list(weights), nSensitivity=len(knowns))
            assert np.allclose(adjoint, weights @ exact, rtol=1e-12, atol=1e-12 * np.max(np.abs(exact)))
    finally:
        instance.free()


@pytest.mark.parametrize("name", ["DoublePendulum", "SpringPendulum", "Spring"])
def test_co_simulation_gives_the_jacobian_of_model_exchange(extracted, name):
    """After a step and a new input, Co-Simulation's Jacobian is taken at the inputs as they are now
    (its outputs still belong to the end of the step): equal to Model Exchange's at the same state,
    time and inputs."""
    path, folder = extracted[name, 2]
    md = read_model_description(str(path))
    start = moved_start(md, 3)
    me = ModelExchange(extracted, name, 2, start, {})
    cs = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                   instanceName="cs")
    cs.instantiate()
    cs.setupExperiment(startTime=0.0)
    cs.enterInitializationMode()
    cs.setReal([me.vr[k] for k in start], list(start.values()))
    cs.exitInitializationMode()
    try:
        cs.doStep(0.0, 0.1)
        if me.states:
            me.fmu.setTime(0.1)
            me.set_states(cs.getReal(me.states))
        changed = [v + 10.0 for v in cs.getReal(me.inputs)]
        cs.setReal(me.inputs, changed)
        me.set(me.inputs, changed)
        for k in me.states + me.inputs:
            assert cs.getDirectionalDerivative(me.outputs + me.derivatives, [k], [1.0]) == \
                me.fmu.getDirectionalDerivative(me.outputs + me.derivatives, [k], [1.0]), k
    finally:
        me.free()
        cs.terminate()
        cs.freeInstance()


def test_a_co_simulation_input_that_makes_the_spring_singular_gives_no_jacobian(extracted):
    """l0 > 0 and both ends moved together after initialization: the direction of the force is
    undefined, and so is its derivative (a discard, as in Model Exchange)."""
    path, folder = extracted["Spring", 2]
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    log = Log()
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(log)
    callbacks.allocateMemory = defaultCallbacks.allocateMemory
    callbacks.freeMemory = defaultCallbacks.freeMemory
    cs = FMU2Slave(guid=md.guid, unzipDirectory=folder, modelIdentifier=md.coSimulation.modelIdentifier,
                   instanceName="cs")
    cs.instantiate(callbacks=callbacks)
    cs.setupExperiment(startTime=0.0)
    cs.enterInitializationMode()
    cs.exitInitializationMode()
    try:
        cs.setReal([vr[n] for n in ("a_x", "a_y", "b_x", "b_y")], [0.3, 0.3, 0.3, 0.3])
        out = reals([7.0])
        assert raw_status(cs, "fmi2GetDirectionalDerivative", refs([vr["Fa_x"]]), 1, refs([vr["a_x"]]), 1,
                          reals([1.0]), out) == 2 and out[0] == 7.0
        assert "undefined in the current (singular) configuration" in log.messages[-1]
    finally:
        cs.terminate()
        cs.freeInstance()


def raw_status(fmu, function: str, *args) -> int:
    found = getattr(fmu.dll, function)
    found.restype = ctypes.c_int
    return found(fmu.component, *args)


def refs(values) -> ctypes.Array:
    return (ctypes.c_uint32 * len(values))(*values)


def reals(values) -> ctypes.Array:
    return (ctypes.c_double * max(1, len(values)))(*values)


@pytest.mark.parametrize("version", [2, 3])
def test_what_has_no_derivative_is_refused_by_name(extracted, version):
    name = "SimplePendulum"
    instance = ModelExchange(extracted, name, version, {}, {})
    vr = instance.vr
    function = "fmi2GetDirectionalDerivative" if version == 2 else "fmi3GetDirectionalDerivative"

    def call(unknowns, knowns, seed, sizes=None) -> int:
        out = reals([0.0] * len(unknowns))
        sizes = sizes or (len(seed), len(unknowns))
        if version == 2:
            return raw_status(instance.fmu, function, refs(unknowns), len(unknowns), refs(knowns), len(knowns),
                              reals(seed), out)
        return raw_status(instance.fmu, function, refs(unknowns), ctypes.c_size_t(len(unknowns)), refs(knowns),
                          ctypes.c_size_t(len(knowns)), reals(seed), ctypes.c_size_t(sizes[0]), out,
                          ctypes.c_size_t(sizes[1]))

    def last_message() -> str:
        return instance.log.messages[-1] if instance.log.messages else ""
    try:
        cases = [
            (([vr["der(omega)"]], [vr["L"]], [1.0]), "known L (value reference 10) is not a continuous state or a Real "
                                                       "input"),
            (([vr["g"]], [vr["phi"]], [1.0]), "unknown g (value reference 4) is not a state derivative or a "
                                                "continuous output"),
            (([vr["der(omega)"]], [vr["phi"]], [float("nan")]), "seed[0] = nan is not a finite number"),
            (([vr["der(omega)"]], [999], [1.0]), "999"),
        ]
        for arguments, words in cases:
            assert call(*arguments) == 3, words
            assert words in last_message() and function in last_message(), last_message()
        assert call([vr["der(omega)"]], [vr["phi"]], [1.0]) == 0
        if version == 3:
            assert call([vr["der(omega)"]], [vr["phi"]], [1.0], sizes=(2, 1)) == 3
            assert "nSeed = 2 and nSensitivity = 1, but there are 1 knowns and 1 unknowns" in last_message()
    finally:
        instance.free()


@pytest.mark.parametrize("version", [2, 3])
def test_a_derivative_that_overflows_is_a_discard_and_hands_out_nothing(extracted, version):
    """The Spring's force is finite (the ends move apart sideways: no damping force) while its
    derivative with respect to the sideways position, c |v| / r, overflows."""
    instance = ModelExchange(extracted, "Spring", version,
                             {"k": 1e-9, "c": 1e300, "l0": 0.0, "b_x": 1e-10, "b_vy": 1.0}, {})
    vr = instance.vr
    function = "fmi2GetDirectionalDerivative" if version == 2 else "fmi3GetDirectionalDerivative"
    try:
        assert np.all(np.isfinite(instance.get([vr["Fa_x"], vr["Fa_y"]])))
        out = reals([12345.0])
        if version == 2:
            status = raw_status(instance.fmu, function, refs([vr["Fa_y"]]), 1, refs([vr["b_y"]]), 1, reals([1.0]), out)
        else:
            status = raw_status(instance.fmu, function, refs([vr["Fa_y"]]), ctypes.c_size_t(1), refs([vr["b_y"]]),
                                ctypes.c_size_t(1), reals([1.0]), ctypes.c_size_t(1), out, ctypes.c_size_t(1))
        assert status == 2 and out[0] == 12345.0
        assert "the derivative of Fa_y with respect to b_y is not finite" in instance.log.messages[-1]
    finally:
        instance.free()
