"""FMI behaviour of the FMUs: Co-Simulation and Model Exchange, time keeping, FMU state, failure,
bad input, input and output derivatives."""
from __future__ import annotations

import ctypes
import ctypes.util
import math
import platform
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from fmpy import simulate_fmu
from scipy.integrate import solve_ivp

from harness.fmi.fmu_instance import DISCARD, ERROR, OK
from harness.fmi.methods import ADAPTIVE, SOLVERS
from harness.fmi.simulation import simulate
from harness.objects.thesis.equations import OUTER_MASS, STATES

PENDULUMS = ("SimplePendulum", "DoublePendulum", "SpringPendulum")


# ---------------------------------------------------------------- CS and ME

@pytest.mark.parametrize("name", PENDULUMS)
def test_co_simulation_agrees_with_model_exchange_under_cvode(fmu_paths, name):
    stop = 1.5  # the double pendulum is chaotic: compare over a short time only
    cs = simulate_fmu(str(fmu_paths[name]), stop_time=stop, output_interval=0.01,
                      start_values={"solver": 7, "h": 0.002})
    me = simulate_fmu(str(fmu_paths[name]), fmi_type="ModelExchange", stop_time=stop, output_interval=0.01,
                      relative_tolerance=1e-10)
    x, y = OUTER_MASS[name]
    assert np.max(np.hypot(cs[x] - np.interp(cs["time"], me["time"], me[x]),
                           cs[y] - np.interp(cs["time"], me["time"], me[y]))) < 1e-6
    assert me["n_rhs"][-1] > len(me)  # in ME the FMU counts CVode's evaluations: at least one per output point


def test_spring_simulates_in_both_interfaces(fmu_paths):
    start = {"a_vx": -0.25, "b_vy": 0.5, "c": 1.0}
    cs = simulate_fmu(str(fmu_paths["Spring"]), stop_time=1.0, output_interval=0.1, start_values=start)
    me = simulate_fmu(str(fmu_paths["Spring"]), fmi_type="ModelExchange", stop_time=1.0, output_interval=0.1,
                      start_values=start)
    # The inputs are held in both; in CS the positions move with the velocity inputs over each step.
    assert me["Fa_x"][-1] == pytest.approx(me["Fa_x"][0])
    r = np.hypot(1.0 + 0.25 * 1.0, 0.5 * 1.0)
    assert cs["E_pot"][-1] == pytest.approx(0.5 * 10 * (r - 1.0) ** 2, rel=1e-12)


# ---------------------------------------------------------------- time

def test_time_lands_exactly_on_the_masters_grid(open_fmu):
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="rk4", h=0.003)
    t = 0.0
    for i in range(100):
        H = 0.1 / 3 if i % 2 else 0.07
        assert fmu.do_step(t, H) == OK
        t = t + H
        assert fmu.last_successful_time() == t  # bit for bit the master's t + H
    # The communication point may deviate from the FMU's time by 1e-9 max(1, |t|), no more.
    assert fmu.do_step(t + 0.5e-9 * max(1.0, t), 0.01) == OK
    assert fmu.do_step(t + 0.01 + 1e-8, 0.01) == ERROR
    assert "currentCommunicationPoint" in fmu.last_message()


def test_substeps_are_equal_and_counted(open_fmu):
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="rk4", h=0.008)
    assert fmu.do_step(0.0, 0.1) == OK  # ceil(0.1 / 0.008) = 13 substeps of 0.1/13
    assert fmu.get("n_steps", "n_rhs") == [13, 52]
    assert fmu.do_step(0.1, 0.008 * 3) == OK  # exactly 3 substeps, not 4
    assert fmu.get("n_steps")[0] == 16


@pytest.mark.parametrize("solver,per_step", [("euler", 1), ("midpoint", 2), ("heun", 2), ("rk3", 3), ("rk4", 4),
                                             ("nystrom5", 6), ("ab3", 1), ("ab6", 1), ("abm3", 2), ("abm6", 2)])
def test_right_hand_side_evaluations_per_step(open_fmu, solver, per_step):
    fmu = open_fmu("DoublePendulum")
    fmu.initialize(solver=solver, h=0.01)
    assert fmu.do_step(0.0, 1.0) == OK
    n_rhs, n_steps = fmu.get("n_rhs", "n_steps")
    # Runge-Kutta start steps cost their extra stages (over the predictor-corrector's two evaluations)
    start_extra = {"ab3": 2 * 3, "ab6": 5 * 5, "abm3": 2 * 2, "abm6": 5 * 4}.get(solver, 0)
    assert n_steps == 100 and n_rhs == per_step * 100 + start_extra


# ---------------------------------------------------------------- FMU state

def run_steps(fmu, t0: float, count: int, H: float = 0.05) -> list[float]:
    for i in range(count):
        assert fmu.do_step(t0 + i * H, H) == OK
    return fmu.get(*STATES[fmu.path.stem], "n_rhs", "n_steps")


@pytest.mark.parametrize("name", PENDULUMS)
@pytest.mark.parametrize("solver", ["rk4", "ab4", "rkf45", "abm5"])
def test_fmu_state_round_trip_continues_bit_identically(open_fmu, name, solver):
    reference = open_fmu(name)
    reference.initialize(solver=solver, h=0.01, tol=1e-7)
    run_steps(reference, 0.0, 20)
    state = reference.get_state()
    data = reference.serialize(state)
    expected = run_steps(reference, 1.0, 20)

    # the same instance, rolled back
    reference.set_state(state)
    assert run_steps(reference, 1.0, 20) == expected
    # a fresh instance, from the serialized bytes
    other = open_fmu(name)
    other.initialize()
    other.set_state(other.deserialize(data))
    assert run_steps(other, 1.0, 20) == expected


@pytest.mark.parametrize("name", ["SimplePendulum", "DoublePendulum", "KapitzaPendulum"])
@pytest.mark.parametrize("solver", ["rk4", "ab5", "abm4", "gbs"])
def test_a_call_that_starts_from_the_last_calls_end_evaluation_matches_a_fresh_start(open_fmu, name, solver):
    """With one substep per call, a call takes the derivatives its predecessor's end check computed as its first
    evaluation. A run in which every call starts from a restored FMU state (which evaluates afresh) must match it
    bit for bit and count the same n_rhs, also across a force input switched on and off between calls and a
    communication point off the FMU's time by the allowed 1e-9 (the Kapitza pendulum's right-hand side depends on
    the time)."""
    h = 0.01
    runs = []
    for restoring in (False, True):
        fmu = open_fmu(name)
        fmu.initialize(solver=solver, h=h, tol=0.0)
        t, trajectory = 0.0, []
        for k in range(40):
            if k in (12, 24):
                assert fmu.set(F_x=0.3 if k == 12 else 0.0) == OK
            if restoring:
                state = fmu.get_state()
                fmu.set_state(state)
                fmu.free_state(state)
            start = t + 0.5e-9 if k == 30 else t
            assert fmu.do_step(start, h) == OK
            t = fmu.last_successful_time()
            trajectory.append(fmu.get(*STATES.get(name, ("phi", "omega"))))
        runs.append((np.array(trajectory).tobytes(), fmu.get("n_rhs", "n_steps")))  # bits: -0.0 differs from 0.0
    assert runs[0][1][1] == 40  # one substep per call
    assert runs[0] == runs[1]


def test_a_held_input_keeps_its_bits_and_the_next_call_starts_from_them(open_fmu):
    """An input set to -0.0 stays -0.0 through steps (no u + 0 H, which is +0.0), so the derivatives one call
    leaves are those the next call computes afresh, to the sign of a zero (on a start where every term is a zero)."""
    runs = []
    for restoring in (False, True):
        fmu = open_fmu("SimplePendulum")
        fmu.initialize(solver="euler", h=0.01, tol=0.0, phi=-0.0, omega=-0.0, g=-0.0, d=-0.0)
        assert fmu.set(F_x=-0.0, F2_x=-0.0, F_y=1.0, F2_y=-1.0) == OK
        trajectory = []
        for k in range(3):
            if restoring:
                state = fmu.get_state()
                fmu.set_state(state)
                fmu.free_state(state)
            assert fmu.do_step(0.01 * k, 0.01) == OK
            trajectory.append(fmu.get("phi", "omega", "F_x", "F2_x"))
        runs.append(np.array(trajectory).tobytes())
        assert math.copysign(1.0, fmu.get("F_x")[0]) == -1.0
    assert runs[0] == runs[1]


@pytest.mark.skipif(sys.platform != "linux" or platform.machine() != "x86_64", reason="FE_UPWARD's value is x86's")
def test_a_call_in_another_rounding_mode_evaluates_afresh(open_fmu):
    """An importer that changes the rounding mode between two calls gets the second call computed in its mode
    throughout: the derivatives the first call left (computed rounding to nearest) are not reused (nor any in a
    mode other than to nearest, where the compiler's rewrites may round two evaluations of f apart)."""
    libm = ctypes.CDLL(ctypes.util.find_library("m"))
    upward = 0x800  # FE_UPWARD on x86
    runs = []
    for restoring in (False, True):
        fmu = open_fmu("DoublePendulum")
        fmu.initialize(solver="euler", h=0.01, tol=0.0)
        assert fmu.do_step(0.0, 0.03) == OK
        if restoring:
            state = fmu.get_state()
            fmu.set_state(state)
            fmu.free_state(state)
        nearest = libm.fegetround()
        assert libm.fesetround(upward) == 0
        try:
            status = fmu.do_step(0.03, 0.03)
        finally:
            libm.fesetround(nearest)
        assert status == OK
        runs.append(np.array(fmu.get("phi1", "phi2", "omega1", "omega2")).tobytes())
    assert runs[0] == runs[1]


@pytest.mark.parametrize("solver, settings", [("abm6", {"h": 0.01}), ("gbs", {"tol": 1e-9})])
def test_a_parameter_set_to_the_value_it_holds_keeps_the_integrators_memory(open_fmu, solver, settings):
    """An importer that sets every tunable parameter before each step, to the values they hold, gets the run
    without the sets, bit for bit and at the same work (the Adams history and gbs's proposals kept); a real
    change between two steps (h or tol and back) restarts the integrator and costs more."""
    runs = {}
    for mode in ("plain", "same", "changed"):
        fmu = open_fmu("DoublePendulum")
        fmu.initialize(solver=solver, **settings)
        t = 0.0
        for k in range(40):
            if mode == "same":
                assert fmu.set(solver=solver, **settings) == OK
            elif mode == "changed" and k == 20:
                name, value = next(iter(settings.items()))
                assert fmu.set(**{name: value * 2}) == OK and fmu.set(**{name: value}) == OK
            assert fmu.do_step(t, 0.05) == OK
            t += 0.05
        runs[mode] = (fmu.get("phi1", "omega1", "phi2", "omega2"), fmu.work())
    assert runs["same"] == runs["plain"]
    assert runs["changed"][1] > runs["plain"][1]


def test_serialized_state_restores_in_another_process(fmu_paths, unzipped, open_fmu, tmp_path):
    fmu = open_fmu("DoublePendulum")
    fmu.initialize(solver="ab4", h=0.01)
    run_steps(fmu, 0.0, 10)
    (tmp_path / "state.bin").write_bytes(fmu.serialize(fmu.get_state()))
    expected = run_steps(fmu, 0.5, 10)
    script = textwrap.dedent(f"""
        import sys
        from harness.fmi.fmu_instance import FmuInstance
        fmu = FmuInstance({str(fmu_paths['DoublePendulum'])!r}, unzipdir={str(unzipped['DoublePendulum'])!r})
        fmu.initialize()
        fmu.set_state(fmu.deserialize(open({str(tmp_path / 'state.bin')!r}, 'rb').read()))
        for i in range(10):
            assert fmu.do_step(0.5 + i * 0.05, 0.05) == 0
        print(repr(fmu.get('phi1', 'phi2', 'omega1', 'omega2', 'n_rhs', 'n_steps')))
    """)
    output = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    assert eval(output) == expected


def test_corrupt_or_foreign_state_is_rejected(open_fmu):
    simple, double = open_fmu("SimplePendulum"), open_fmu("DoublePendulum")
    simple.initialize()
    double.initialize()
    data = bytearray(simple.serialize(simple.get_state()))
    data[100] ^= 0x10
    size = len(data)
    with pytest.raises(Exception):
        simple.deserialize(bytes(data))
    assert "corrupt" in simple.last_message()
    with pytest.raises(Exception):
        simple.deserialize(bytes(data[:size - 8]))
    assert "size" in simple.last_message()
    foreign = double.get_state()
    assert simple.call("fmi2SetFMUstate", foreign) == ERROR
    assert "another FMU" in simple.last_message() or "not made by this FMU" in simple.last_message()
    assert simple.do_step(0.0, 0.1) == OK  # the instance is unharmed


def _fnv1a64(data: bytes) -> int:
    value = 1469598103934665603
    for byte in data:
        value = ((value ^ byte) * 1099511628211) % 2 ** 64
    return value


def _forged(serialized: bytes, vr: int, value: float) -> bytes:
    """A serialized state with one Real variable replaced and a valid checksum (the layout: 64 header
    bytes, then time, last successful time and the Real variables by value reference)."""
    import struct
    data = bytearray(serialized)
    struct.pack_into("<d", data, 64 + 16 + 8 * vr, value)
    struct.pack_into("<Q", data, len(data) - 8, _fnv1a64(bytes(data[:-8])))
    return bytes(data)


@pytest.mark.parametrize("name,value,words", [("L", -1.0, "[1e-09, inf]"), ("m", 0.0, "[1e-09, inf]"),
                                              ("h", -1.0, "[1e-09, inf]"), ("phi", math.inf, "not a finite number"),
                                              ("F_x", math.nan, "not a finite number")])
def test_a_restored_state_passes_the_setters_checks(open_fmu, name, value, words):
    """A state with a valid checksum whose values break the variables' ranges is refused, by
    fmi2DeSerializeFMUstate with the variable, its value and its range; the instance steps on unharmed."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize()
    serialized = fmu.serialize(fmu.get_state())
    assert fmu.deserialize(_forged(serialized, fmu.reference("g"), 9.81)) is not None  # the forgery itself is sound
    with pytest.raises(Exception):
        fmu.deserialize(_forged(serialized, fmu.reference(name), value))
    message = fmu.last_message()
    assert message.startswith("fmi2DeSerializeFMUstate") and f"variable {name}" in message and words in message
    assert fmu.do_step(0.0, 0.1) == OK


def test_the_time_must_advance(open_fmu):
    """At t = 1e9 a step of 1e-8 s is below the time's resolution: refused, not a state moving while the time
    stays."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(start_time=1e9)
    assert fmu.do_step(1e9, 1e-8) == ERROR
    assert "does not advance the time" in fmu.last_message()
    assert fmu.do_step(1e9, 1e-3) == OK


def test_parameters_and_inputs_read_fine_where_the_outputs_are_undefined(open_fmu):
    """After a discard (the spring pendulum's mass through its anchor) the parameters, inputs and states
    still read with fmi2OK; the outputs say fmi2Discard."""
    fmu = open_fmu("SpringPendulum")
    fmu.initialize(solver="rk4", h=0.001, phi=0.0, eps=-0.5, v_eps=-3.0, g=0.0, D=1e-6)
    assert fmu.do_step(0.0, 1.0) == DISCARD
    import ctypes
    values = (ctypes.c_double * 3)()
    read = fmu.call("fmi2GetReal", (ctypes.c_uint * 3)(*[fmu.reference(n) for n in ("m", "F_x", "eps")]), 3, values)
    assert read == OK and values[0] > 0


def test_non_finite_output_derivatives_are_a_discard(open_fmu):
    """The Spring with its ends almost together and a large velocity: its force's rate is 0 times infinity;
    the call says so instead of handing out NaN."""
    import ctypes
    fmu = open_fmu("Spring")
    fmu.initialize(l0=0.0, b_x=1e-300, b_vy=1e300)
    out = (ctypes.c_double * 1)(12345.0)
    status = fmu.call("fmi2GetRealOutputDerivatives", (ctypes.c_uint * 1)(fmu.reference("Fa_x")), 1,
                      (ctypes.c_int * 1)(1), out)
    assert status == DISCARD and out[0] == 12345.0
    assert "derivative of Fa_x" in fmu.last_message() and "not finite" in fmu.last_message()


# ---------------------------------------------------------------- failure

@pytest.mark.parametrize("name,values,method", [
    ("DoublePendulum", {"solver": "euler", "h": 0.3}, "euler"),
    ("SpringPendulum", {"solver": "rk4", "h": 0.2, "D": 5000.0}, "rk4"),
    ("SpringPendulum", {"solver": "ab6", "h": 0.3, "D": 100.0}, "ab6"),
])
def test_blow_up_gives_discard_with_last_good_state(open_fmu, name, values, method):
    fmu = open_fmu(name)
    fmu.initialize(**values)
    t, H, status = 0.0, 1.0, OK
    while status == OK and t < 1e4:
        status = fmu.do_step(t, H)
        t += H
    assert status == DISCARD
    last = fmu.last_successful_time()
    assert t - H <= last < t
    outputs = fmu.get(*STATES[name], *OUTER_MASS[name], "E")
    assert all(math.isfinite(v) for v in outputs)
    message = fmu.last_message()
    assert method in message and f"h = {values['h']:g}" in message and "last successful time" in message
    # Stepping on is illegal after a discard; restoring a state makes the instance usable again.
    assert fmu.do_step(last, 0.1) == ERROR and "illegal call sequence" in fmu.last_message()


def test_singular_spring_pendulum_discards(open_fmu):
    """The mass driven through the anchor (r = l0 + eps <= 0) stops at the last substep before."""
    fmu = open_fmu("SpringPendulum")
    fmu.initialize(solver="rk4", h=0.001, phi=0.0, eps=-0.5, v_eps=-3.0, g=0.0, D=1e-6)
    assert fmu.do_step(0.0, 1.0) == DISCARD
    last = fmu.last_successful_time()
    eps, = fmu.get("eps")
    assert 0.1 < last < 0.2 and -1.0 < eps < -0.99  # hits r = 0 at t = 1/6
    assert fmu.get_state() is not None


@pytest.mark.parametrize("solver", ["euler", "midpoint", "taylor", "gbs", "rkf45"])
def test_an_input_overflowing_along_its_slope_fails_the_step(open_fmu, solver):
    """F_x = 1.7e308 with slope 1e308 overflows at t = 0.0977: a step past that ends in a discard, also for
    the methods that never evaluate the right-hand side at a step's end, and no input or output read
    afterwards is infinite."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver=solver, tol=1e-8, h=1e6, phi=0.5, m=1e307)
    fmu.set(F_x=1.7e308)
    fmu.set_input_derivatives(F_x=1e308)
    assert fmu.do_step(0.0, 0.0977) == DISCARD
    assert fmu.last_successful_time() < 0.0976931348623158
    values = fmu.get("F_x", "phi", "omega")
    assert all(math.isfinite(v) for v in values), values


@pytest.mark.parametrize("solver", ADAPTIVE)
def test_a_huge_communication_step_ends_at_the_work_bound(open_fmu, solver):
    """The floor below which a step counts as underflowed follows the current time, not the end of the
    communication step: one call of 1e12 s on the chaotic double pendulum ends at the work bound, not in
    a false underflow near its start."""
    fmu = open_fmu("DoublePendulum")
    fmu.initialize(solver=solver, tol=1e-6)
    assert fmu.do_step(0.0, 1e12) == DISCARD
    assert "right-hand-side evaluations allowed per call" in fmu.last_message()
    assert fmu.last_successful_time() > 100.0


@pytest.mark.parametrize("solver", ADAPTIVE)
def test_an_adaptive_discard_reports_the_tolerance(open_fmu, solver):
    """Thrown at its pivot, the spring pendulum reaches r = 0 at t = 1/6: the step size underflows just
    before it, and the message names the method and its tol."""
    fmu = open_fmu("SpringPendulum")
    fmu.initialize(solver=solver, phi=0.0, eps=-0.5, v_eps=-3.0, g=0.0, D=1e-6)
    assert fmu.do_step(0.0, 1.0) == DISCARD
    assert f"{solver} with tol = 1e-06" in fmu.last_message() and 0.16 < fmu.last_successful_time() < 1 / 6 + 1e-6
    assert np.all(np.isfinite(fmu.get("phi", "eps", "omega", "v_eps")))


# ---------------------------------------------------------------- bad input

@pytest.mark.parametrize("name,values,words", [
    ("SimplePendulum", {"L": -1.0}, ["fmi2SetReal", "L", "-1", "[1e-09, inf]"]),
    ("SimplePendulum", {"L": float("nan")}, ["fmi2SetReal", "L", "nan", "not a finite number"]),
    ("SimplePendulum", {"m": 0.0}, ["fmi2SetReal", "m", "= 0", "[1e-09, inf]"]),
    ("SimplePendulum", {"h": float("inf")}, ["fmi2SetReal", "h", "inf"]),
    ("SimplePendulum", {"d": -0.1}, ["fmi2SetReal", "d", "-0.1", "[0, inf]"]),
    ("SimplePendulum", {"solver": len(SOLVERS) + 1}, ["fmi2SetInteger", "solver", str(len(SOLVERS) + 1),
                                                      f"[1, {len(SOLVERS)}]"]),
    ("DoublePendulum", {"solver": 15}, ["fmi2SetInteger", "solver", "15 (stormer_verlet)", "mass matrix"]),
    ("SimplePendulum", {"tol": -1e-3}, ["fmi2SetReal", "tol", "[0, 1]"]),
    ("SimplePendulum", {"taylor_order": 31}, ["fmi2SetInteger", "taylor_order", "31", "[2, 30]"]),
    ("DoublePendulum", {"J1": -0.01}, ["fmi2SetReal", "J1", "-0.01", "[0, inf]"]),
    ("DoublePendulum", {"l1": 0.0}, ["fmi2SetReal", "l1", "[1e-09, inf]"]),
    ("SpringPendulum", {"D": -15.0}, ["fmi2SetReal", "D", "-15"]),
    ("Spring", {"k": 0.0}, ["fmi2SetReal", "k", "[1e-09, inf]"]),
    ("Spring", {"l0": -1.0}, ["fmi2SetReal", "l0", "[0, inf]"]),
    ("Spring", {"a_x": float("inf")}, ["fmi2SetReal", "a_x", "inf"]),
    ("Contact", {"k": -1.0}, ["fmi2SetReal", "k", "-1", "[1e-09, inf]"]),
    ("Contact", {"exponent": 0.5}, ["fmi2SetReal", "exponent", "0.5", "[1, 10]"]),
    ("Contact", {"c": -0.2}, ["fmi2SetReal", "c", "-0.2", "[0, inf]"]),
    ("Contact", {"R_b": -0.02}, ["fmi2SetReal", "R_b", "-0.02", "[0, inf]"]),
    ("Contact", {"b_vz": float("nan")}, ["fmi2SetReal", "b_vz", "nan", "not a finite number"]),
])
def test_bad_values_give_error_and_message_and_change_nothing(open_fmu, name, values, words):
    fmu = open_fmu(name)
    assert fmu.set(**values) == ERROR
    message = fmu.last_message()
    assert all(w in message for w in words), message
    fmu.initialize()  # the defaults are intact: initialization and a step still work
    assert fmu.do_step(0.0, 0.1) == OK


def test_unknown_value_references(open_fmu):
    fmu = open_fmu("SimplePendulum")
    fmu.initialize()
    out = (ctypes.c_double * 1)()
    assert fmu.call("fmi2GetReal", (ctypes.c_uint * 1)(999), 1, out) == ERROR
    assert "unknown value reference 999" in fmu.last_message()
    assert fmu.call("fmi2SetBoolean", (ctypes.c_uint * 1)(0), 1, (ctypes.c_int * 1)(1)) == ERROR
    assert "no Boolean variables" in fmu.last_message()
    assert fmu.call("fmi2GetReal", None, 1, out) == ERROR and "NULL" in fmu.last_message()


def test_calls_out_of_order_and_fixed_parameters_after_initialization(open_fmu):
    fmu = open_fmu("SimplePendulum")
    assert fmu.do_step(0.0, 0.1) == ERROR
    assert "fmi2DoStep: illegal call sequence" in fmu.last_message() and "instantiated" in fmu.last_message()
    fmu.initialize()
    assert fmu.set(L=2.0) == ERROR
    assert "fixed parameter" in fmu.last_message() and "stepComplete" in fmu.last_message()
    assert fmu.set(x=1.0) == ERROR and "calculated output" in fmu.last_message()
    assert fmu.set(solver="ab4", h=0.01) == OK  # tunable
    assert fmu.do_step(0.0, 0.0) == ERROR and "communicationStepSize = 0" in fmu.last_message()
    assert fmu.do_step(0.0, -1.0) == ERROR
    assert fmu.call("fmi2ExitInitializationMode") == ERROR
    assert fmu.do_step(0.0, 0.1) == OK


def test_inconsistent_parameters_are_refused_at_initialization(open_fmu):
    """Link 2 without mass moment about its pivot (J2 + m2 s2^2 = 0): the mass matrix is singular."""
    fmu = open_fmu("DoublePendulum")
    assert fmu.set(J2=0.0, s2=0.0) == OK
    fmu.fmu.setupExperiment(startTime=0.0)
    assert fmu.call("fmi2EnterInitializationMode") == OK
    assert fmu.call("fmi2ExitInitializationMode") == ERROR
    assert "mass matrix d2T/dv2 is not positive definite here (pivot 2" in fmu.last_message()


def test_a_massless_first_link_is_regular(open_fmu):
    """J1 + m1 s1^2 = 0 leaves M positive definite (det = m2 l1^2 (J2 + m2 s2^2 sin^2(phi1 - phi2)) > 0)."""
    fmu = open_fmu("DoublePendulum")
    fmu.initialize(J1=0.0, s1=0.0)
    assert fmu.do_step(0.0, 0.5) == OK


@pytest.mark.parametrize("name, start, shown", [
    ("SimplePendulum", {"m": 1e300, "omega": 1e200}, "phi = 0.5, omega = 1e+200"),  # E_kin = m L^2 omega^2 / 2
    ("CartPendulum", {"v": 1e200}, "v = 1e+200")])
def test_start_values_with_non_finite_outputs_are_refused(open_fmu, name, start, shown):
    """Finite states whose kinetic energy overflows: refused at initialization, not NaN later; the message
    names the states and the first value that is not finite."""
    fmu = open_fmu(name)
    assert fmu.set(**start) == OK
    assert fmu.call("fmi2EnterInitializationMode") == OK
    assert fmu.call("fmi2ExitInitializationMode") == ERROR
    message = fmu.last_message()
    assert "fmi2ExitInitializationMode" in message and shown in message and "make E_kin not finite" in message


WORK_BOUND = 10_000_000  # right-hand-side evaluations per fmi2DoStep, as the model description says


@pytest.mark.parametrize("solver", ["euler", "rk4", "nystrom5", "ab6"])
def test_a_fixed_step_call_past_the_work_bound_is_refused_at_once(open_fmu, solver):
    """A step whose substeps alone need one evaluation past the bound is refused before any work (the
    counter does not move, the message gives the work with the state checks); one at 98 % of the
    bound is taken."""
    stages = {"euler": 1, "rk4": 4, "nystrom5": 6, "ab6": 1}[solver]
    fmu = open_fmu("SimplePendulum")
    substeps = WORK_BOUND // stages
    fmu.initialize(solver=solver, h=1e-3)
    assert fmu.do_step(0.0, 1e-3 * (substeps + 1)) == ERROR
    message = fmu.last_message()
    needed = float(re.search(r"needs (\S+) right-hand-side evaluations, its state checks included", message).group(1))
    assert stages * (substeps + 1) <= needed <= 1.02 * stages * (substeps + 1)
    assert "allowed at most 10000000 per call" in message and solver in message
    assert fmu.get("n_rhs")[0] == 0
    h = next(v for v in fmu.model_description.modelVariables if v.name == "h")
    assert "at most 1e7 times" in h.description
    assert fmu.do_step(0.0, 1e-3 * int(0.98 * substeps)) == OK
    assert 0.97 * WORK_BOUND <= fmu.get("n_rhs")[0] <= WORK_BOUND


def test_a_failing_step_stays_within_the_work_bound(open_fmu):
    """A step that fails near its end is redone from its last good block only: the evaluations it
    makes, and one state check per block of 256 substeps, stay within the bound."""
    fmu = open_fmu("SpringPendulum")
    h, H = 4.6e-8, 0.452
    fmu.initialize(solver="euler", h=h, phi=math.pi, D=1e-9)
    assert fmu.do_step(0.0, H) == DISCARD
    reached = fmu.last_successful_time()
    assert 0.9 * H < reached < H
    substeps = math.ceil(H / h)
    assert fmu.get("n_rhs")[0] + math.ceil(substeps / 64) <= WORK_BOUND


def test_rkf45_stops_at_the_work_bound_with_a_discard(open_fmu):
    """A long step at the tightest tolerance: fmi2Discard after at most the bound's evaluations, at a
    last successful time that the state and the status report agree on; the master can go on from there."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="rkf45", tol=1e-14)
    assert fmu.do_step(0.0, 1e7) == DISCARD
    assert "used its 10000000 right-hand-side evaluations allowed per call" in fmu.last_message()
    n_rhs = fmu.get("n_rhs")[0]
    assert WORK_BOUND - 7 <= n_rhs <= WORK_BOUND
    reached = fmu.last_successful_time()
    assert 0.0 < reached < 1e7
    phi, omega = fmu.get("phi", "omega")
    assert math.isfinite(phi) and math.isfinite(omega)


def test_wrong_guid_and_type_at_instantiation(fmu_paths, unzipped):
    from fmpy.fmi2 import FMU2Slave
    from harness.fmi.fmu_instance import LogCollector
    log = LogCollector()
    slave = FMU2Slave(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=unzipped["SimplePendulum"],
                      modelIdentifier="SimplePendulum", instanceName="wrong")
    with pytest.raises(Exception):
        slave.instantiate(callbacks=log.callbacks)
    assert "does not match this FMU" in log.messages[-1].text
    slave.freeLibrary()


# ---------------------------------------------------------------- input and output derivatives

def test_input_derivative_ramps_the_force_over_one_step(open_fmu):
    """F_x = 0 with slope 2 N/s over one 1 s step equals the reference with F_x(t) = 2 t."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="rk4", h=0.001)
    assert fmu.set_input_derivatives(F_x=2.0) == OK
    assert fmu.do_step(0.0, 1.0) == OK
    phi, omega, F_x = fmu.get("phi", "omega", "F_x")

    def rhs(t, y):
        return [y[1], -9.81 * np.sin(y[0]) + 2.0 * t * np.cos(y[0])]

    ref = solve_ivp(rhs, (0, 1), [0.5, 0.0], rtol=1e-12, atol=1e-12, method="DOP853").y[:, -1]
    assert abs(phi - ref[0]) < 1e-9 and abs(omega - ref[1]) < 1e-9
    assert F_x == pytest.approx(2.0)  # the input is at its value for the FMU's current time
    # The slope held for that step only.
    assert fmu.do_step(1.0, 0.5) == OK and fmu.get("F_x")[0] == pytest.approx(2.0)


@pytest.mark.parametrize("name", PENDULUMS)
def test_output_derivatives_are_exact(open_fmu, name):
    """Against a third-order finite difference of the outputs along the trajectory (a second-order one is
    too coarse at this step for the link tensions, which hold the accelerations)."""
    fmu = open_fmu(name)
    fmu.initialize(solver="nystrom5", h=1e-4, F_x=0.7, F_y=-0.4, d=0.3)
    assert fmu.do_step(0.0, 0.3) == OK
    outputs = [v.name for v in fmu.model_description.modelVariables
               if v.causality == "output" and v.type == "Real"]
    rates = fmu.output_derivatives(*outputs)
    delta = 1e-4
    samples = [np.array(fmu.get(*outputs))]
    for i in range(3):
        assert fmu.do_step(0.3 + i * delta, delta) == OK
        samples.append(np.array(fmu.get(*outputs)))
    finite_difference = (-11 * samples[0] + 18 * samples[1] - 9 * samples[2] + 2 * samples[3]) / (6 * delta)
    scale = 1 + np.abs(rates)
    assert np.all(np.abs(rates - finite_difference) < 1e-6 * scale), dict(zip(outputs, rates - finite_difference))


def test_spring_outputs_belong_to_the_end_of_the_step(open_fmu):
    fmu = open_fmu("Spring")
    fmu.initialize(k=10.0, c=2.0, l0=1.0, a_x=0.0, b_x=1.0, b_vx=0.5)
    assert fmu.set_input_derivatives(b_vx=1.0) == OK
    assert fmu.do_step(0.0, 1.0) == OK
    # b_x = 1 + 0.5 + 1/2 = 2, relative velocity 0.5 + 1 = 1.5
    Fa_x, Fb_x, E = fmu.get("Fa_x", "Fb_x", "E_pot")
    assert Fa_x == pytest.approx(10 * 1.0 + 2 * 1.5) and Fb_x == pytest.approx(-Fa_x)
    assert E == pytest.approx(5.0)
    # Setting the inputs after the step does not change the outputs until the next step.
    assert fmu.set(b_x=5.0) == OK and fmu.get("Fa_x")[0] == pytest.approx(Fa_x)


def test_spring_output_derivatives_follow_the_slopes_of_the_step(open_fmu):
    """At a step's end the force's rate follows the inputs as they moved over the step, velocities with
    their slopes (the damping term's rate needs the ends' accelerations): checked against the force
    written out along the extrapolated inputs and differentiated by central differences. The slopes
    drive no further step."""
    k, c, l0, H = 10.0, 2.0, 1.0, 0.5
    start = dict(a_x=0.0, a_y=0.0, b_x=1.2, b_y=0.3, a_vx=0.1, a_vy=-0.2, b_vx=0.5, b_vy=0.4)
    slopes = dict(a_vx=0.7, a_vy=-1.1, b_vx=1.0, b_vy=0.3)
    fmu = open_fmu("Spring")
    fmu.initialize(k=k, c=c, l0=l0, **start)
    assert fmu.set_input_derivatives(**slopes) == OK
    assert fmu.do_step(0.0, H) == OK

    def end(name: str, t: float) -> tuple[float, float]:  # a point's position and velocity at time t
        x, y = start[f"{name}_x"], start[f"{name}_y"]
        vx, vy, ax, ay = start[f"{name}_vx"], start[f"{name}_vy"], slopes[f"{name}_vx"], slopes[f"{name}_vy"]
        return (np.array([x + vx * t + ax * t * t / 2, y + vy * t + ay * t * t / 2]),
                np.array([vx + ax * t, vy + ay * t]))

    def force_on_a(t: float) -> np.ndarray:
        (pa, va), (pb, vb) = end("a", t), end("b", t)
        r = np.linalg.norm(pb - pa)
        e = (pb - pa) / r
        return (k * (r - l0) + c * np.dot(vb - va, e)) * e

    delta = 1e-5
    expected = (force_on_a(H + delta) - force_on_a(H - delta)) / (2 * delta)
    assert np.allclose(fmu.get("Fa_x", "Fa_y"), force_on_a(H), rtol=1e-12)
    assert np.allclose(fmu.output_derivatives("Fa_x", "Fa_y"), expected, rtol=1e-7, atol=1e-8)
    # the next step, its slopes not set again, holds the velocities
    assert fmu.do_step(H, 0.1) == OK
    b, vb = end("b", H)
    assert fmu.get("b_x", "b_vx") == pytest.approx([b[0] + vb[0] * 0.1, vb[0]], rel=1e-14)


def test_spring_at_zero_length(open_fmu):
    zero_rest = open_fmu("Spring")
    zero_rest.initialize(l0=0.0, b_x=0.0, c=3.0)
    assert zero_rest.do_step(0.0, 0.1) == OK and zero_rest.get("Fa_x", "Fa_y") == [0.0, 0.0]
    pre_stressed = open_fmu("Spring")  # l0 = 1 m: at r = 0 its direction is undefined
    assert pre_stressed.set(b_x=0.0) == OK
    assert pre_stressed.call("fmi2EnterInitializationMode") == OK
    assert pre_stressed.call("fmi2ExitInitializationMode") == ERROR  # refused like a singular pendulum
    assert "singular configuration" in pre_stressed.last_message()
    closing = open_fmu("Spring")  # its ends meet at the end of the step
    closing.initialize(b_x=0.05, b_vx=-0.5)
    assert closing.do_step(0.0, 0.1) == DISCARD
    assert "singular" in closing.last_message()


# ---------------------------------------------------------------- closed-form linear model

@pytest.mark.parametrize("g,d,H", [(9.81, 0.0, 0.25), (9.81, 0.5, 0.25), (9.81, 2 * math.sqrt(9.81), 0.25),
                                   (9.81, 40.0, 0.25), (0.0, 0.0, 0.25), (0.0, 3.0, 0.25), (9.81, 0.3, 1e-6),
                                   (9.81, 0.3, 7.0), (1e-8, 5.0, 3.0)])
def test_linear_model_is_solved_exactly(open_fmu, g, d, H):
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(model="linear", g=g, d=d, L=1.0, phi=0.3, omega=-0.2, F_x=0.4)
    assert fmu.set_input_derivatives(F_x=-0.6) == OK
    assert fmu.do_step(0.0, H) == OK
    phi, omega, n_rhs, n_steps = fmu.get("phi", "omega", "n_rhs", "n_steps")
    force = 0.4 - 0.6 * H / 2  # held at its mid-step value

    def rhs(t, y):
        return [y[1], -g * y[0] - d * y[1] + force]

    ref = solve_ivp(rhs, (0, H), [0.3, -0.2], rtol=1e-13, atol=1e-14, method="DOP853").y[:, -1]
    assert abs(phi - ref[0]) < 1e-10 and abs(omega - ref[1]) < 1e-10 * (1 + abs(ref[1]))
    assert n_rhs == 0 and n_steps == 1


@pytest.mark.parametrize("solver,tol,message", [
    ("rkf45", 0.0, "rkf45 needs a tolerance: variable tol = 0"),
    ("gbs", 1e-16, "gbs with tol = 1e-16: out of reach in double precision")])
def test_linear_model_checks_the_method_settings_too(open_fmu, solver, tol, message):
    """The closed form takes the step, but settings the method would refuse are refused as they are
    with the nonlinear model: the same error, the state untouched."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(model="linear", solver=solver, tol=tol, phi=0.3)
    assert fmu.do_step(0.0, 0.1) == 3
    assert message in fmu.last_message()


def test_linear_model_conserves_its_energy(fmu_paths, unzipped):
    r = simulate(fmu_paths["SimplePendulum"], 50.0, 0.5, start_values={"model": "linear", "phi": 0.2},
                 unzipdir=unzipped["SimplePendulum"])
    assert np.max(np.abs(r["E"] - r["E"][0])) < 1e-12
    assert np.max(np.abs(r["phi"] - 0.2 * np.cos(np.sqrt(9.81) * r.time))) < 1e-12


# ---------------------------------------------------------------- instances side by side

def test_instances_do_not_share_data(open_fmu):
    first, second = open_fmu("DoublePendulum"), open_fmu("DoublePendulum")
    first.initialize(solver="ab4", h=0.01)
    second.initialize(solver="rk4", h=0.02, phi1=0.3)
    for i in range(20):  # interleaved
        assert first.do_step(i * 0.05, 0.05) == OK and second.do_step(i * 0.05, 0.05) == OK
    alone = open_fmu("DoublePendulum")
    alone.initialize(solver="ab4", h=0.01)
    for i in range(20):
        assert alone.do_step(i * 0.05, 0.05) == OK
    assert first.get("phi1", "phi2", "omega1", "omega2") == alone.get("phi1", "phi2", "omega1", "omega2")


def test_spring_outputs_never_overflow_silently(open_fmu):
    fmu = open_fmu("Spring")
    fmu.initialize(k=1e10)
    assert fmu.set(b_x=1e160) == OK
    assert fmu.do_step(0.0, 0.1) == DISCARD  # E_pot = k/2 (r - l0)^2 would overflow
    assert "non-finite outputs" in fmu.last_message() and fmu.last_successful_time() == 0.0


def test_a_pass_through_the_anchor_within_one_step_is_caught(open_fmu):
    """eps(t) = -0.5 cos(w t) - (5/w) sin(w t) reaches -1 (r = 0) near t = 0.21 and is back above -1
    long before t = 1: the end of the step looks regular, the pass through the anchor is not."""
    fmu = open_fmu("SpringPendulum")
    fmu.initialize(solver="rk4", h=0.001, phi=0.0, eps=-0.5, v_eps=-5.0, g=0.0)
    assert fmu.do_step(0.0, 1.0) == DISCARD
    last = fmu.last_successful_time()
    assert 0.1 < last < 0.25 and fmu.get("eps")[0] > -1.0


def test_model_exchange_at_the_singularity_discards_without_nan(open_fmu):
    fmu = open_fmu("SpringPendulum", kind="ME")
    fmu.initialize()
    assert fmu.call("fmi2EnterContinuousTimeMode") == OK
    singular = (ctypes.c_double * 4)(0.3, -1.0, 0.0, 0.0)  # r = l0 + eps = 0
    assert fmu.call("fmi2SetContinuousStates", singular, 4) == OK
    derivatives = (ctypes.c_double * 4)(7.0, 7.0, 7.0, 7.0)
    assert fmu.call("fmi2GetDerivatives", derivatives, 4) == DISCARD
    assert all(math.isfinite(v) for v in derivatives)


def test_a_restored_state_with_a_non_finite_history_is_refused(open_fmu):
    """The Adams-Bashforth history belongs to the state: a NaN in it (valid checksum) is refused when
    the state is deserialized, not found by the next step."""
    import struct
    fmu = open_fmu("SimplePendulum")
    fmu.set(solver="ab6", h=0.01)
    fmu.initialize()
    for k in range(3):
        assert fmu.do_step(0.1 * k, 0.1) == OK
    serialized = bytearray(fmu.serialize(fmu.get_state()))
    # the layout of SimState after the 64-byte header: time, last successful time, Reals, Integers
    # (int32), input derivatives, machine state (int32), three counters, then the history
    variables = fmu.model_description.modelVariables
    n_real = sum(v.type == "Real" for v in variables)
    n_integer = sum(v.type in ("Integer", "Enumeration") for v in variables)
    n_input = sum(v.causality == "input" for v in variables)
    n_states = fmu.model_description.numberOfContinuousStates

    def aligned(offset: int) -> int:
        return (offset + 7) // 8 * 8
    history = aligned(aligned(64 + 16 + 8 * n_real + 4 * n_integer) + 8 * n_input + 4) + 24
    for k in range(6 * n_states):
        struct.pack_into("<d", serialized, history + 8 * k, math.nan)
    struct.pack_into("<Q", serialized, len(serialized) - 8, _fnv1a64(bytes(serialized[:-8])))
    with pytest.raises(Exception):
        fmu.deserialize(bytes(serialized))
    assert "Adams-Bashforth history holds a non-finite value" in fmu.last_message()
    assert fmu.do_step(0.3, 0.1) == OK
