"""A hostile review of constraints, contacts and events: each test is a probe that failed when it was written,
with what physics or the FMI standard expects and what the FMUs and the master did instead (in its text). Every
probe's fix has landed since (in the master, fmus/framework/stepper.c and core.c): each test now guards its fix.

The probes that passed (an impact exactly at a communication step's end and one ulp either side, the cradle
struck from both ends at once, restitution 0 and 1, touching without force, the bouncing ball's Zeno end in
Co-Simulation and Model Exchange, serialization at and after rigid impacts, refused parameters and start
values, the Contact's overflow) are not repeated here."""
from __future__ import annotations

import ctypes
import json
import math

import numpy as np
import pytest
from fmpy import simulate_fmu

from harness.cosim.master import Master, MasterOptions
from harness.cosim.system import load_system
from harness.fmi.fmu_instance import DISCARD, ERROR, OK, FmuInstance
from harness.fmi.methods import SOLVERS
from harness.scene.contact_scenes import pendulum_cradle

pytestmark = pytest.mark.timeout(60)

G, R = 9.81, 0.1  # modelDescription/BouncingBall.toml


def _solver(name: str) -> int:
    return SOLVERS.index(name) + 1


@pytest.fixture
def instance(fmu_paths):
    """instance(name, kind="CS") -> FmuInstance of the FMI 2.0 FMU, freed after the test."""
    made = []

    def factory(name: str, kind: str = "CS") -> FmuInstance:
        made.append(FmuInstance(fmu_paths[name], kind=kind, name=f"{name}{len(made)}"))
        return made[-1]

    yield factory
    for one in made:
        one.free()


# ---------------------------------------------------------------- adaptive methods at late times

# Heights from which one bounce (restitution 1) is found late, from a start time of 1e4 s (2 to 5 of 200
# heights per method there): an adaptive method's trial step runs to the time t + theta, and the event's
# Newton steps (about (z + 5e-15) / rate, 1.5e-15 s) move theta by less than one rounding of t (1.8e-12 s),
# so every trial repeats the same state on the near side of the floor until the 60 trials run out; the event
# is then handled at the end of the internal step (0.5 ms late, 1.8 mm inside the floor). The same happens at
# smaller times: restitution 0.9999 from t = 0 went wrong at t = 1388 s (0.01 m/s), and gbs with e = 0.99999
# stopped at t = 35774 s with fmi2Discard ("an event ... recurs at once"). Fix (fmus/framework/stepper.c,
# locate_event, after `if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);`):
#     if (e->adaptive && t + next <= t + lo) {
#         next = nextafter(t + lo, INFINITY) - t;  /* the next representable time, not the same trial again */
#         if (!(t + next < t + hi)) break;         /* the bracket is as narrow as time: hi is past the event */
#     }
LATE = [("rkf45", 0.957286432160804), ("gbs", 0.957286432160804), ("taylor", 0.6105527638190955)]


@pytest.mark.parametrize("solver, height", LATE)
def test_an_adaptive_method_finds_an_impact_where_time_rounds_coarsely(instance, solver, height):
    """Expected: back at the top after one bounce, at rest (vy = 0 to the rounding of time, about 5e-11 m/s
    here). Found: vy = 0.038 m/s (rkf45, gbs) and 0.027 m/s (taylor): the impact was handled at the end of the
    internal step, the ball already 1.8 mm inside the floor (with the fix above: 4.6e-11 and 3.6e-11 m/s)."""
    start = 1e4
    ball = instance("BouncingBall")
    ball.initialize(start_time=start, solver=_solver(solver), h=0.004, tol=1e-10, e=1.0, y=height)
    fall = math.sqrt(2 * (height - R) / G)
    assert ball.do_step(start, 2 * fall) == OK  # down, the impact, and up again in one call
    assert ball.get("n_events") == [1]
    assert abs(ball.get("vy")[0]) < 1e-8, ball.get("vy")
    assert ball.get("y")[0] == pytest.approx(height, abs=1e-9)


def test_a_hundred_thousand_elastic_bounces_keep_their_clock(instance):
    """Restitution 1, rkf45 (steps up to h = 1 s), one call of 1e6 s: it ends at its limit of 100,000 events
    per call, at the impact that exceeds it, the 100,001st, which falls at t = (1 + 2 * 100,000) sqrt(2 (y0 -
    R) / g) = 85,671.0157 s. Found: the call ended at 85,994.69 s, 324 s late, the impacts found late adding up
    (with the fix above: 85,671.0157335 s, 4.9e-6 s off)."""
    ball = instance("BouncingBall")
    ball.initialize(solver=_solver("rkf45"), h=1.0, tol=1e-10, e=1.0)
    assert ball.do_step(0.0, 1e6) == DISCARD
    assert "100000 events" in ball.last_message()
    fall = math.sqrt(2 * (1.0 - R) / G)
    # each impact located to a few roundings of t (1.5e-11 s near 8.6e4 s): 5e-6 s over 100,000 of them
    assert ball.last_successful_time() == pytest.approx((1 + 2 * 100_000) * fall, abs=1e-4)


# ---------------------------------------------------------------- serialization inside a compliant contact

def test_a_state_serialized_inside_a_hertz_contact_deserializes(instance):
    """SPEC 10: which constraints are active is part of the FMU state and survives serialization. A compliant
    contact's bit records that it overlaps (constraints.c, track_overlaps). Found: fmi2DeSerializeFMUstate
    refuses every state taken while a Hertz contact overlaps ("the FMU state's active constraints 0x7 name a
    constraint that cannot be active"); fmi2SetFMUstate of the same state works. Expected: deserialized into a
    fresh instance, the run goes on to the same bits as without the detour. Fix (fmus/framework/core.c,
    restored_state_valid): refuse only a bilateral constraint's bit, `if ((s->active_constraints >> i & 1) &&
    constants.law[i].bilateral) break;`, and say "a bit for each rigid unilateral or compliant constraint"."""
    starts = dict(solver=_solver("rkf45"), h=1e-4, tol=1e-10)
    quarter, inside = 0.2789, 0.27911  # the strike begins at 0.27905 s and lasts about 0.2 ms
    names = [f"omega{k}" for k in range(1, 6)] + ["n_events", "E"]
    straight = instance("HertzCradle")
    straight.initialize(**starts)
    straight.do_step(0.0, quarter)
    straight.do_step(quarter, inside - quarter)
    assert straight.get("contact12_gap")[0] < 0.0  # inside the contact
    state = straight.get_state()
    data = straight.serialize(state)
    straight.free_state(state)
    straight.do_step(inside, 0.3 - inside)
    fresh = instance("HertzCradle")
    fresh.initialize(**starts)
    restored = fresh.deserialize(data)
    fresh.set_state(restored)
    fresh.free_state(restored)
    assert fresh.do_step(inside, 0.3 - inside) == OK
    assert fresh.get(*names) == straight.get(*names)


# ---------------------------------------------------------------- a unilateral force never pulls

def test_a_string_never_pulls_in_model_exchange(fmu_paths):
    """SPEC 10: NAME_force >= 0 for unilateral constraints. Through fmpy's Model Exchange (CVode), the string
    pendulum's tension falls to zero where the string goes slack, a state event: the importer reads the outputs at
    the located event, where the force (the indicator) lies just past zero. Found: string_force = -9.3e-15 N
    handed out. Expected: never below zero; the release and the jerk taut still found (2 events)."""
    result = simulate_fmu(str(fmu_paths["StringPendulum"]), fmi_type="ModelExchange", stop_time=3.0,
                          output_interval=0.03, relative_tolerance=1e-8, output=["string_force", "n_events"])
    assert result["string_force"].min() >= 0.0, result["string_force"].min()
    assert result["n_events"][-1] == 2


# ---------------------------------------------------------------- implicit methods against a Hertz contact

@pytest.mark.parametrize("solver", ["implicit_midpoint", "gauss_legendre4", "trapezoid"])
def test_an_implicit_method_takes_the_strike_of_a_hertz_contact(instance, solver):
    """Ball 1 of the Hertz cradle approaches ball 2 at 0.85 m/s; steps of 10 us, h = 10 us. Found: the implicit
    method's Newton iteration failed at the first strike (t = 0.279 s), because its Jacobian, from the free equations,
    lacked the contact's stiffness (k = 1.5e10 N/m^1.5: the correction in omega after the onset outgrew the first one).
    Before that was understood, the failure was even reported as steps taken: 15 to 16 of 19 steps "succeeded"
    without moving. Now jacobian_at adds each pushing contact's M^-1 G^T dF/dg G (and its rate's) to the free
    equations' Jacobian. Expected, and asserted: every step succeeds and moves, the strike's onset and end are
    events, and the energy holds to 1e-4 of itself over the strike (measured: 3e-6 to 3e-5)."""
    cradle = instance("HertzCradle")
    cradle.initialize(solver=_solver(solver), h=1e-5, tol=0.0)
    t = 0.279
    assert cradle.do_step(0.0, t) == OK
    energy = cradle.get("E")[0]
    for _ in range(60):
        before = cradle.get("phi1", "omega1", "phi2", "contact12_gap")
        assert cradle.do_step(t, 1e-5) == OK, cradle.last_message()
        t += 1e-5
        after = cradle.get("phi1", "omega1", "phi2", "contact12_gap")
        if before[3] > 1e-5:  # apart for the whole step: a free swing of 10 us
            assert after[0] - before[0] == pytest.approx(before[1] * 1e-5, rel=1e-3), (t, before, after)
        else:
            assert after != before, (t, before, after)
    assert cradle.get("n_events")[0] >= 2  # the onset and the end of the strike
    assert abs(cradle.get("E")[0] - energy) <= 1e-4 * abs(energy), (cradle.get("E")[0], energy)


def test_a_fixed_step_too_long_for_a_stiff_contact_is_refused_with_the_step_that_holds(instance):
    """rk4 on the Hertz cradle at h = 0.2 ms, 1 ms per call over 0.4 s. Found: every call returned fmi2OK while the
    strike's oscillation (about 3e4 rad/s at full compression: h omega beyond rk4's bound 2.83) grew step by step:
    the energy went from -3.59 J to 2.1e8 J, with 352 events. Expected: fmi2Discard before the strike, naming the
    contact, the method, h and the largest h that keeps the oscillation from growing more than 2-fold per period
    (for the contact it names; the next one of the strike can ask for a little less), with the energy untouched;
    at half that h the strike runs and keeps its energy to the method's error."""
    cradle = instance("HertzCradle")
    cradle.initialize(solver=_solver("rk4"), h=2e-4, tol=0.0)
    energy, t = cradle.get("E")[0], 0.0
    while t < 0.4 - 1e-12 and cradle.do_step(t, 1e-3) == OK:
        t += 1e-3
    assert t < 0.4 and cradle.last_successful_time() < 0.2791, t
    message = cradle.last_message()
    assert "the compliant contact contact12" in message and "is too stiff for rk4 at h = 0.0002" in message, message
    assert cradle.get("n_events")[0] == 0 and abs(cradle.get("E")[0] - energy) <= 1e-12 * abs(energy)
    largest = float(message.split("where h at most ")[1].split(" ")[0])
    assert 1e-5 < largest < 2e-4, message
    cradle = instance("HertzCradle")
    cradle.initialize(solver=_solver("rk4"), h=0.5 * largest, tol=0.0)
    for k in range(400):
        assert cradle.do_step(k * 1e-3, 1e-3) == OK, cradle.last_message()
    assert cradle.get("n_events")[0] >= 2
    assert abs(cradle.get("E")[0] - energy) < 1e-2 * abs(energy), (cradle.get("E")[0], energy)


# ---------------------------------------------------------------- extreme stiffness with fixed steps

def _real(instance: FmuInstance, name: str) -> tuple[int, float]:
    """fmi2GetReal of one variable: (status, value), without raising on a discard."""
    value = (ctypes.c_double * 1)()
    reference = (ctypes.c_uint * 1)(instance.reference(name))
    return instance.call("fmi2GetReal", reference, ctypes.c_size_t(1), value), value[0]


def test_a_discarded_step_with_events_leaves_a_state_with_finite_outputs(instance):
    """k = 1e300 (the range is [1e-9, inf)): rk4 at h = 10 us steps into the contact and its state overflows
    the energy. Found: fmi2DoStep returned fmi2Discard "the state would become non-finite or singular in the
    substep after t = 0.28; stopped there (last successful time 0.28)", i.e. at the step's end, and kept the
    state it had reached there: omega2 = -3.6e293 rad/s handed out with fmi2OK, E and E_kin refused as not
    finite. Expected: a last successful time whose state has finite outputs, and that state handed out. Now the call
    goes back to its start where the state it stopped in (at the step's end, or where an event could not be
    resolved) overflows its outputs."""
    cradle = instance("HertzCradle")
    cradle.initialize(solver=_solver("rk4"), h=1e-5, tol=0.0, k=1e300)
    assert cradle.do_step(0.0, 0.279) == OK
    status = cradle.do_step(0.279, 0.001)
    assert status == DISCARD
    reached = cradle.last_successful_time()
    assert reached < 0.28 - 1e-12, (reached, cradle.last_message())
    status, energy = _real(cradle, "E")
    assert status == OK and math.isfinite(energy)


# ---------------------------------------------------------------- invalid parameters

@pytest.mark.parametrize("name", ["NewtonsCradle", "HertzCradle"])
def test_a_cradle_of_point_balls_is_refused(instance, name):
    """R = 0: the five pivots coincide and the balls are points at one place; a contact's gap (the distance of the
    centres minus 2 R) can never become negative, so no contact is ever found. Found: accepted, ball 1 swung
    through the other four (0 events, omega1 = 2.71 rad/s after the quarter period). Expected: fmi2SetReal
    refuses R = 0 with its allowed range (as it does m = 0 and L = 0)."""
    cradle = instance(name)
    cradle.call("fmi2SetupExperiment", 0, 0.0, ctypes.c_double(0.0), 0, 0.0)
    assert cradle.set(R=0.0) == ERROR
    assert "variable R" in cradle.last_message() and "allowed range" in cradle.last_message()


def test_a_contact_between_two_points_is_refused(instance):
    """R_a = R_b = 0: the bodies are points, the gap |b - a| is never negative, the contact never acts, and at
    coincidence its direction is undefined. Found: accepted. Expected: fmi2ExitInitializationMode refuses the
    pair by name with what is allowed."""
    contact = instance("Contact")
    contact.call("fmi2SetupExperiment", 0, 0.0, ctypes.c_double(0.0), 0, 0.0)
    assert contact.set(R_a=0.0, R_b=0.0, b_x=0.1) == OK
    assert contact.call("fmi2EnterInitializationMode") == OK
    assert contact.call("fmi2ExitInitializationMode") == ERROR
    message = contact.last_message()
    assert "fmi2ExitInitializationMode" in message and "R_a" in message and "R_b" in message, message


# ---------------------------------------------------------------- the master's contact steps at extreme stiffness

def _strike(tmp_path, stiffness: float):
    """The cradle of five pendulum FMUs, ball 1 0.6 mm from ball 2 at 0.9 m/s, its Contacts at `stiffness`."""
    data = pendulum_cradle(5, angle=-0.002, stop=0.004, step=0.001)
    data["components"]["ball1"]["start"]["omega"] = 3.0
    for component in data["components"].values():
        if component["fmu"] == "Contact":
            component["start"]["k"] = stiffness
    path = tmp_path / "strike.json"
    path.write_text(json.dumps(data))
    return load_system(path)


STEEL_RATES = np.array([-0.21302, -0.09079, -0.04343, 0.38099, 2.96573])  # the strike at steel's k = 1.465e10


def _runs(system, **options) -> list[tuple]:
    """The run in the C loop and in the Python loop: the result and the FMU states left unreleased."""
    runs = []
    for native in (True, False):
        with Master(system, MasterOptions(stop=0.004, step=0.001, **options)) as master:
            master.use_native = native
            result = master.run()
            runs.append((result, sum(unit.live_states for unit in master.units)))
    return runs


@pytest.mark.parametrize("stiffness", [1e15, 1e17, 1e20])
def test_contact_steps_never_step_through_a_stiff_contact(tmp_path, stiffness):
    """Hertz's chain has no time scale of its own: the balls' rates after the strike do not depend on k (at
    steel's k = 1.465e10 they are -0.213, -0.091, -0.043, 0.381, 2.966 rad/s), and the energy stays -3.5775 J.
    At k = 1e17 a contact lasts 0.1 us, and the first step into it (the contact step before any contact was
    seen, 1e-4 of the interval: 0.1 us) drives the balls 90 nm into each other; the blind steps after it
    double. Found: --contact-steps 100 finished without a word, ball rates of 1e9 rad/s, the energy residual
    2.6e16 J (1e20: 5.6e16 J, 30 macro steps; 1e15: rates off by 1.2e-2, 1.2e-3 J). Expected: steel's rates to
    the accuracy of 100 steps per contact (measured after the fix: within 3.6e-4 rad/s, 1,066 to 1,106 macro
    steps, 1 to 3 entries redone, 2e-5 to 3e-5 J), in the C loop and the Python loop alike, bit for bit."""
    (c, c_live), (py, py_live) = _runs(_strike(tmp_path, stiffness), contact_steps=100)
    assert c.stopped_at is None, c.message
    assert np.array_equal(c.values, py.values) and (c.macro_steps, c.retries) == (py.macro_steps, py.retries)
    assert c_live == py_live == 0
    rates = np.array([c[f"ball{k}.omega"][-1] for k in range(1, 6)])
    assert np.max(np.abs(rates - STEEL_RATES)) < 1e-3, rates
    assert c.energy_residual < 1e-4 and c.retries >= 1, (c.energy_residual, c.retries)


def test_contact_steps_at_steel_stiffness_are_what_they_were(tmp_path):
    """The entries kept through a contact's blind steps change nothing where no blind step swings: the strike at
    steel's stiffness takes its 1,048 macro steps, none redone (1,149 before the steps read an overlap below
    1e-13 m as none, the Contact's own event rule: the balls at rest, whose gaps the strike closes first by a
    rounding, no longer count as in contact from the first step that moves them)."""
    (c, _), (py, _) = _runs(_strike(tmp_path, 1.465e10), contact_steps=100)
    assert (c.macro_steps, c.retries, py.macro_steps, py.retries) == (1048, 0, 1048, 0)
    rates = np.array([c[f"ball{k}.omega"][-1] for k in range(1, 6)])
    # within 3e-5 rad/s of the rates before that rule (2.3e-5), a little nearer the monolithic reference's
    # (2.0e-4 from them against 2.2e-4)
    assert np.max(np.abs(rates - STEEL_RATES)) < 3e-5, rates
