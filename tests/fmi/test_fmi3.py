"""The FMI 3.0 FMUs (build/fmus/fmi3/<id>.fmu): the same binaries' numbers as FMI 2.0 through the FMI
3.0 layer, its state machine and argument checks with their messages, the intermediate-update
callback at internal steps, FMU state round trips, exported symbols, the standard's own headers,
and fmpy's validation, simulation and source build."""
from __future__ import annotations

import ctypes
import re
import subprocess
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi3 import FMU3Model, FMU3Slave, fmi3Error, fmi3OK
from fmpy.validation import validate_fmu


from harness.fmi.methods import METHODS, SOLVERS
from harness.fmi.fmus import build_dir
from harness.objects.registry import PROJECT_ROOT, handwritten_names, object_names

from conftest import rebuilt_with_fmpy

NAMES = [*object_names(), *handwritten_names()]


def solver(name: str) -> int:
    """The enumeration value of a method: its position in the method list, from 1."""
    return SOLVERS.index(name) + 1


@pytest.fixture(scope="session")
def fmi3_paths(fmu_paths) -> dict[str, Path]:
    return {name: build_dir() / "fmus" / "fmi3" / f"{name}.fmu" for name in fmu_paths}


@pytest.fixture(scope="session")
def fmi3_unzipped(fmi3_paths, tmp_path_factory) -> dict[str, str]:
    return {name: extract(str(path), str(tmp_path_factory.mktemp(f"{name}3"))) for name, path in fmi3_paths.items()}


def raw(fmu, function: str):
    """The binary's function itself, returning its status (fmpy's wrappers raise on an error)."""
    found = getattr(fmu.dll, function)
    found.restype = ctypes.c_int
    return lambda *args: found(fmu.component, *args)


class Log:
    """The FMU's messages, through FMI 3.0's logger."""

    def __init__(self):
        self.messages: list[tuple[int, str]] = []

    def __call__(self, environment, status, category, message):
        self.messages.append((status, message.decode()))

    def last(self) -> str:
        return self.messages[-1][1] if self.messages else ""


def slave(fmi3_paths, fmi3_unzipped, name: str, log: Log | None = None, **instantiate) -> FMU3Slave:
    md = read_model_description(str(fmi3_paths[name]))
    fmu = FMU3Slave(guid=md.instantiationToken, unzipDirectory=fmi3_unzipped[name],
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
    fmu.instantiate(logMessage=log if log is not None else Log(), **instantiate)
    return fmu


def references(path: Path) -> dict[str, int]:
    return {v.name: v.valueReference for v in read_model_description(str(path)).modelVariables}


@pytest.mark.compatibility(importer=f"fmpy {fmpy.__version__} validate_fmu", version="3.0", interface="CS, ME",
                           platform="(model description)", criterion="no problem reported")
@pytest.mark.parametrize("name", NAMES)
def test_fmpy_validates_the_fmu(fmi3_paths, compatibility, name):
    assert validate_fmu(str(fmi3_paths[name])) == []
    compatibility.agrees(name)


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("fmi_type", ["CoSimulation", "ModelExchange"])
def test_fmpy_simulates_it_as_it_simulates_fmi2(fmu_paths, fmi3_paths, name, fmi_type):
    """fmpy's FMI 3.0 importer against its FMI 2.0 one over 10 s: the same binary arithmetic, so the
    same numbers bit for bit."""
    kwargs = dict(fmi_type=fmi_type, stop_time=10.0, output_interval=0.05)
    new = fmpy.simulate_fmu(str(fmi3_paths[name]), **kwargs)
    old = fmpy.simulate_fmu(str(fmu_paths[name]), **kwargs)
    names = [n for n in old.dtype.names if n != "time"]
    assert names and set(names) <= set(new.dtype.names)
    for column in ["time", *names]:
        assert np.array_equal(new[column], old[column]), column
    moving = [n for n in names if np.ptp(old[n]) > 1e-3]
    assert moving or name in handwritten_names()


@pytest.mark.parametrize("method", METHODS, ids=[m.name for m in METHODS])
def test_every_method_gives_the_fmi2_numbers(fmu_paths, fmi3_paths, method):
    name = "SimplePendulum" if method.needs_constant_mass else "DoublePendulum"
    kwargs = dict(stop_time=5.0, output_interval=0.1,
                  start_values={"solver": solver(method.name), "h": 0.01, "tol": 1e-8})
    new = fmpy.simulate_fmu(str(fmi3_paths[name]), **kwargs)
    old = fmpy.simulate_fmu(str(fmu_paths[name]), **kwargs)
    states = ("phi", "omega") if name == "SimplePendulum" else ("phi1", "phi2", "omega1", "omega2")
    for column in (*states, "n_rhs", "n_steps", "n_jacobians", "n_iterations"):
        assert np.array_equal(new[column], old[column]), column


def run_with_reports(fmi3_paths, fmi3_unzipped, method: int, h: float, H: float, steps: int):
    """A Co-Simulation run that records every intermediate update: (time, phi read in the callback)."""
    refs = references(fmi3_paths["SimplePendulum"])
    reports: list[tuple[float, float, bool, bool]] = []
    holder = {}

    def intermediate(environment, t, set_requested, get_allowed, step_finished, can_return_early, early, early_time):
        phi = holder["fmu"].getFloat64([refs["phi"]])[0]
        reports.append((t, phi, bool(get_allowed), bool(set_requested)))

    fmu = slave(fmi3_paths, fmi3_unzipped, "SimplePendulum", intermediateUpdate=intermediate)
    holder["fmu"] = fmu
    fmu.setInt64([refs["solver"]], [method])
    fmu.setFloat64([refs["h"], refs["tol"]], [h, 1e-8])
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    ends = []
    t = 0.0
    for _ in range(steps):
        fmu.doStep(t, H)
        t += H
        ends.append((t, fmu.getFloat64([refs["phi"]])[0]))
    fmu.terminate()
    fmu.freeInstance()
    return reports, ends


def test_intermediate_updates_report_every_internal_step(fmi3_paths, fmi3_unzipped):
    """rk4 with h = 0.01 in steps of 0.1: ten reports per step at t0 + k h, each with the state of that
    substep (equal to an FMI 2.0 run that stops at every substep), outputs readable, nothing to set."""
    reports, ends = run_with_reports(fmi3_paths, fmi3_unzipped, solver("rk4"), 0.01, 0.1, 5)
    assert len(reports) == 50
    times = np.array([r[0] for r in reports])
    assert np.allclose(times, 0.01 * np.arange(1, 51), rtol=0, atol=1e-12)
    assert all(get and not set_ for _, _, get, set_ in reports)
    fine = fmpy.simulate_fmu(str(PROJECT_ROOT / "build" / "fmus" / "SimplePendulum.fmu"), stop_time=0.5,
                             output_interval=0.01, start_values={"solver": solver("rk4"), "h": 0.01})
    assert np.allclose([r[1] for r in reports], fine["phi"][1:51], rtol=0, atol=1e-13)
    # the step's end is its last report
    for t_end, phi in ends:
        match = [r for r in reports if abs(r[0] - t_end) < 1e-12]
        assert match and match[-1][1] == phi


def test_intermediate_updates_follow_the_accepted_rkf45_steps(fmi3_paths, fmi3_unzipped):
    reports, ends = run_with_reports(fmi3_paths, fmi3_unzipped, solver("rkf45"), 0.05, 0.5, 4)
    times = [r[0] for r in reports]
    assert len(times) > 4
    assert all(b > a for a, b in zip(times, times[1:]))  # accepted steps only, in order
    for t_end, _ in ends:
        assert any(abs(t - t_end) < 1e-12 for t in times)
    # the same run without a callback ends in the same state
    plain = fmpy.simulate_fmu(str(PROJECT_ROOT / "build" / "fmus" / "SimplePendulum.fmu"), stop_time=2.0,
                              output_interval=0.5, start_values={"solver": solver("rkf45"), "h": 0.05, "tol": 1e-8})
    assert np.allclose([phi for _, phi in ends], plain["phi"][1:], rtol=0, atol=1e-12)


def long_call(fmi3_paths, fmi3_unzipped, name: str, settings: dict, steps: int, refs: list[int], report: bool):
    """One fmi3DoStep over `steps` internal steps: every Real output of `refs` read at each report (when `report`),
    and at the end; the end's n_rhs and n_steps."""
    reported: list[list[float]] = []
    holder = {}

    def intermediate(environment, t, set_requested, get_allowed, step_finished, can_return_early, early, early_time):
        if get_allowed and step_finished:
            reported.append(holder["fmu"].getFloat64(refs))

    fmu = slave(fmi3_paths, fmi3_unzipped, name, **({"intermediateUpdate": intermediate} if report else {}))
    holder["fmu"] = fmu
    variables = references(fmi3_paths[name])
    fmu.setInt64([variables["solver"]], [settings["solver"]])
    for key, value in settings.items():
        if key != "solver":
            fmu.setFloat64([variables[key]], [value])
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    fmu.doStep(0.0, steps * settings["h"])
    end = fmu.getFloat64(refs)
    counters = list(fmu.getUInt64([variables["n_rhs"], variables["n_steps"]]))
    fmu.terminate()
    fmu.freeInstance()
    return reported, end, counters


def bits(values) -> np.ndarray:
    """Doubles as their bit patterns: equal only where every bit is (-0.0 is not 0.0)."""
    return np.asarray(values, dtype=np.float64).view(np.uint64)


@pytest.mark.parametrize("name, inputs", [("SimplePendulum", {"F_x": 0.3}), ("SimplePendulum", {}),
                                          ("KapitzaPendulum", {})])
@pytest.mark.parametrize("method", ["heun", "rk4", "ab5", "abm4", "gbs", "gauss_legendre4"])
def test_reported_steps_are_the_steps_of_one_call_each_bit_for_bit(open_fmu, fmi3_paths, fmi3_unzipped, name, inputs,
                                                                  method):
    """One fmi3DoStep of 300 internal steps (a check block of 256 and the rest), every Real output read at each
    step's report: the end is that of the same call without a callback, and (but for gauss_legendre4, whose Newton
    iteration starts each step from the step before inside a call) each step's outputs are those of 300
    fmi2DoStep calls of one step each, read after each call. At h = 2^-7 every time is exact in all three, so the
    comparisons are of bits. With a held force (the model's force terms) and without, and on the Kapitza pendulum,
    whose right-hand side depends on t."""
    h, steps = 2.0 ** -7, 300
    settings = {"solver": solver(method), "h": h, "tol": 0.0 if method == "gbs" else 1e-8, **inputs}
    outputs = [v for v in read_model_description(str(fmi3_paths[name])).modelVariables
               if v.causality == "output" and v.type == "Float64"]
    refs = [v.valueReference for v in outputs]
    reported, end, counters = long_call(fmi3_paths, fmi3_unzipped, name, settings, steps, refs, report=True)
    _, quiet_end, quiet_counters = long_call(fmi3_paths, fmi3_unzipped, name, settings, steps, refs, report=False)
    assert len(reported) == steps
    assert np.array_equal(bits(end), bits(reported[-1]))
    assert np.array_equal(bits(end), bits(quiet_end)) and counters == quiet_counters
    if method == "gauss_legendre4":
        return
    calls = open_fmu(name)
    calls.initialize(**settings)
    each_call = []
    for i in range(steps):
        assert calls.do_step(i * h, h) == 0
        each_call.append(calls.get(*(v.name for v in outputs)))
    assert np.array_equal(bits(reported), bits(each_call))
    assert counters == calls.get("n_rhs", "n_steps")


@pytest.mark.parametrize("method", ["rk4", "ab5", "gbs"])
def test_a_reported_call_that_fails_stops_where_the_same_call_without_reports_stops(fmi3_paths, fmi3_unzipped, method):
    """The spherical pendulum's plane swing reaches the pole, where psi is undefined, inside one fmi3DoStep of 5 s at
    h = 0.001: with reports and without, the call ends in fmi3Discard at the same last successful time with the same
    message and state, and the last report shows that time and state (a refused step is never reported)."""
    refs = references(fmi3_paths["SphericalPendulum"])
    outputs = [v.valueReference for v in read_model_description(str(fmi3_paths["SphericalPendulum"])).modelVariables
               if v.causality == "output" and v.type == "Float64"]
    runs = []
    for report in (True, False):
        log = Log()
        reported: list[tuple[float, list[float]]] = []
        holder = {}

        def intermediate(environment, t, set_requested, get_allowed, step_finished, can_return_early, early, when):
            reported.append((t, holder["fmu"].getFloat64(outputs)))

        fmu = slave(fmi3_paths, fmi3_unzipped, "SphericalPendulum", log=log,
                    **({"intermediateUpdate": intermediate} if report else {}))
        holder["fmu"] = fmu
        fmu.setInt64([refs["solver"]], [solver(method)])
        fmu.setFloat64([refs["h"], refs["psi_dot"], refs["tol"]], [0.001, 0.0, 0.0 if method == "gbs" else 1e-8])
        fmu.enterInitializationMode(startTime=0.0)
        fmu.exitInitializationMode()
        flag, last = ctypes.c_bool(), ctypes.c_double()
        status = raw(fmu, "fmi3DoStep")(ctypes.c_double(0.0), ctypes.c_double(5.0), ctypes.c_bool(True),
                                        ctypes.byref(flag), ctypes.byref(flag), ctypes.byref(flag), ctypes.byref(last))
        runs.append((status, last.value, log.last(), bits(fmu.getFloat64(outputs)), reported))
        fmu.terminate()
        fmu.freeInstance()
    (status, last, message, state, reported), (quiet_status, quiet_last, quiet_message, quiet_state, _) = runs
    assert status == quiet_status == 2  # fmi3Discard
    assert 0.0 < last == quiet_last < 5.0 and message == quiet_message and "singular" in message
    assert np.array_equal(state, quiet_state)
    assert reported and reported[-1][0] == last and np.array_equal(bits(reported[-1][1]), state)


def test_the_callback_cannot_step_or_read_parameters(fmi3_paths, fmi3_unzipped):
    refs = references(fmi3_paths["SimplePendulum"])
    log = Log()
    results = []
    holder = {}

    def intermediate(environment, t, *rest):
        fmu = holder["fmu"]
        flag = ctypes.c_bool()
        results.append(raw(fmu, "fmi3DoStep")(ctypes.c_double(t), ctypes.c_double(0.1), ctypes.c_bool(True),
                                              ctypes.byref(flag), ctypes.byref(flag), ctypes.byref(flag),
                                              ctypes.byref(ctypes.c_double())))
        values = (ctypes.c_double * 1)()
        vr = (ctypes.c_uint32 * 1)(refs["L"])
        results.append(raw(fmu, "fmi3GetFloat64")(vr, ctypes.c_size_t(1), values, ctypes.c_size_t(1)))

    fmu = slave(fmi3_paths, fmi3_unzipped, "SimplePendulum", log=log, intermediateUpdate=intermediate)
    holder["fmu"] = fmu
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    fmu.doStep(0.0, 0.01)
    assert results[:2] == [fmi3Error, fmi3Error]
    text = " ".join(m for _, m in log.messages)
    assert "fmi3DoStep: illegal call sequence: not allowed in state Intermediate Update Mode" in text
    assert "only the outputs" in text
    fmu.freeInstance()


def asking_run(fmi3_paths, fmi3_unzipped, force, answer, registered=("F_x",), steps=5, H=0.1, log=None):
    """SimplePendulum (rk4, h = 0.01) stepped by H with F_x = force(t0) set before each step and the inputs
    `registered` for intermediate updates, answered by answer(fmu, t): the calls of the callback
    (t, set requested, get allowed, step finished) and the states after each step."""
    refs = references(fmi3_paths["SimplePendulum"])
    calls, states, holder = [], [], {}

    def intermediate(environment, t, set_requested, get_allowed, step_finished, can_return_early, early, early_time):
        calls.append((t, bool(set_requested), bool(get_allowed), bool(step_finished)))
        if set_requested:
            answer(holder["fmu"], t)

    fmu = slave(fmi3_paths, fmi3_unzipped, "SimplePendulum", log=log, intermediateUpdate=intermediate,
                requiredIntermediateVariables=[refs[name] for name in registered])
    holder["fmu"] = fmu
    fmu.setInt64([refs["solver"]], [solver("rk4")])
    fmu.setFloat64([refs["h"]], [0.01])
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    for k in range(steps):
        fmu.setFloat64([refs["F_x"]], [force(k * H)])
        fmu.doStep(k * H, H)
        states.append(fmu.getFloat64([refs["phi"], refs["omega"]]))
    fmu.freeInstance()
    return calls, np.array(states)


def fmi2_run_with_slopes(fmu_paths, force, slope, steps=5, H=0.1):
    """The same run through FMI 2.0, each step's F_x with its derivative set (None: held)."""
    from fmpy.fmi2 import FMU2Slave
    md = read_model_description(str(fmu_paths["SimplePendulum"]))
    refs = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu_paths["SimplePendulum"])),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="two")
    fmu.instantiate()
    fmu.setInteger([refs["solver"]], [solver("rk4")])
    fmu.setReal([refs["h"]], [0.01])
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    states = []
    for k in range(steps):
        fmu.setReal([refs["F_x"]], [force(k * H)])
        if slope is not None:
            fmu.setRealInputDerivatives([refs["F_x"]], [1], [slope])
        fmu.doStep(k * H, H)
        states.append(fmu.getReal([refs["phi"], refs["omega"]]))
    fmu.freeInstance()
    return np.array(states)


def test_registered_inputs_are_asked_for_at_the_step_end_and_follow_a_line(fmu_paths, fmi3_paths, fmi3_unzipped):
    """FMI 3.0 has no input derivatives: an importer that registers an input is asked for it once per step, before
    the step, at its end (set requested, nothing readable, not a finished step), and the step takes the input
    along the line to the value given: FMI 2.0's numbers with that slope set as the input derivative. An importer
    that registered only inputs is not called at the internal steps."""
    force = lambda t: 2.0 + 3.0 * t  # noqa: E731
    refs = references(fmi3_paths["SimplePendulum"])
    calls, states = asking_run(fmi3_paths, fmi3_unzipped, force,
                               lambda fmu, t: fmu.setFloat64([refs["F_x"]], [force(t)]))
    assert [c[1:] for c in calls] == [(True, False, False)] * 5
    assert np.allclose([c[0] for c in calls], 0.1 * np.arange(1, 6), rtol=0, atol=1e-15)
    along = fmi2_run_with_slopes(fmu_paths, force, 3.0)
    assert np.allclose(states, along, rtol=0, atol=1e-13)
    held = fmi2_run_with_slopes(fmu_paths, force, None)
    assert np.max(np.abs(states - held)) > 1e-4  # the slope matters at this force
    # an input not given is held: the FMI 2.0 numbers without slopes, bit for bit
    calls, unanswered = asking_run(fmi3_paths, fmi3_unzipped, force, lambda fmu, t: None)
    assert len(calls) == 5 and np.array_equal(unanswered, held)


def test_the_request_for_inputs_refuses_reads_other_variables_and_lines_that_overflow(fmi3_paths, fmi3_unzipped):
    refs = references(fmi3_paths["SimplePendulum"])
    log, statuses = Log(), []

    def answer(fmu, t):
        values = (ctypes.c_double * 1)()
        for function, name, value in (("fmi3GetFloat64", "phi", None), ("fmi3SetFloat64", "F_y", 1.0),
                                      ("fmi3SetFloat64", "L", 2.0), ("fmi3SetFloat64", "F_x", 1e308)):
            vr = (ctypes.c_uint32 * 1)(refs[name])
            if value is not None:
                values[0] = value
            statuses.append(raw(fmu, function)(vr, ctypes.c_size_t(1), values, ctypes.c_size_t(1)))

    with pytest.raises(Exception, match="fmi3DoStep failed"):
        asking_run(fmi3_paths, fmi3_unzipped, lambda t: -1e308, answer, steps=1, log=log)
    assert statuses == [fmi3Error, fmi3Error, fmi3Error, fmi3OK]
    text = [m for _, m in log.messages]
    assert ("fmi3GetFloat64: the FMU asks for inputs at the step's end (intermediateVariableGetAllowed = false)"
            in text[0])
    assert f"fmi3SetFloat64: F_y (value reference {refs['F_y']}) cannot be set here" in text[1]
    assert "only the inputs registered in requiredIntermediateVariables" in text[1]
    assert f"fmi3SetFloat64: L (value reference {refs['L']}) cannot be set here" in text[2]
    assert text[-1] == ("fmi3DoStep: input F_x goes from -1e+308 at t = 0 to 1e+308 at t = 0.10000000000000001 "
                        "(set in the intermediate update): its slope over the step is not finite")


def test_inputs_cannot_be_set_at_internal_step_reports_and_parameters_not_registered(fmi3_paths, fmi3_unzipped):
    refs = references(fmi3_paths["SimplePendulum"])
    log, statuses, holder = Log(), [], {}

    def intermediate(environment, t, set_requested, *rest):
        if not set_requested:  # a report of an internal step (phi is registered too)
            values = (ctypes.c_double * 1)(1.0)
            statuses.append(raw(holder["fmu"], "fmi3SetFloat64")((ctypes.c_uint32 * 1)(refs["F_x"]),
                                                                 ctypes.c_size_t(1), values, ctypes.c_size_t(1)))

    fmu = slave(fmi3_paths, fmi3_unzipped, "SimplePendulum", log=log, intermediateUpdate=intermediate,
                requiredIntermediateVariables=[refs["phi"], refs["F_x"]])
    holder["fmu"] = fmu
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    fmu.doStep(0.0, 0.05)
    assert statuses and set(statuses) == {fmi3Error}
    assert f"F_x (value reference {refs['F_x']}) cannot be set here" in log.last()
    fmu.freeInstance()
    log = Log()
    with pytest.raises(Exception, match="Failed to instantiate"):
        slave(fmi3_paths, fmi3_unzipped, "SimplePendulum", log=log, intermediateUpdate=intermediate,
              requiredIntermediateVariables=[refs["L"]])
    assert f"requiredIntermediateVariables[0] = {refs['L']} is not a Float64 output or input" in log.last()


def test_state_machine_and_argument_errors_name_what_is_wrong(fmi3_paths, fmi3_unzipped):
    refs = references(fmi3_paths["DoublePendulum"])
    log = Log()
    fmu = slave(fmi3_paths, fmi3_unzipped, "DoublePendulum", log=log)
    done = ctypes.c_bool()
    when = ctypes.c_double()

    def do_step(t: float, H: float) -> int:
        return raw(fmu, "fmi3DoStep")(ctypes.c_double(t), ctypes.c_double(H), ctypes.c_bool(True), ctypes.byref(done),
                                      ctypes.byref(done), ctypes.byref(done), ctypes.byref(when))

    assert do_step(0.0, 0.1) == fmi3Error
    assert "fmi3DoStep: illegal call sequence: not allowed in state Instantiated for Co-Simulation " \
           "(allowed in: Step Mode)" in log.last()

    def call(function, *args):
        return raw(fmu, function)(*(ctypes.c_size_t(a) if isinstance(a, int) and not isinstance(a, bool) else
                                     ctypes.c_double(a) if isinstance(a, float) else
                                     ctypes.c_bool(a) if isinstance(a, bool) else a for a in args))

    vr = (ctypes.c_uint32 * 1)(refs["L1"] if "L1" in refs else refs["l1"])
    value = (ctypes.c_double * 1)(-1.0)
    assert call("fmi3SetFloat64", vr, 1, value, 1) == fmi3Error
    assert "fmi3SetFloat64: variable l1 (value reference" in log.last() and "out of its allowed range" in log.last()
    assert call("fmi3SetFloat64", vr, 1, value, 2) == fmi3Error
    assert "nValues = 2" in log.last()
    time_vr = (ctypes.c_uint32 * 1)(refs["time"])
    assert call("fmi3SetFloat64", time_vr, 1, value, 1) == fmi3Error
    assert "time (value reference" in log.last() and "independent variable" in log.last()
    solver = (ctypes.c_uint32 * 1)(refs["solver"])
    huge = (ctypes.c_int64 * 1)(2**32 + 5)
    assert call("fmi3SetInt64", solver, 1, huge, 1) == fmi3Error
    assert "fmi3SetInt64: variable solver" in log.last() and "4294967301" in log.last()
    for number in (2**53 + 1, 2**63 - 1, -2**63):  # named exactly, not as the nearest double
        assert call("fmi3SetInt64", solver, 1, (ctypes.c_int64 * 1)(number), 1) == fmi3Error
        assert f"= {number} is out of its allowed range" in log.last()
    counter = (ctypes.c_uint32 * 1)(refs["n_rhs"])
    assert call("fmi3SetUInt64", counter, 1, (ctypes.c_uint64 * 1)(), 1) == fmi3Error
    assert "fmi3SetUInt64: variable n_rhs" in log.last() and "only the FMU sets it" in log.last()
    assert call("fmi3EnterConfigurationMode") == fmi3Error
    assert "no structural parameters" in log.last()
    assert call("fmi3GetClock", solver, 1, (ctypes.c_bool * 1)()) == fmi3Error
    assert "no Clock variables" in log.last()

    assert call("fmi3EnterInitializationMode", False, 0.0, 2.0, False, 0.0) == fmi3OK
    assert call("fmi3ExitInitializationMode") == fmi3OK
    values = (ctypes.c_double * 2)()
    pair = (ctypes.c_uint32 * 2)(refs["time"], refs["phi1"])
    assert call("fmi3GetFloat64", pair, 2, values, 2) == fmi3OK
    assert values[0] == 2.0 and values[1] == pytest.approx(np.pi / 2)
    assert call("fmi3GetInt64", counter, 1, (ctypes.c_int64 * 1)(), 1) == fmi3Error
    assert "fmi3GetInt64: variable n_rhs" in log.last() and "use fmi3GetUInt64" in log.last()
    counts = (ctypes.c_uint64 * 1)()
    assert call("fmi3GetUInt64", counter, 1, counts, 1) == fmi3OK
    assert do_step(2.0, 0.5) == fmi3OK and when.value == 2.5
    assert call("fmi3GetUInt64", counter, 1, counts, 1) == fmi3OK and counts[0] > 0
    assert call("fmi3GetFloat64", pair, 2, values, 2) == fmi3OK and values[0] == 2.5
    fmu.freeInstance()


def test_event_mode_and_scheduled_execution_are_refused(fmi3_paths, fmi3_unzipped):
    log = Log()
    with pytest.raises(Exception):
        slave(fmi3_paths, fmi3_unzipped, "SimplePendulum", log=log, eventModeUsed=True)
    assert "eventModeUsed = true" in log.last() and "hasEventMode is false" in log.last()
    log = Log()
    with pytest.raises(Exception):
        slave(fmi3_paths, fmi3_unzipped, "SimplePendulum", log=log, requiredIntermediateVariables=[100000])
    assert "requiredIntermediateVariables[0] = 100000" in log.last()


def test_serialized_state_restores_the_run(fmi3_paths, fmi3_unzipped):
    refs = references(fmi3_paths["DoublePendulum"])
    fmu = slave(fmi3_paths, fmi3_unzipped, "DoublePendulum")
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    fmu.doStep(0.0, 1.0)
    state = fmu.getFMUState()
    serialized = fmu.serializeFMUState(state)
    fmu.freeFMUState(state)
    fmu.doStep(1.0, 1.0)
    first = fmu.getFloat64([refs["phi1"], refs["phi2"]])
    restored = fmu.deserializeFMUState(serialized)
    fmu.setFMUState(restored)
    fmu.freeFMUState(restored)
    fmu.doStep(1.0, 1.0)
    assert fmu.getFloat64([refs["phi1"], refs["phi2"]]) == first
    fmu.terminate()
    fmu.freeInstance()


def test_model_exchange_through_fmi3(fmi3_paths, fmi3_unzipped):
    """The derivatives FMI 3.0 hands out are those of FMI 2.0's Model Exchange, and the counts agree."""
    md = read_model_description(str(fmi3_paths["SpringPendulum"]))
    fmu = FMU3Model(guid=md.instantiationToken, unzipDirectory=fmi3_unzipped["SpringPendulum"],
                    modelIdentifier=md.modelExchange.modelIdentifier, instanceName="me")
    fmu.instantiate(logMessage=Log())
    fmu.enterInitializationMode(startTime=0.0)
    fmu.exitInitializationMode()
    fmu.updateDiscreteStates()
    fmu.enterContinuousTimeMode()
    n = fmu.getNumberOfContinuousStates()
    assert n == len([v for v in md.modelVariables if v.derivative is not None])
    states = (ctypes.c_double * n)()
    assert raw(fmu, "fmi3GetContinuousStates")(states, ctypes.c_size_t(n)) == fmi3OK
    x = np.array(states)
    dx = (ctypes.c_double * n)()
    assert raw(fmu, "fmi3GetContinuousStateDerivatives")(dx, ctypes.c_size_t(n)) == fmi3OK
    refs = {v.name: v.valueReference for v in md.modelVariables}
    derivative_names = [v.name for v in md.modelVariables if v.derivative is not None]
    assert list(dx) == fmu.getFloat64([refs[d] for d in derivative_names])
    assert np.array_equal(x, fmu.getFloat64([v.valueReference for v in md.modelVariables
                                             if v.valueReference in {s.derivative.valueReference
                                                                     for s in md.modelVariables if s.derivative}]))
    fmu.terminate()
    fmu.freeInstance()


@pytest.mark.parametrize("name", ["DoublePendulum", "Spring"])
def test_only_the_fmi3_functions_are_exported(fmi3_unzipped, name):
    library = Path(fmi3_unzipped[name]) / "binaries" / "x86_64-linux" / f"{name}.so"
    symbols = subprocess.run(["nm", "-D", "--defined-only", str(library)], capture_output=True, text=True,
                             check=True).stdout.split()
    exported = {s for s in symbols if s[:1].isalpha() and len(s) > 2}
    # every function of the standard (also those answered with an error), read from its own header
    header = (Path(fmpy.__file__).parent / "c-code" / "fmi3FunctionTypes.h").read_text()
    standard = set(re.findall(r"\b(fmi3\w+)TYPE\b", header))
    assert len(standard) == 75
    assert exported == standard


def test_the_layer_compiles_against_the_standard_headers():
    headers = Path(fmpy.__file__).parent / "c-code"
    generated = PROJECT_ROOT / "build" / "generated" / "SimplePendulum"
    subprocess.run(["gcc", "-std=c99", "-fsyntax-only", "-Werror=incompatible-pointer-types", "-Werror",
                    "-Wall", "-Wno-unused-parameter", "-DUSE_STANDARD_FMI3_HEADERS", f"-I{headers}", f"-I{generated}",
                    f"-I{PROJECT_ROOT / 'fmus' / 'framework'}",
                    str(PROJECT_ROOT / "fmus" / "framework" / "fmi3_functions.c")], check=True)


@pytest.mark.compatibility(importer="fmpy's source build (the macOS route)", version="3.0", interface="CS",
                           platform="x86_64 Linux, built from sources/", criterion="the shipped binary, within 1e-12")
@pytest.mark.parametrize("name", ["DoublePendulum", "Spring"])
def test_fmpy_builds_the_binary_from_the_sources(fmi3_paths, fmi3_unzipped, tmp_path, compatibility, name):
    """fmpy's source build reads buildDescription.xml: the binary it makes gives the same numbers."""
    copy = rebuilt_with_fmpy(fmi3_unzipped[name], tmp_path)
    assert (copy / "binaries" / "x86_64-linux" / f"{name}.so").is_file()
    rebuilt = fmpy.simulate_fmu(str(copy), stop_time=2.0, output_interval=0.1)
    original = fmpy.simulate_fmu(str(fmi3_paths[name]), stop_time=2.0, output_interval=0.1)
    worst = 0.0
    for column in original.dtype.names:
        assert np.allclose(rebuilt[column], original[column], rtol=1e-12, atol=1e-12), column
        worst = max(worst, float(np.max(np.abs(rebuilt[column] - original[column])
                                        / np.maximum(1.0, np.abs(original[column])))))
    compatibility.agrees(name, worst)
