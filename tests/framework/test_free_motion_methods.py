"""taylor and stormer_verlet on objects that touch: both are built on the free equations (their Taylor
series; their split into a(q) - d v), which hold between contacts. They integrate an object whose constraints
are rigid and unilateral while none acts, and stop with a message where one would have to (a taut string, a
ball come to rest); an object whose constraints always act (a rod, Hertz contacts) refuses them. Checked here
against solutions derived independently: the pendulum equation with the wall as SciPy's event, the textbook
cradle, and the bouncing ball's geometric series."""
from __future__ import annotations

import math

import numpy as np
import pytest
from fmpy import simulate_fmu

from harness.errors import HarnessError
from harness.fmi.events import event_times, fmi3_counterpart
from harness.fmi.fmu_instance import DISCARD, ERROR, FmuInstance, accepted_methods
from harness.fmi.methods import SOLVERS
from test_constraints import _bounces, _wall_reference
from test_contact_objects import CRADLE_PHI0, QUARTER

FREE = ("taylor", "stormer_verlet")


def _settings(solver: str, h: float, tol: float = 0.0, **others) -> dict:
    return {"solver": SOLVERS.index(solver) + 1, "h": h, "tol": tol, **others}


@pytest.mark.parametrize("name, accepted", [("NewtonsCradle", FREE), ("WallPendulum", FREE), ("BouncingBall", FREE),
                                            ("StringPendulum", ()), ("CartesianPendulum", ()), ("HertzCradle", ())])
def test_who_takes_the_free_motion_methods(fmu_paths, name, accepted):
    """Taken where every constraint is rigid and unilateral and none acts at the default start; the string
    pendulum's string is taut there, a rod and Hertz contacts always act."""
    assert set(FREE) & set(accepted_methods(str(fmu_paths[name]))) == set(accepted)


@pytest.mark.parametrize("name, message", [
    ("CartesianPendulum", "(taylor) needs Taylor recurrences for every function of the equations, and "
                          "CartesianPendulum's constraint rod acts with forces, which its series do not hold"),
    ("HertzCradle", "HertzCradle's constraints contact12, contact23, contact34, contact45 act with forces")])
def test_constraints_that_always_act_refuse_taylor_by_name(fmu_paths, name, message):
    with FmuInstance(fmu_paths[name]) as instance:
        assert instance.set(solver="taylor") == ERROR
        assert message in instance.last_message()


def test_a_taut_string_at_the_start_refuses_them_at_initialization(fmu_paths):
    for method in FREE:
        with FmuInstance(fmu_paths["StringPendulum"]) as instance:
            with pytest.raises(HarnessError):
                instance.initialize(0.0, solver=method)
            assert (f"constraint string acts at the start (resting or taut), and {method} integrates free motion "
                    "only") in instance.last_message()


def test_the_cradle_with_taylor_is_the_textbook_cradle(fmu_paths):
    """One ball in, one ball out, and back: after a period (one call, tol 1e-12) ball 1 is at rest at its
    start and the others hang still; the eight impacts are found; the energy is kept."""
    period = 4 * QUARTER
    with FmuInstance(fmu_paths["NewtonsCradle"]) as cradle:
        cradle.initialize(0.0, **_settings("taylor", 0.05, 1e-12))
        energy = cradle.get("E")[0]
        assert cradle.do_step(0.0, period) == 0, cradle.last_message()
        state = cradle.get(*[f"phi{i}" for i in range(1, 6)], *[f"omega{i}" for i in range(1, 6)])
        assert cradle.get("n_events") == [8]
        assert np.max(np.abs(np.subtract(state, [-CRADLE_PHI0] + [0.0] * 9))) < 1e-9
        assert abs(cradle.get("E")[0] / energy - 1) < 1e-12


@pytest.mark.parametrize("method, settings, steps, order", [
    ("taylor", {"taylor_order": 4}, (0.02, 0.01, 0.005), 4),
    ("taylor", {"taylor_order": 6}, (0.05, 0.025, 0.0125), 6),
    ("stormer_verlet", {}, (0.004, 0.002, 0.001), 2)])
def test_their_order_holds_through_impacts(fmu_paths, method, settings, steps, order):
    """The wall pendulum over three impacts against the pendulum equation with the wall as SciPy's event."""
    reference, impacts = _wall_reference(3.0)
    errors = []
    for h in steps:
        result = simulate_fmu(fmu_paths["WallPendulum"], stop_time=3.0, output_interval=0.5,
                              start_values=_settings(method, h, **settings), output=["phi", "omega", "n_events"])
        assert result["n_events"][-1] == len(impacts)
        errors.append(abs(result["phi"][-1] - reference[0]) + abs(result["omega"][-1] - reference[1]))
    measured = math.log2(errors[1] / errors[2])
    assert abs(measured - order) < 0.3, (errors, measured)


def test_taylor_finds_the_impact_times(fmu_paths):
    """FMI 3.0's early returns with taylor (tol 1e-12): the wall pendulum's eight impacts in 10 s within 1e-11 s."""
    _, impacts = _wall_reference(10.0)
    with FmuInstance(fmi3_counterpart(fmu_paths["WallPendulum"]), early_return=True) as pendulum:
        pendulum.initialize(0.0, **_settings("taylor", 0.1, 1e-12))
        events = event_times(pendulum, np.array([0.0, 10.0]))
    assert events.completed and len(events.times) == len(impacts) == 8
    assert np.max(np.abs(np.subtract(events.times, impacts))) < 1e-11


@pytest.mark.parametrize("method, settings", [("taylor", {"tol": 1e-12}), ("stormer_verlet", {})])
def test_a_ball_coming_to_rest_stops_them_there_with_the_reason(fmu_paths, method, settings):
    """The ball bounces along the geometric series; where it comes to rest on its floor (the constraint acts),
    the call ends there (fmi2Discard, last successful time the rest) and says why; nothing is lost."""
    _, _, landing = _bounces()  # where the last rebound faster than the rest speed lands: rest
    with FmuInstance(fmu_paths["BouncingBall"]) as ball:
        ball.initialize(0.0, **_settings(method, 1e-3 if method == "stormer_verlet" else 0.05, **settings))
        assert ball.do_step(0.0, landing + 1.0) == DISCARD
        rest = ball.last_successful_time()
        message = ball.last_message()
        assert "constraint floor acts from t = " in message and f"and {method} integrates free motion only" in message
        assert rest == pytest.approx(landing, abs=1e-8 if method == "taylor" else 1e-4)
        assert ball.get("y")[0] == pytest.approx(0.1, abs=1e-9)


def test_the_accepted_methods_are_asked_once_per_version_of_the_file(fmu_paths, tmp_path, monkeypatch):
    """A sweep asks per case and method; the FMU is asked once, and again only when the file changes."""
    import os
    import shutil

    import harness.fmi.fmu_instance as fmu_instance
    made = []
    original = fmu_instance.FmuInstance.__init__

    def counted(self, *arguments, **options):
        made.append(arguments[0])
        original(self, *arguments, **options)
    monkeypatch.setattr(fmu_instance.FmuInstance, "__init__", counted)
    fmu = tmp_path / "Pendulum.fmu"
    shutil.copy(fmu_paths["SimplePendulum"], fmu)
    first = accepted_methods(fmu)
    assert accepted_methods(str(fmu)) == first and "stormer_verlet" in first
    assert len(made) == 1
    shutil.copy(fmu_paths["DoublePendulum"], fmu)  # a mass matrix that is not constant: no stormer_verlet
    os.utime(fmu, ns=(os.stat(fmu).st_atime_ns, os.stat(fmu).st_mtime_ns + 1_000_000_000))
    assert "stormer_verlet" not in accepted_methods(fmu) and len(made) == 2
