"""The registry's objects that touch, against solutions derived here from their physics alone: Newton's
cradle from the pendulum's elliptic period and the textbook exchange of velocities (one in, one out; two
in, two out), the string pendulum's slack point from its tension, its flight as a parabola and the jerk
that takes its radial velocity, and the Hertz cradle against itself at a tenth of the step.
(tests/framework/test_constraints.py proves the bouncing ball, the wall pendulum and the Cartesian pendulum.)"""
from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from fmpy import simulate_fmu
from scipy.integrate import quad, solve_ivp
from scipy.special import ellipk

from harness.fmi.events import event_times, fmi3_counterpart
from harness.fmi.fmu_instance import FmuInstance
from harness.fmi.fmus import PROJECT_ROOT
from harness.fmi.methods import FIXED_STEP, ORDER, SOLVERS
from harness.objects.object_file import read_object_file
from harness.objects.proof import numeric_route_agreement
from harness.objects.registry import object_file
from test_new_objects import assert_the_plan_holds

G = 9.81
CRADLE_L, CRADLE_PHI0 = 0.3, 0.5           # modelDescription/NewtonsCradle.toml
STRING_L, STRING_V0 = 1.0, 5.5             # modelDescription/StringPendulum.toml
BALLS = range(1, 6)


def _settings(solver: str, h: float, **others) -> dict:
    return {"solver": SOLVERS.index(solver) + 1, "h": h, "tol": 1e-12 if solver == "rkf45" else 0.0, **others}


def _pendulum(phi: float, omega: float, duration: float, L: float) -> np.ndarray:
    """The simple pendulum's equation, integrated here by SciPy to 1e-13."""
    if duration == 0.0:
        return np.array([phi, omega])
    solution = solve_ivp(lambda t, s: [s[1], -G / L * math.sin(s[0])], (0.0, duration), [phi, omega],
                         method="DOP853", rtol=1e-13, atol=1e-14)
    return solution.y[:, -1]


# ---------------------------------------------------------------- Newton's cradle, rigid

QUARTER = ellipk(math.sin(CRADLE_PHI0 / 2) ** 2) * math.sqrt(CRADLE_L / G)  # a quarter of the pendulum's period
IMPACT_SPEED = math.sqrt(2 * G / CRADLE_L * (1 - math.cos(CRADLE_PHI0)))      # omega where the ball strikes


@pytest.fixture(scope="module")
def cradle(fmu_paths):
    def run(solver: str, h: float, stop: float, **starts):
        names = [f"{kind}{i}" for i in BALLS for kind in ("phi", "omega")] + ["E", "n_events"]
        return simulate_fmu(fmu_paths["NewtonsCradle"], stop_time=stop, output_interval=stop / 4,
                            start_values=_settings(solver, h, **starts), output=names)
    return run


@pytest.mark.parametrize("solver", [s for s in FIXED_STEP if s != "stormer_verlet"] + ["rkf45"])
def test_the_cradle_sends_one_ball_out_for_one_in(cradle, solver):
    """Ball 1 strikes the row at the quarter period; ball 5 leaves with its speed, the others stay at rest
    (exactly: the impulses go through the touching balls one contact at a time)."""
    after = 0.1
    run = cradle(solver, 1e-3 if solver not in ("euler", "midpoint", "heun") else 1e-4, QUARTER + after)
    final = {name: run[name][-1] for name in run.dtype.names}
    for i in (1, 2, 3, 4):
        assert abs(final[f"phi{i}"]) < 1e-12 and abs(final[f"omega{i}"]) < 1e-12, (i, final)
    assert final["n_events"] == 4  # one impulse per contact
    expected = _pendulum(0.0, IMPACT_SPEED, after, CRADLE_L)
    accuracy = 1e-9 if solver not in ("euler", "midpoint", "heun", "ab2", "abm2", "implicit_midpoint",
                                      "trapezoid", "rk3", "ab3", "abm3") else 2e-3
    assert abs(final["phi5"] - expected[0]) < accuracy and abs(final["omega5"] - expected[1]) < 10 * accuracy


def test_two_balls_in_send_two_out(cradle):
    run = cradle("rk4", 1e-3, QUARTER + 0.1, phi2=-CRADLE_PHI0)
    final = {name: run[name][-1] for name in run.dtype.names}
    for i in (1, 2, 3):
        assert abs(final[f"phi{i}"]) < 1e-12 and abs(final[f"omega{i}"]) < 1e-12, (i, final)
    expected = _pendulum(0.0, IMPACT_SPEED, 0.1, CRADLE_L)
    for i in (4, 5):
        assert abs(final[f"phi{i}"] - expected[0]) < 1e-9 and abs(final[f"omega{i}"] - expected[1]) < 1e-8


def test_ten_periods_of_the_cradle_come_back_to_the_start_with_its_energy(cradle):
    """The cradle's period is the pendulum's, four quarters: after ten, ball 1 is back where it was let go,
    at rest, and the impacts (restitution 1) have kept the energy to the integration's error."""
    periods = 10
    run = cradle("nystrom5", 5e-4, 4 * QUARTER * periods)
    assert run["phi1"][-1] == pytest.approx(-CRADLE_PHI0, abs=1e-9)
    assert abs(run["omega1"][-1]) < 1e-8
    assert all(abs(run[f"omega{i}"][-1]) < 1e-12 for i in (2, 3, 4, 5))
    assert abs(run["E"][-1] - run["E"][0]) < 1e-10 * abs(run["E"][0])
    assert run["n_events"][-1] == 4 * 2 * periods  # two strikes per period through four contacts


@pytest.mark.parametrize("solver, h, tol", [("rkf45", 1.0, 1e-8), ("gbs", 0.05, 1e-8), ("gbs", 1.0, 1e-10),
                                           ("taylor", 1.0, 1e-9), ("taylor", 1.0, 1e-12)])
def test_adaptive_methods_find_every_impact_however_long_their_steps(fmu_paths, solver, h, tol):
    """One call over the whole period, each accepted step (at most h long) checked for events. gbs and taylor
    take steps of a fifth of the period and more, longer than the time ball 1 takes to pass through ball 2
    (4 R / v, 0.16 s): no gap changes sign between the ends of such a step, and only the gaps' rates there
    (approaching at the start, receding at the end) show the contact inside it."""
    period = 4 * QUARTER
    run = simulate_fmu(fmu_paths["NewtonsCradle"], stop_time=period, output_interval=period,
                       start_values=_settings(solver, h, tol=tol), output=["phi1", "omega1", "phi5", "n_events"])
    assert run["n_events"][-1] == 8
    assert run["phi1"][-1] == pytest.approx(-CRADLE_PHI0, abs=1e-6) and abs(run["omega1"][-1]) < 1e-5
    assert abs(run["phi5"][-1]) < 1e-12


# unstable at h = 0.17 (h omega = 0.97 lies outside their stability regions): their motion is no cradle's there
UNSTABLE_AT_017 = ("euler", "ab2")


@pytest.mark.parametrize("solver, h", [(s, 0.12) for s in FIXED_STEP] +
                         [(s, 0.17) for s in FIXED_STEP if s not in UNSTABLE_AT_017])
def test_fixed_step_methods_find_every_impact_inside_their_steps(fmu_paths, solver, h):
    """Steps of 0.12 s and 0.17 s against the 0.16 s ball 1 takes to pass through ball 2: at the ends of such
    a step ball 1 may be short of ball 2 and past it, with no gap's sign changed; the gaps' rates show the
    contact inside, and the period keeps its eight impacts (without them 13 of these 18 methods lost three or
    four at h = 0.17, rk4 and gauss_legendre4 among them: a ball passed through the row). Ball 5 is back at
    rest; ball 1 back at its start, at rest, where the method's order lets it be at such steps (the rest of a
    step after a contact inside it is taken: a step that ended at the contact lost 0.07 s, and rk4's ball 1
    came back at 1.1 rad/s)."""
    period = 4 * QUARTER
    run = simulate_fmu(fmu_paths["NewtonsCradle"], stop_time=period, output_interval=period,
                       start_values=_settings(solver, h), output=["phi1", "omega1", "phi5", "n_events"])
    assert run["n_events"][-1] == 8
    assert abs(run["phi5"][-1]) < 1e-12 and run["phi1"][-1] < -0.2
    if ORDER[solver] >= 4:  # within 0.05 rad and 0.18 rad/s at h = 0.17 (gauss_legendre4 0.0004 and 0.011)
        assert abs(run["phi1"][-1] + CRADLE_PHI0) < 0.08 and abs(run["omega1"][-1]) < 0.3


# ---------------------------------------------------------------- the string pendulum (Fadenpendel)

def _slack_point():
    """Where the string's tension m (v^2 / L + g cos phi) reaches zero, and when (from the energy)."""
    v0, L = STRING_V0, STRING_L
    phi = math.acos((2 * G - v0 ** 2 / L) / (3 * G))
    omega = lambda a: math.sqrt(v0 ** 2 / L ** 2 - 2 * G / L * (1 - math.cos(a)))  # noqa: E731
    t, _ = quad(lambda a: 1.0 / omega(a), 0.0, phi, epsabs=1e-14, epsrel=1e-14)
    return t, phi, omega(phi)


@pytest.fixture(scope="module")
def string(fmu_paths):
    def run(solver: str, h: float, stop: float):
        return simulate_fmu(fmu_paths["StringPendulum"], stop_time=stop, output_interval=stop / 2,
                            start_values=_settings(solver, h),
                            output=["x", "y", "vx", "vy", "string_gap", "string_force", "n_events"])
    return run


def _flight():
    """The flight after the slack point: a parabola, from a velocity along the circle, until it meets the
    circle again after 4 v_y / g (|r|^2 - L^2 = v_y g t^3 ... vanishes there: the t^2 term is zero where
    the tension is)."""
    t_slack, phi, omega = _slack_point()
    position = STRING_L * np.array([math.sin(phi), -math.cos(phi)])
    velocity = STRING_L * omega * np.array([math.cos(phi), math.sin(phi)])
    return t_slack, position, velocity, 4 * velocity[1] / G


@pytest.mark.parametrize("solver, h, accuracy", [("rk4", 1e-3, 1e-9), ("nystrom5", 2e-3, 1e-9),
                                                 ("ab4", 5e-4, 1e-8), ("heun", 1e-4, 1e-5)])
def test_the_string_goes_slack_where_its_tension_vanishes_and_flies_a_parabola(string, solver, h, accuracy):
    t_slack, position, velocity, flight = _flight()
    tau = 0.6 * flight
    run = string(solver, h, t_slack + tau)
    expected = position + velocity * tau + 0.5 * np.array([0.0, -G]) * tau ** 2
    assert abs(run["x"][-1] - expected[0]) < accuracy and abs(run["y"][-1] - expected[1]) < accuracy
    assert run["string_force"][-1] == 0.0 and run["string_gap"][-1] > 0.0
    assert run["n_events"][-1] == 1  # the release


def test_the_string_jerks_taut_and_swings_on_as_a_pendulum(string):
    """Taut again (restitution 0): the radial velocity is gone, the tangential one swings on."""
    t_slack, position, velocity, flight = _flight()
    end = position + velocity * flight + 0.5 * np.array([0.0, -G]) * flight ** 2
    assert math.hypot(*end) == pytest.approx(STRING_L, abs=1e-12)
    phi = math.atan2(end[0], -end[1])
    tangential = (velocity + np.array([0.0, -G]) * flight) @ np.array([math.cos(phi), math.sin(phi)])
    later = 0.2
    expected = _pendulum(phi, tangential / STRING_L, later, STRING_L)
    run = string("rk4", 1e-3, t_slack + flight + later)
    assert run["n_events"][-1] == 2
    assert run["string_gap"][-1] == pytest.approx(0.0, abs=1e-13)
    assert math.atan2(run["x"][-1], -run["y"][-1]) == pytest.approx(expected[0], abs=1e-8)
    speed = (run["vx"][-1] * math.cos(expected[0]) + run["vy"][-1] * math.sin(expected[0])) / STRING_L
    assert speed == pytest.approx(expected[1], abs=1e-7)


@pytest.mark.parametrize("solver", ["euler", "midpoint", "heun", "ab2", "abm2", "implicit_midpoint", "trapezoid"])
@pytest.mark.parametrize("h", [2e-3, 8e-3])  # 8 ms: the FMU's default step
def test_low_order_methods_leave_the_slack_string_without_hanging(string, solver, h):
    """A first- or second-order step from the slack point ends outside the circle (the exact flight is inside
    by only (v g) t^3): that is the method's error, not a new event, and the call goes on."""
    run = string(solver, h, 2.0)
    assert run["n_events"][-1] >= 2
    assert np.all(np.isfinite(run["x"]))


@pytest.mark.parametrize("h", [8e-3, 4e-3])
def test_euler_leaves_the_slack_string_on_any_grid(fmu_paths, h):
    """Euler's straight step off the circle dips outside it by h^2 v^2 / 2L for several steps after the slack
    point, while the flight's opening rate is still below that dip: each such dip is the method's error, on a
    grid of 0.01 s (FMI 2.0) as on the early returns' grid of FMI 3.0 (once stopped with "an event recurs at
    once"). The string goes slack once and jerks taut once, near the exact times."""
    t_slack, _, _, flight = _flight()
    with FmuInstance(fmu_paths["StringPendulum"]) as fmi2:
        fmi2.initialize(0.0, **_settings("euler", h))
        statuses = [fmi2.do_step(0.01 * k, 0.01) for k in range(150)]
        assert statuses == [0] * 150, fmi2.last_message()
        assert fmi2.get("n_events") == [2]
    with FmuInstance(fmi3_counterpart(fmu_paths["StringPendulum"]), early_return=True) as fmi3:
        fmi3.initialize(0.0, **_settings("euler", h))
        events = event_times(fmi3, np.array([0.0, 1.5]))
    assert events.completed and len(events.times) == 2
    # Euler's error in the event times: first order, about 8 h here
    assert abs(events.times[0] - t_slack) < 10 * h and abs(events.times[1] - (t_slack + flight)) < 10 * h


# ---------------------------------------------------------------- the Hertz cradle

def test_the_hertz_cradle_spreads_the_motion_and_keeps_its_energy(fmu_paths):
    """Steel contacts last about 0.1 ms: rkf45 resolves them, and agrees with rk4 at a step of 2e-7 s.
    Unlike the rigid cradle, the outgoing motion spreads over several balls (ball 1 rebounds a little)."""
    names = [f"omega{i}" for i in BALLS] + ["E"]
    stop = QUARTER + 0.1

    def run(solver, **settings):
        result = simulate_fmu(fmu_paths["HertzCradle"], stop_time=stop, output_interval=stop / 20,
                              start_values={"solver": SOLVERS.index(solver) + 1, **settings}, output=names)
        return np.array([result[name][-1] for name in names]), result["E"][0]

    reference, energy = run("rk4", h=2e-7, tol=0.0)
    adaptive, _ = run("rkf45", h=1e-3, tol=1e-10)
    assert np.max(np.abs(adaptive[:5] - reference[:5])) < 1e-6 * IMPACT_SPEED
    assert abs(reference[5] - energy) < 1e-9 * abs(energy)
    assert reference[0] < -0.01 * IMPACT_SPEED          # ball 1 rebounds
    assert 0.5 * IMPACT_SPEED < reference[4] < IMPACT_SPEED  # ball 5 leaves with most, not all
    assert reference[3] > 0.01 * IMPACT_SPEED           # ball 4 follows


# ---------------------------------------------------------------- the generated equations, independently

@pytest.mark.parametrize("name", ["NewtonsCradle", "StringPendulum", "HertzCradle"])
def test_the_constrained_equations_are_the_numeric_routes(fmu_paths, name):
    """Accelerations, constraint forces, gaps and energies at random states against Lagrange's equations of
    the first kind by finite differences of the file's plain T, U and gaps (harness.objects.numeric_route)."""
    spec = read_object_file(object_file(name))
    proof = numeric_route_agreement(fmu_paths[name], spec, samples=4)
    assert proof.passed, proof.detail


# ---------------------------------------------------------------- the scenes, run and planned

# each scene, and whether its object keeps its energy (restitution 1, no damping) or loses some at impacts
CONTACT_SCENES = {"bouncing_ball": False, "wall_pendulum": False, "string_pendulum": False,
                  "cartesian_pendulum": True, "newtons_cradle": True, "hertz_cradle": True}


@pytest.mark.parametrize("scene, conserves", CONTACT_SCENES.items())
def test_each_contact_scene_runs_and_never_gains_energy(tmp_path, fmu_paths, scene, conserves):
    """Each scene through the master (`harness run`): impacts happen, and the energy never grows; an
    elastic object keeps it."""
    path = PROJECT_ROOT / "scenes" / f"{scene}.json"
    out = tmp_path / "run.csv"
    result = subprocess.run([sys.executable, "-m", "harness", "run", str(path), "--stop", "2", "--out", str(out),
                             "--quiet"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    data = np.genfromtxt(out, delimiter=",", names=True)
    (component,) = json.loads(path.read_text())["components"]
    energy, scale = data[f"{component}E"], max(1.0, abs(data[f"{component}E"][0]))
    if scene != "cartesian_pendulum":  # its rod never lets go: no event
        assert data[f"{component}n_events"][-1] > 0
    if conserves:
        assert np.max(np.abs(energy - energy[0])) < 1e-6 * scale
    else:
        assert np.max(np.diff(energy)) < 1e-9 * scale and energy[-1] < energy[0] - 1e-3 * scale


@pytest.mark.parametrize("scene", [s for s in CONTACT_SCENES if s != "hertz_cradle"])  # hertz: 40 s to plan
def test_scenes_with_impacts_can_be_planned_and_the_plan_holds(fmu_paths, scene):
    """The planner on objects that touch: its verified error meets the tolerance, and the plan is re-checked
    here against an independent run (rkf45 at 1e-12, its events located on its own steps)."""
    assert_the_plan_holds(scene)
