"""Constraints (Lagrange's equations of the first kind) and events, against solutions derived here
independently of the generator: the bouncing ball's geometric series of bounces, the energy an impact
takes, (1 - e^2) of the normal kinetic energy, a ball at rest on its floor carrying m g, a pendulum
striking a wall against SciPy's event-located solution of the pendulum equation, and the pendulum
written in Cartesian coordinates with a rod (a bilateral constraint) against the angle form and its
rod tension m (L omega^2 + g cos phi)."""
from __future__ import annotations

import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu
from scipy.integrate import solve_ivp

from harness.fmi.methods import SOLVERS
from harness.objects.derivation import derive
from harness.objects.object_file import ObjectFileError, read_object_file
from harness.objects.proof import numeric_route_agreement

from harness.objects.registry import object_file

ROOT = Path(__file__).resolve().parents[2]

BALL = """
identifier = "Ball"
description = "a ball bouncing on a floor"
[parameters]
g = { start = 9.81, unit = "m/s2", min = 0.0 }
m = { start = 2.0, unit = "kg", min = 1e-9 }
R = { start = 0.1, unit = "m", min = 0.0 }
e = { start = 0.8, unit = "1", min = 0.0, max = 1.0 }
[coordinates]
x = { start = 0.0, unit = "m", velocity = "vx", velocity_start = 0.5 }
y = { start = 1.0, unit = "m", velocity = "vy" }
[energy]
T = "m/2*(vx**2 + vy**2)"
U = "m*g*y"
[points]
ball = { x = "x", y = "y" }
[constraints]
floor = { gap = "y - R", restitution = "e" }
"""

@pytest.fixture(scope="module")
def derived(fmu_paths):
    """The registry's objects that touch, under the names these tests use."""
    return {"Ball": fmu_paths["BouncingBall"], "WallPendulum": fmu_paths["WallPendulum"],
            "RodPendulum": fmu_paths["CartesianPendulum"]}


def _settings(solver: str, h: float, **others) -> dict:
    return {"solver": SOLVERS.index(solver) + 1, "h": h, "tol": 0.0, **others}


# ---------------------------------------------------------------- the bouncing ball, exactly

G, E, R, Y0 = 9.81, 0.8, 0.1, 1.0
BALL_MASS = 1.0  # modelDescription/BouncingBall.toml


def _bounces(e: float = E, rest_speed: float = 1e-3):
    """Impact times and the upward speeds after them, to the last rebound faster than rest_speed."""
    t = math.sqrt(2 * (Y0 - R) / G)
    v = G * t
    times, speeds = [], []
    while e * v >= rest_speed:
        v *= e
        times.append(t)
        speeds.append(v)
        t += 2 * v / G
    return times, speeds, t  # t: where the ball lands for good


def _height(t: float) -> float:
    times, speeds, rest = _bounces()
    if t < times[0]:
        return Y0 - G * t * t / 2
    for start, speed, end in zip(times, speeds, times[1:] + [rest]):
        if t < end:
            s = t - start
            return R + speed * s - G * s * s / 2
    return R


@pytest.mark.parametrize("solver", ["heun", "rk4", "nystrom5", "ab3", "abm4", "gauss_legendre4", "trapezoid"])
def test_the_ball_bounces_where_the_geometric_series_says(derived, solver):
    """Free flight is a parabola, which every method of order >= 2 integrates exactly: what is left is
    the location of the impacts, found to rounding."""
    times = np.linspace(0.0, 3.0, 61)
    result = simulate_fmu(derived["Ball"], stop_time=3.0, output_interval=0.05, start_values=_settings(solver, 0.003),
                          output=["y", "floor_gap", "n_events"])
    expected = np.array([_height(t) for t in times])
    assert np.max(np.abs(result["y"] - expected)) < 1e-11
    assert np.allclose(result["floor_gap"], result["y"] - R, atol=1e-15)
    assert result["n_events"][-1] == sum(1 for t in _bounces()[0] if t <= 3.0)


def test_an_impact_takes_one_minus_e_squared_of_the_normal_kinetic_energy(derived):
    first = _bounces()[0][0]
    before = simulate_fmu(derived["Ball"], stop_time=first - 0.01, output_interval=0.01,
                          start_values=_settings("rk4", 0.001), output=["E", "vy"])
    after = simulate_fmu(derived["Ball"], stop_time=first + 0.01, output_interval=0.01,
                         start_values=_settings("rk4", 0.001), output=["E", "vy"])
    m = BALL_MASS
    speed = G * first
    lost = before["E"][-1] - after["E"][-1]
    assert lost == pytest.approx((1 - E ** 2) * m * speed ** 2 / 2, rel=1e-12)


def test_the_ball_comes_to_rest_after_finitely_many_events(derived):
    """Rebounds slower than 1e-3 m/s end at rest: the floor turns active and carries the weight."""
    times, speeds, rest = _bounces()
    result = simulate_fmu(derived["Ball"], stop_time=rest + 1.0, output_interval=0.5,
                          start_values=_settings("rk4", 0.004), output=["y", "vy", "floor_force", "n_events"])
    assert result["y"][-1] == pytest.approx(R, abs=1e-12)
    assert abs(result["vy"][-1]) < 1e-12
    assert result["floor_force"][-1] == pytest.approx(BALL_MASS * G, rel=1e-12)
    # each rebound is an event, and the last landing one more (the floor turns active)
    assert result["n_events"][-1] == len(times) + 1


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_model_exchange_shows_the_impacts_to_an_importer(derived, version):
    """fmpy's CVode sees the event indicators, and event mode makes the velocity jump (fmi2NewDiscreteStates,
    fmi3UpdateDiscreteStates)."""
    path = derived["Ball"] if version == "2.0" else derived["Ball"].parent / "fmi3" / derived["Ball"].name
    result = simulate_fmu(path, fmi_type="ModelExchange", solver="CVode", stop_time=2.0,
                          output_interval=0.05, relative_tolerance=1e-10, output=["y", "n_events"])
    expected = np.array([_height(t) for t in result["time"]])
    assert np.max(np.abs(result["y"] - expected)) < 1e-6
    assert result["n_events"][-1] == sum(1 for t in _bounces()[0] if t <= 2.0)


# ---------------------------------------------------------------- a pendulum striking a wall

def _wall_reference(t_end: float, phi0=-1.0, wall=0.3, e=0.9, g=9.81, L=1.0):
    """The pendulum equation written here, integrated by SciPy to 1e-13 with the wall as an event."""
    def rhs(t, y):
        return [y[1], -g / L * math.sin(y[0])]

    def hit(t, y):
        return wall - y[0]
    hit.terminal, hit.direction = True, -1
    t, y, impacts = 0.0, [phi0, 0.0], []
    while t < t_end:
        solution = solve_ivp(rhs, (t, t_end), y, method="DOP853", rtol=1e-13, atol=1e-14, events=hit)
        if solution.status == 1:
            t = solution.t_events[0][0]
            y = [wall, -e * solution.y_events[0][0][1]]
            impacts.append(t)
        else:
            return solution.y[:, -1], impacts
    return np.array(y), impacts


@pytest.mark.parametrize("solver, order", [("euler", 1), ("heun", 2), ("rk3", 3), ("rk4", 4), ("nystrom5", 5),
                                           ("ab2", 2), ("ab3", 3), ("ab4", 4), ("ab6", 6), ("abm2", 2), ("abm3", 3),
                                           ("abm4", 4), ("abm5", 5), ("abm6", 6), ("implicit_midpoint", 2)])
def test_each_method_keeps_its_order_through_impacts(derived, solver, order):
    """The event is found on the method's own step (an Adams method's on the polynomial of its step, from its
    history), so the error after several impacts still falls as h^p."""
    reference, impacts = _wall_reference(3.0)
    assert len(impacts) >= 2
    errors = []
    steps = (0.02, 0.01, 0.005) if order >= 3 else (0.004, 0.002, 0.001)
    for h in steps:
        result = simulate_fmu(derived["WallPendulum"], stop_time=3.0, output_interval=0.5,
                              start_values=_settings(solver, h), output=["phi", "omega", "n_events"])
        assert result["n_events"][-1] == len(impacts)
        errors.append(abs(result["phi"][-1] - reference[0]) + abs(result["omega"][-1] - reference[1]))
    measured = math.log2(errors[1] / errors[2])
    assert abs(measured - order) < 0.3, (errors, measured)


def test_a_step_split_by_an_impact_counts_as_two(derived):
    """n_steps counts the step onto each impact and the rest of that step after it."""
    result = simulate_fmu(derived["WallPendulum"], stop_time=3.0, output_interval=0.5,
                          start_values=_settings("rk4", 0.01), output=["n_steps", "n_events"])
    assert result["n_events"][-1] >= 2
    assert result["n_steps"][-1] == 300 + result["n_events"][-1]


# trapezoid is left out: its Newton iterations per step vary with the state, so a run with impacts can take fewer
# evaluations than one without; of the Adams methods, whose history starts again after an impact (p - 1 steps of a
# Runge-Kutta method of order p - 1), only those whose restart fits: ab2, abm2 and abm3
@pytest.mark.parametrize("solver", ["euler", "midpoint", "heun", "rk3", "rk4", "nystrom5", "stormer_verlet",
                                    "implicit_midpoint", "gauss_legendre4", "ab2", "abm2", "abm3"])
def test_an_impact_costs_at_most_three_steps_of_its_method(derived, solver):
    """Locating an impact on the method's own step and taking the rest of that step costs at most three of its
    steps in right-hand-side evaluations: the wall pendulum (restitution 1) over 10 s in one call, with its wall and
    again with the wall out of reach, on the same fixed steps."""
    def work(wall: float) -> tuple[int, int, int]:
        result = simulate_fmu(derived["WallPendulum"], stop_time=10.0, output_interval=10.0,
                              start_values=_settings(solver, 1e-3, phi_wall=wall, e=1.0),
                              output=["n_rhs", "n_steps", "n_events"])
        return result["n_rhs"][-1], result["n_steps"][-1], result["n_events"][-1]
    with_wall, without = work(0.3), work(3.2)
    assert with_wall[2] == 8 and without[2] == 0
    per_step = without[0] / without[1]
    per_impact = (with_wall[0] - without[0]) / with_wall[2]
    assert per_impact <= 3 * per_step, (per_impact, per_step)


# ---------------------------------------------------------------- a rod as a bilateral constraint

def test_a_rod_in_cartesian_coordinates_swings_like_the_angle_form(derived):
    """phi = atan2(x, -y) follows the simple pendulum's equation; the rod's force is its tension."""
    phi0 = 0.5
    result = simulate_fmu(derived["RodPendulum"], stop_time=2.0, output_interval=0.1,
                          start_values=_settings("rk4", 0.001), output=["x", "y", "vx", "vy", "rod_gap", "rod_force"])
    solution = solve_ivp(lambda t, s: [s[1], -9.81 * math.sin(s[0])], (0, 2.0), [phi0, 0.0], method="DOP853",
                         rtol=1e-13, atol=1e-14, t_eval=result["time"])
    phi = np.arctan2(result["x"], -result["y"])
    assert np.max(np.abs(phi - solution.y[0])) < 1e-9
    assert np.max(np.abs(result["rod_gap"])) < 1e-14  # projected back to rounding
    omega = solution.y[1]
    tension = 1.0 * (1.0 * omega ** 2 + 9.81 * np.cos(solution.y[0]))
    # lambda acts along dg/dq, which points inward (the gap shrinks outward): it is the tension
    assert np.max(np.abs(result["rod_force"] - tension)) < 1e-7


# ---------------------------------------------------------------- what a file may not say

@pytest.mark.parametrize("line, message", [
    ('floor = { gap = "y - R", restitution = 1.5 }', "constraints.floor.restitution: 1.5 is outside [0, 1]"),
    ('floor = { gap = "vy - R" }', "constraints.floor.gap: 'vy' may not appear here"),
    ('floor = { gap = "R - 1" }', "constraints.floor.gap: = R - 1 is not a function of the coordinates"),
    ('floor = { gap = "y - R", restitution = "g" }', "parameter 'g' may take values outside [0, 1]"),
    ('floor = { gap = "y - R", kind = "sideways" }', "constraints.floor.kind: 'sideways'"),
    ('floor = { gap = "y - R", kind = "bilateral", restitution = 0.5 }', "a bilateral constraint is rigid"),
    ('floor = { gap = "y - R", exponent = 1.5 }', "belongs to a compliant constraint"),
])
def test_a_constraint_that_cannot_be_derived_is_named(line, message):
    text = BALL.replace('floor = { gap = "y - R", restitution = "e" }', line)
    with pytest.raises(ObjectFileError, match=None) as caught:
        read_object_file("Ball.toml", text)
    assert message in str(caught.value) and "\n" not in str(caught.value)


def test_a_start_that_violates_a_rigid_constraint_is_refused_with_exit_code_2(tmp_path):
    source = tmp_path / "Ball.toml"
    source.write_text(BALL.replace('y = { start = 1.0,', 'y = { start = 0.05,'))
    with pytest.raises(ObjectFileError, match=r"constraints.floor: the start values violate it \(gap = -0.05"):
        derive(read_object_file(source))
    result = subprocess.run([sys.executable, "-m", "harness", "derive", str(source), "--out", str(tmp_path)],
                            capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 2
    assert "constraints.floor: the start values violate it" in result.stderr
    assert "Traceback" not in result.stderr and not list(tmp_path.glob("*.fmu"))


def test_the_fmu_refuses_a_start_inside_the_floor(derived):
    """The start values the importer sets are checked again at the end of initialization. (No logger of its own:
    fmpy keeps the last one handed to simulate_fmu for every later FMU's messages, and a lambda freed after this
    test crashed the next FMU that logged in the same process.)"""
    with pytest.raises(Exception, match="fmi2ExitInitializationMode"):
        simulate_fmu(derived["Ball"], stop_time=0.1, start_values={"y": 0.05})


# ---------------------------------------------------------------- compliant contact

HERTZ = BALL.replace('floor = { gap = "y - R", restitution = "e" }',
                     'floor = { gap = "y - R", stiffness = "k", exponent = 1.5 }').replace(
    'e = { start = 0.8, unit = "1", min = 0.0, max = 1.0 }',
    'k = { start = 1e5, min = 1e-9, description = "Hertz stiffness, N/m^1.5" }')


def test_a_compliant_contact_stores_and_returns_the_energy(tmp_path):
    """Without damping a Hertz contact is elastic: the ball leaves as fast as it came, E (the overlap's
    stored energy included) stays, and the onset and the end of each contact are events."""
    source = tmp_path / "Ball.toml"
    source.write_text(HERTZ)
    result = subprocess.run([sys.executable, "-m", "harness", "derive", str(source), "--out", str(tmp_path)],
                            capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    first = math.sqrt(2 * (Y0 - R) / G)
    run = simulate_fmu(tmp_path / "Ball.fmu", stop_time=2 * first + 0.05, output_interval=0.001,
                       start_values=_settings("rk4", 2e-4), output=["y", "vy", "E", "floor_gap", "floor_force",
                                                                   "n_events"])
    assert run["n_events"][-1] == 2
    # the deepest overlap stores the impact's kinetic energy: k delta^2.5 / 2.5 = m v^2 / 2 (gravity aside)
    deepest = (2.5 * 2.0 * (G * first) ** 2 / 2 / 1e5) ** (1 / 2.5)
    assert -np.min(run["floor_gap"]) == pytest.approx(deepest, rel=2e-2)
    assert np.max(run["floor_force"]) == pytest.approx(1e5 * deepest ** 1.5, rel=5e-2)
    # E is kept to rk4's error. Hertz's delta^1.5 has unbounded higher derivatives at the onset, so with
    # fixed steps the error falls as about h^2.5 there (not h^4), however exactly the onset is found.
    drifts = []
    for h in (2e-4, 1e-4):
        rerun = simulate_fmu(tmp_path / "Ball.fmu", stop_time=2 * first + 0.05, output_interval=0.05,
                             start_values=_settings("rk4", h), output=["E"])
        drifts.append(abs(rerun["E"][-1] - rerun["E"][0]))
    assert math.log2(drifts[0] / drifts[1]) > 1.8, drifts
    assert drifts[1] < 1e-8 * run["E"][0]
    after = run["time"] > first + 0.1
    assert np.max(run["y"][after]) == pytest.approx(Y0, abs=1e-5)  # back up to where it fell from


# ---------------------------------------------------------------- event state in the FMU state

def _instance(path: Path, **start):
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    description = read_model_description(path)
    instance = FMU2Slave(guid=description.guid, unzipDirectory=extract(path),
                         modelIdentifier=description.coSimulation.modelIdentifier, instanceName="ball")
    references = {v.name: v.valueReference for v in description.modelVariables}
    instance.instantiate()
    for name, value in {"h": 0.004, **start}.items():
        if name == "solver":
            instance.setInteger([references[name]], [value])
        else:
            instance.setReal([references[name]], [value])
    instance.setupExperiment(startTime=0.0)
    instance.enterInitializationMode()
    instance.exitInitializationMode()
    return instance, references


def test_the_active_constraints_survive_serialization(derived):
    """At rest the floor is active (it carries m g); a serialized state brings that back in a new instance,
    which then goes on resting without an event."""
    rest = _bounces()[2]
    first, references = _instance(derived["Ball"])
    t = 0.0
    while t < rest + 0.5:
        first.doStep(t, 0.1)
        t += 0.1
    events = first.getInteger([references["n_events"]])[0]
    blob = first.serializeFMUstate(first.getFMUstate())
    second, _ = _instance(derived["Ball"])
    second.setFMUstate(second.deSerializeFMUstate(blob))
    for _ in range(10):
        second.doStep(t, 0.1)
        t += 0.1
    y, force = second.getReal([references["y"], references["floor_force"]])
    assert y == pytest.approx(R, abs=1e-12) and force == pytest.approx(BALL_MASS * G, rel=1e-12)
    assert second.getInteger([references["n_events"]])[0] == events
    for instance in (first, second):
        instance.terminate()
        instance.freeInstance()


@pytest.mark.parametrize("solver", ["ab4", "abm5"])
def test_an_adams_restart_after_an_impact_survives_serialization(derived, solver):
    """After an impact an Adams method's history starts again with its lower-order restarter, not with the run's
    starter: a state saved in the middle of that restart continues in a new instance bit for bit as the run
    that was not interrupted (each call one internal step)."""
    h = 1e-3
    start = {"solver": SOLVERS.index(solver) + 1, "h": h, "tol": 0.0, "phi_wall": 0.3, "e": 1.0}
    first, references = _instance(derived["WallPendulum"], **start)
    states = [references[name] for name in ("phi", "omega")]
    step = 0
    while first.getInteger([references["n_events"]])[0] == 0:
        first.doStep(step * h, h)
        step += 1
    first.doStep(step * h, h)  # one step into the restart
    step += 1
    blob = first.serializeFMUstate(first.getFMUstate())
    second, _ = _instance(derived["WallPendulum"], **start)
    second.setFMUstate(second.deSerializeFMUstate(blob))
    for k in range(step, step + 50):
        for instance in (first, second):
            instance.doStep(k * h, h)
        assert first.getReal(states) == second.getReal(states), k
    for instance in (first, second):
        instance.terminate()
        instance.freeInstance()


@pytest.mark.parametrize("name, source", [("Ball", "BouncingBall"), ("WallPendulum", "WallPendulum"),
                                          ("RodPendulum", "CartesianPendulum")])
def test_the_constrained_equations_are_the_numeric_routes(derived, name, source):
    """Accelerations, constraint forces (the rod's tension), gaps and energies at random states against
    Lagrange's equations of the first kind by finite differences (harness.objects.numeric_route)."""
    proof = numeric_route_agreement(derived[name], read_object_file(object_file(source)), samples=4)
    assert proof.passed, proof.detail


def test_partial_derivatives_of_constrained_motion_are_refused_by_name(derived):
    from fmpy import read_model_description
    for path in (derived["Ball"], derived["Ball"].parent / "fmi3" / derived["Ball"].name):
        description = read_model_description(path)
        assert description.coSimulation.providesDirectionalDerivative is False
        assert description.modelExchange.providesDirectionalDerivative is False
        assert description.numberOfEventIndicators == 1
        # FMI 3.0 names each event indicator by a variable: the constraint's indicator
        indicator = next(v for v in description.modelVariables if v.name == "floor_indicator")
        assert indicator.causality == "local"


def test_fmi3_co_simulation_returns_early_at_each_impact(derived):
    """With earlyReturnAllowed, fmi3DoStep ends at the first event it handles: lastSuccessfulTime is the impact
    time of the geometric series, the ball on the floor, rising; without it the step runs to its end."""
    from fmpy import extract, read_model_description
    from fmpy.fmi3 import FMU3Slave
    path = derived["Ball"].parent / "fmi3" / derived["Ball"].name
    description = read_model_description(path)
    references = {v.name: v.valueReference for v in description.modelVariables}
    unzipped = extract(path)
    times = _bounces()[0]
    for allowed in (True, False):
        instance = FMU3Slave(guid=description.guid, unzipDirectory=unzipped, instanceName="ball",
                             modelIdentifier=description.coSimulation.modelIdentifier)
        instance.instantiate(earlyReturnAllowed=allowed)
        instance.enterInitializationMode()
        instance.exitInitializationMode()
        t = 0.0
        for expected in times[:4]:
            _, _, early, reached = instance.doStep(currentCommunicationPoint=t, communicationStepSize=1.0)
            if not allowed:
                assert not early and reached == t + 1.0
                break
            assert early and reached == pytest.approx(expected, abs=1e-12)
            y, vy = instance.getFloat64([references["y"], references["vy"]])
            assert y == pytest.approx(R, abs=1e-12) and vy > 0
            t = reached
        instance.terminate()
        instance.freeInstance()
    shutil.rmtree(unzipped, ignore_errors=True)
