"""Contacts across FMUs at whatever output interval a scene asks for: by default the master lands its macro steps
on the contacts and resolves them in as many steps between two rows as they need, in both loops and both FMI
versions, against the monolithic reference; and any master whose step carries a contact deeper than it can
resolve stops there, naming the contact, the time and a step that would do (harness/cosim/contact_guard.py),
with the rows so far kept."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from harness.cli import main
from harness.cosim.contacts import ContactSteps
from harness.cosim.master import DEFAULT_CONTACT_STEPS, Master, MasterOptions
from harness.cosim.system import load_system
from harness.scene.contact_scenes import ball_row, released_cradle
from harness.studies.monolithic import MonolithicScene

INTERVALS = (1e-5, 1e-4, 1e-3, 1e-2)
GRAVITY = 9.81


def written(tmp_path: Path, data: dict, name: str = "scene.json", fmi3: bool = False) -> Path:
    if fmi3:
        for component in data["components"].values():
            component["fmu"] = "fmi3/" + component["fmu"]
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


cradle = released_cradle


def run(path: Path, native: bool = True, **options):
    with load_system(path) as system:
        with Master(system, MasterOptions(stop=system.stop, step=system.step, **options)) as master:
            master.use_native = native
            result = master.run()
            interval = master.interval
        reference = MonolithicScene(system)
        columns = reference.solve(result.time)
    return result, interval, columns, reference.events


def error_after(result, columns, events, balls: int, after: float = 0.0) -> float:
    """The largest error of the balls' velocities from the first onset on (plus `after`), relative to the
    fastest ball's speed in the reference."""
    rows = result.time >= events[0][0] + after
    speed = max(float(np.max(np.abs(columns[f"ball{k}.v_x"]))) for k in range(1, balls + 1))
    return max(float(np.max(np.abs(result[f"ball{k}.v_x"][rows] - columns[f"ball{k}.v_x"][rows])))
               for k in range(1, balls + 1)) / speed


@pytest.mark.parametrize("interval", INTERVALS)
def test_the_cradle_is_resolved_at_every_output_interval_by_default(tmp_path, interval):
    """At every output interval from 1e-5 to 1e-2 s, with no option given, the master lands on the strike: every
    ball's velocity after it within 1e-3 of the impact speed from the reference (measured 4.5e-5 to 7.3e-5), the
    rows at the scene's interval. Before, a row every millisecond sent balls 1 and 2 apart at 197 m/s, exit 0."""
    result, interval_control, columns, events = run(written(tmp_path, cradle(interval)))
    assert isinstance(interval_control, ContactSteps) and interval_control.per_contact == DEFAULT_CONTACT_STEPS
    assert result.stopped_at is None and len(result.time) == round(0.5 / interval) + 1
    assert np.allclose(np.diff(result.time), interval, rtol=1e-9)
    assert [what for _, _, what in events[:1]] == ["onset"]
    assert error_after(result, columns, events, 5) < 1e-3
    assert result.energy_residual < 1e-3 * 0.057


@st.composite
def rows_of_balls(draw, counts):
    """A row of balls of random radii, masses, stiffness and start angle, at a random output interval, run in the C
    loop or the Python loop with FMI 2.0 or 3.0 FMUs; the run ends 20 ms after the first strike."""
    n = draw(counts)
    radii = [draw(st.floats(0.005, 0.05)) for _ in range(n)]
    masses = [draw(st.floats(0.05, 2.0)) for _ in range(n)]
    length = draw(st.floats(0.2, 1.0))
    angle = -draw(st.floats(0.05, 0.5))
    scale = 10.0 ** draw(st.floats(-4.0, 1.0))
    interval = draw(st.sampled_from(INTERVALS))
    strike = math.pi / 2 * math.sqrt(length / GRAVITY) * 1.02  # a quarter period, the swing's amplitude included
    stop = math.ceil((strike + 0.02) / interval) * interval
    return ball_row(radii, masses, length, angle, scale, stop, interval), draw(st.booleans()), draw(st.booleans())


def check_row(tmp_path: Path, drawn: tuple, bound: float) -> None:
    data, native, fmi3 = drawn
    balls = sum(1 for name in data["components"] if name.startswith("ball"))
    result, _, columns, events = run(written(tmp_path, data, fmi3=fmi3), native)
    assert result.stopped_at is None, result.message
    assert error_after(result, columns, events, balls) < bound, data["description"]
    kinetic = max(float(np.max(columns[f"ball{k}.E_kin"])) for k in range(1, balls + 1))
    assert result.energy_residual < 1e-2 * kinetic


@settings(max_examples=20, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(drawn=rows_of_balls(st.just(2)))
def test_two_balls_of_any_size_mass_and_stiffness_at_any_interval(tmp_path_factory, drawn):
    """Two balls: after the strike the velocities within 1e-3 of the fastest speed from the reference (measured up
    to 3.4e-4 over the two-ball rows of 320 random runs), the energy within 1 per cent of the largest kinetic energy."""
    check_row(tmp_path_factory.mktemp("two"), drawn, 1e-3)


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(drawn=rows_of_balls(st.integers(3, 5)))
def test_rows_of_balls_of_any_size_mass_and_stiffness_at_any_interval(tmp_path_factory, drawn):
    """Rows of three to five balls, each struck in turn through contacts that begin from rest: within 1e-2
    (measured up to 2.3e-3; unequal masses make the row's later strikes sensitive to the first)."""
    check_row(tmp_path_factory.mktemp("row"), drawn, 1e-2)


def test_balls_touching_at_rest_by_a_rounding_are_no_contact(tmp_path):
    """Pivots summed from the radii leave a gap of -1e-18 m between balls that touch at rest: the contact steps read
    it as a contact of no force and no frequency, grew their steps inside it and stepped into the strike blind
    (the balls left at 350 m/s). The Contact's own event rule (an overlap from 1e-13 m on) holds in the control."""
    radii = [0.024748062661021013, 0.028579764574128946, 0.010043161861753585]
    data = ball_row(radii, [1.1047418357732763, 1.9023805073594648, 1.5237657399940063], 0.27692356901671666,
                    -0.3195707896663886, 0.38, 0.286, 1e-3)
    start = data["components"]["contact23"]["start"]
    assert (start["b_x"] - start["a_x"]) - (radii[1] + radii[2]) < 0.0  # the rounding this test is about
    path = written(tmp_path, data)
    for native in (True, False):
        result, _, columns, events = run(path, native)
        assert result.stopped_at is None and error_after(result, columns, events, 3) < 1e-3


@pytest.mark.parametrize("fmi3", [False, True])
def test_both_loops_take_the_same_steps_in_both_fmi_versions(tmp_path, fmi3):
    """The C loop and the Python loop, bit for bit, at an interval of 1e-2 s; FMI 3.0 as FMI 2.0 to 1e-12."""
    path = written(tmp_path, cradle(1e-2), fmi3=fmi3)
    (c, _, columns, events), (py, _, _, _) = run(path, True), run(path, False)
    assert np.array_equal(c.values, py.values) and (c.macro_steps, c.retries) == (py.macro_steps, py.retries)
    assert error_after(c, columns, events, 5) < 1e-3
    if fmi3:
        two, _, _, _ = run(written(tmp_path, cradle(1e-2), "two.json"))
        assert c.macro_steps == two.macro_steps and np.allclose(c.values, two.values, rtol=0, atol=1e-12)


@pytest.mark.parametrize("native", [True, False])
@pytest.mark.parametrize("fmi3", [False, True])
def test_a_step_deep_into_a_contact_stops_the_run_by_name(tmp_path, native, fmi3):
    """Plain macro steps of a millisecond (--contact-steps 0) step 0.24 mm into the strike: the run stops at that
    step's start, naming the contact, the time and a step that would do, with the rows up to there; before, the
    first strike alone created 1.2e4 J in a cradle of 0.057 J and the run went on. Both loops stop alike."""
    path = written(tmp_path, cradle(1e-3), fmi3=fmi3)
    result, _, columns, _ = run(path, native, contact_steps=0)
    with load_system(path) as system:
        scene = MonolithicScene(system)
        scene.solve(np.array([0.0, 0.4]))
        onset = scene.events[0][0]
    assert result.stopped_at is not None and onset - 1e-3 <= result.stopped_at < onset
    assert result.message.startswith(f"contact12: the macro step of 0.001 s from t = {result.stopped_at:.10g} s")
    assert "created" in result.message and "a macro step of at most" in result.message, result.message
    assert result.time[-1] == pytest.approx(result.stopped_at) and np.max(np.abs(result["ball1.v_x"])) < 0.67
    assert error_after(result, columns, [(0.0, "", "")], 5) < 1e-6  # the rows kept are right
    if not native:
        c, _, _, _ = run(written(tmp_path, cradle(1e-3), "c.json", fmi3=fmi3), True, contact_steps=0)
        assert (c.stopped_at, c.message, c.macro_steps) == (result.stopped_at, result.message, result.macro_steps)
        assert np.array_equal(c.values, result.values)


def test_the_step_the_stop_advises_does(tmp_path):
    """The fixed macro step the message advises, taken: the run ends, the velocities after the strike within 1e-2
    of the impact speed."""
    stopped, _, _, _ = run(written(tmp_path, cradle(1e-3)), contact_steps=0)
    advised = float(stopped.message.split("a macro step of at most ")[1].split(" s")[0])
    assert advised < 2e-5
    steps = math.ceil(0.4 / advised)
    result, _, columns, events = run(written(tmp_path, cradle(0.4 / steps, 0.4), "advised.json"), contact_steps=0)
    assert result.stopped_at is None and error_after(result, columns, events, 5, 2e-3) < 1e-2


def test_the_run_command_stops_with_one_line_and_keeps_the_rows(tmp_path, capsys):
    scene = written(tmp_path, cradle(1e-3))
    out = tmp_path / "run.csv"
    assert main(["run", str(scene), "--contact-steps", "0", "--out", str(out), "--quiet"]) == 1
    said = capsys.readouterr()
    assert said.err.count("\n") == 1 and "harness: stopped at t = 0.35" in said.err and "contact12" in said.err
    assert "Traceback" not in said.err
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    assert 350 < len(rows) < 358 and np.all(np.isfinite(rows))
    # the default lands on the contacts and says so
    assert main(["run", str(scene), "--out", str(out), "--quiet"]) == 0
    assert "macro steps landed on the contacts" in capsys.readouterr().out
