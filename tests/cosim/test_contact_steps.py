"""The master that sees impacts (harness/cosim/contacts.py): macro steps landed on the onsets of the
Contact elements' contacts and sized for their duration, against the monolithic reference, which locates
the same onsets as events of one system of equations."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from harness.cosim.algorithm_registry import NAMES as ALGORITHM_NAMES
from harness.cli import main
from harness.cosim.contacts import ContactSteps
from harness.cosim.master import Master, MasterOptions, run_system
from harness.cosim.system import load_system
from harness.errors import HarnessError
from harness.objects.registry import PROJECT_ROOT
from harness.scene.contact_scenes import pendulum_cradle
from harness.studies.monolithic import MonolithicScene

STOP = 0.004


@pytest.fixture(scope="module")
def strike(tmp_path_factory):
    """The cradle of five pendulum FMUs with ball 1 0.6 mm from ball 2, coming at 0.9 m/s: the strike
    begins at 0.67 ms and has left the row by 1.2 ms. Its reference at the communication points."""
    data = pendulum_cradle(5, angle=-0.002, stop=STOP, step=STOP / 4)
    data["components"]["ball1"]["start"]["omega"] = 3.0
    path = tmp_path_factory.mktemp("strike") / "strike.json"
    path.write_text(json.dumps(data))
    system = load_system(path)
    scene = MonolithicScene(system)
    reference = scene.solve(np.linspace(0.0, STOP, 5))
    return system, reference, scene.events


def rate_error(result, reference) -> float:
    """The largest error of the balls' rates at the end, relative to the fastest ball's rate."""
    rates = np.array([reference[f"ball{k}.omega"][-1] for k in range(1, 6)])
    return float(max(abs(result[f"ball{k}.omega"][-1] - rates[k - 1]) for k in range(1, 6)) / np.max(np.abs(rates)))


def test_the_steps_land_on_the_strike_and_resolve_it(strike):
    """100 steps per contact: the balls' rates after the strike within 1e-4 of the reference, in fewer than
    1,500 macro steps, where the fixed-step master with as many steps errs five times more (measured: 9
    times); the strike's onset met by a landed step's end within 1e-8 s (a hundredth of a contact step)."""
    system, reference, events = strike
    with Master(system, MasterOptions(stop=STOP, step=STOP / 4, contact_steps=100)) as master:
        result = master.run()
        landed = master.interval.landed
    assert isinstance(master.interval, ContactSteps)
    error = rate_error(result, reference)
    assert error < 1e-4 and result.macro_steps < 1500, (error, result.macro_steps)
    fixed = run_system(system, MasterOptions(stop=STOP, step=STOP / result.macro_steps, contact_steps=0))
    assert fixed.macro_steps == result.macro_steps and rate_error(fixed, reference) > 5 * error
    onsets = [t for t, _, what in events if what == "onset"]
    assert len(onsets) == 4
    # The strike lands on ball 2; the other onsets begin from balls that touch at rest (gap 0), inside the
    # strike's contact steps, as each ball starts to move.
    assert min(abs(onsets[0] - s) for s in landed) < 1e-8, (onsets, landed)


def test_more_steps_per_contact_converge_at_second_order(strike):
    """Linear extrapolation couples at second order: doubling the steps per contact divides the error by
    about four (three to six; measured 3.65 and 3.31). From 100 steps per contact on: below, the balls that touch
    at rest enter their contacts within a step of the strike's (measured 2.7e-4 at 25, 1.4e-4 at 50)."""
    system, reference, _ = strike
    errors = [rate_error(run_system(system, MasterOptions(stop=STOP, step=STOP / 4, contact_steps=n)), reference)
              for n in (100, 200, 400)]
    assert all(3 < a / b < 6 for a, b in zip(errors, errors[1:])), errors


def test_a_failed_prediction_is_rolled_back_onto_the_onset(strike, monkeypatch):
    """A plan that steps 50 us past an onset (as a prediction that failed would): the step is rolled back
    through the FMU states, the approach lands on the onset to 1e-8 s all the same, and the run keeps its
    accuracy."""
    system, reference, events = strike
    onset = events[0][0]
    planned = ContactSteps._planned
    faulted = {"done": False}

    def overshooting(self, state, room):
        step, touching = planned(self, state, room)
        if not touching and not faulted["done"] and any(g / -r < 5e-5 for g, r, _ in state if r < 0):
            faulted["done"] = True
            return min(room, 5e-5 + min(g / -r for g, r, _ in state if r < 0)), touching
        return step, touching

    monkeypatch.setattr(ContactSteps, "_planned", overshooting)
    with Master(system, MasterOptions(stop=STOP, step=STOP / 4, contact_steps=100)) as master:
        master.use_native = False  # the plan planted is the Python loop's
        result = master.run()
        landings, landed = master.interval.landings, master.interval.landed
    assert faulted["done"] and landings >= 1 and result.retries == landings
    assert rate_error(result, reference) < 1e-4
    assert min(abs(onset - s) for s in landed) < 1e-8


def test_a_system_without_contacts_is_refused_by_name(capsys, tmp_path):
    out = tmp_path / "run.csv"
    assert main(["run", str(PROJECT_ROOT / "scenes" / "coupled_pendulums.json"), "--contact-steps", "50",
                 "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "no component with the outputs gap and gap_rate" in err and err.count("\n") == 1, err
    assert not out.exists()


def test_contact_steps_choose_the_steps_alone():
    with pytest.raises(HarnessError, match="does not combine with --tolerance"):
        MasterOptions(stop=1.0, step=0.1, contact_steps=10, tolerance=1e-3)
    with pytest.raises(HarnessError, match="from 1 to 100000, or 0 for plain macro steps"):
        MasterOptions(stop=1.0, step=0.1, contact_steps=-1)
    with pytest.raises(HarnessError, match="does not combine with --on-discard retry"):
        MasterOptions(stop=1.0, step=0.1, contact_steps=10, on_discard="retry")


@pytest.fixture(scope="module")
def contact_chart(tmp_path_factory):
    out = tmp_path_factory.mktemp("contacts")
    assert main(["chart", "contacts", "--quick", "--repeats", "1", "--stop", "0.3", "--out", str(out)]) == 0
    from harness.studies.contact_study import read_csv
    return out, read_csv(out / "contacts.csv")


def test_the_contact_chart_shows_what_its_page_claims(contact_chart):
    """On the cradle up to just past the strike: the impact-aware master at 100 steps per contact errs less
    than the best fixed-step master at 2e-6 s, with a hundredth of its macro steps; held inputs err at first
    order (a tenth and more); the energy correction keeps the energy created per onset below 1e-6; the
    energy step control lands on the contacts and sizes them by the energy created: below 1e-6 per onset and
    an error below 1e-4 (measured: 2.4e-8 and 4.6e-7 at 1e-3 J), in a thirtieth of the macro steps of the
    fixed step at 2e-6 s (measured: 3,778 against 150,000, which err 2e-4)."""
    out, points = contact_chart
    assert {(out / f"contacts.{suffix}").is_file() for suffix in ("csv", "png", "svg")} == {True}
    run = {(p.master, p.setting): p for p in points}
    aware = run["contact steps", "N = 100"]
    fixed = run["fixed step, gauss-seidel, linear", "H = 2e-06 s"]
    assert aware.error < fixed.error and 100 * aware.macro_steps < fixed.macro_steps
    assert run["fixed step, gauss-seidel, hold", "H = 2e-06 s"].error > 0.01
    assert abs(run["contact steps, energy correction", "N = 100"].per_onset) < 1e-6
    energy = run["energy step control", "0.001 J"]
    assert energy.error < 1e-4 and abs(energy.per_onset) < 1e-6 and 30 * energy.macro_steps < fixed.macro_steps


def test_fmi3_components_take_the_contact_steps_as_fmi2_ones(strike, tmp_path):
    """The strike with FMI 3.0 FMUs: they ask for their inputs at each step's end (FMI 3.0 has no input
    derivatives), so the inputs vary linearly as FMI 2.0's do, and the control takes the same macro steps to the
    same numbers and converges at second order too (the error falls about 4 times per doubling of the steps per
    contact); held, it couples at first order (the error halves)."""
    system, reference, _ = strike
    path = tmp_path / "strike3.json"
    data = json.loads(Path(system.origin).read_text())
    for component in data["components"].values():
        component["fmu"] = "fmi3/" + component["fmu"]
    path.write_text(json.dumps(data))
    newer = load_system(path)
    errors = {"linear": [], "hold": []}
    for n in (100, 200):
        for extrapolation in errors:
            three = run_system(newer, MasterOptions(stop=STOP, step=STOP / 4, contact_steps=n,
                                                    extrapolation=None if extrapolation == "linear" else "hold"))
            two = run_system(system, MasterOptions(stop=STOP, step=STOP / 4, contact_steps=n,
                                                   extrapolation=extrapolation))
            assert three.extrapolation == extrapolation and three.macro_steps == two.macro_steps
            assert np.allclose(three.values, two.values, rtol=0, atol=1e-12)
            errors[extrapolation].append(rate_error(three, reference))
    assert errors["linear"][0] / errors["linear"][1] > 3.5, errors
    assert 1.7 < errors["hold"][0] / errors["hold"][1] < 2.3 and errors["hold"][0] < 0.03, errors
    assert errors["linear"][0] < errors["hold"][0] / 10, errors


def dropped_cradle(tmp_path: Path, fmi3: bool = False):
    """The cradle with ball 1 released from rest 0.05 rad out, at a communication interval of 0.5 s: the first
    steps see no closing gap (the rate is zero), so the fall overshoots the onset and is rolled back."""
    data = pendulum_cradle(5, angle=-0.05, stop=1.0, step=0.5)
    if fmi3:
        for component in data["components"].values():
            component["fmu"] = "fmi3/" + component["fmu"]
    path = tmp_path / f"dropped{3 if fmi3 else 2}.json"
    path.write_text(json.dumps(data))
    return load_system(path)


def both_loops(system, **options) -> list[tuple]:
    """The run in the C loop, then in the Python loop: the result, the landed onsets, the rollbacks and the FMU
    states left unreleased."""
    runs = []
    for native in (True, False):
        with Master(system, MasterOptions(stop=system.stop, step=system.step, **options)) as master:
            master.use_native = native
            result = master.run()
            runs.append((result, master.interval.landed, master.interval.landings,
                         sum(unit.live_states for unit in master.units)))
    return runs


@pytest.mark.parametrize("algorithm", ALGORITHM_NAMES)
def test_the_c_loop_takes_the_python_loops_contact_steps(strike, tmp_path, algorithm):
    """The contact steps in C (harness/cosim/native/cosim_core.c) give the Python loop's numbers bit for bit:
    the strike, and a fall whose onset the prediction misses, rolled back (four times) in FMI 2.0 and 3.0
    alike; every FMU state saved is released. (With FMI 3.0's held inputs the fall's first prediction sees no
    rate and the element no motion within a step: the ball ends 14 mm inside its neighbour, a contact the
    steps cannot resolve; where a run stops on it, both loops stop alike, by the same words.)"""
    system = strike[0]
    for scene, options in ((system, {}), (dropped_cradle(tmp_path), {}),
                           (dropped_cradle(tmp_path, fmi3=True), {})):
        (c, c_landed, c_landings, c_live), (py, py_landed, py_landings, py_live) = both_loops(
            scene, contact_steps=50, algorithm=algorithm, **options)
        assert np.array_equal(c.values, py.values) and np.array_equal(c.energy, py.energy, equal_nan=True)
        assert (c.macro_steps, c.retries, c_landed, c_landings) == (py.macro_steps, py.retries, py_landed, py_landings)
        assert c_live == py_live == 0
        assert (c.stopped_at, c.message) == (py.stopped_at, py.message)
        if c.extrapolation == "linear":
            assert c.stopped_at is None
            if scene is not system:
                assert c_landings >= 2 and c.retries == c_landings, c_landings


def test_a_step_cut_by_the_interval_end_does_not_shrink_the_next(tmp_path):
    """Apart, the carts take one macro step per communication interval, also where the time's rounding leaves
    the last step of an interval one rounding short of its end (from 0.5 s on, at 1e-5 s: before, each such
    step restarted the growth from 1e-16 s, ten times the steps)."""
    system = load_system(PROJECT_ROOT / "scenes" / "colliding_carts.json")
    result = run_system(system, MasterOptions(start=0.5, stop=0.6, step=system.step, contact_steps=20))
    intervals = len(result.values) - 1
    assert intervals == 10_000 and result.macro_steps <= intervals + 100, result.macro_steps


def test_an_onset_missed_by_a_rounding_is_kept_at_the_landing_precision(strike, monkeypatch):
    """A step that overshoots an onset the secant puts 1e-20 s ahead (a grazing contact) is redone no shorter
    than a thousandth of a contact step, and kept: the run goes on, no step below that."""
    system = strike[0]
    steps = []
    taken, overshoot = ContactSteps._landed_step, ContactSteps._overshoot

    def recording(self, t, step, last, state):
        out = taken(self, t, step, last, state)
        steps.append((out[0], self.contact_step))
        return out

    def grazing(self, before, step):  # the first step's overshoot, as a grazing contact's
        return 1e-20 if not steps else overshoot(self, before, step)

    monkeypatch.setattr(ContactSteps, "_overshoot", grazing)
    monkeypatch.setattr(ContactSteps, "_landed_step", recording)
    with Master(system, MasterOptions(stop=STOP, step=STOP / 4, contact_steps=20)) as master:
        master.use_native = False
        result = master.run()
    assert result.stopped_at is None and result.retries == 1
    first, contact_step = steps[0]
    assert first == contact_step * 1e-3, steps[0]


def test_the_energy_step_control_lands_on_contacts_and_sizes_them_by_energy(strike):
    """--energy-tolerance on a scene with contacts lands on each onset and keeps every step within the energy
    controller's: the strike's rates within 1e-4 of the reference and the energy created below the tolerance
    (measured: 1e-3 J: 499 steps, 9e-9 J; 1e-4 J: 1,398 steps, error 2.9e-6, 4e-8 J). Before, the control
    stepped into the strike blind and the balls left with 1e3 times their energy."""
    system, reference, events = strike
    for tolerance in (1e-3, 1e-4):
        with Master(system, MasterOptions(stop=STOP, step=STOP / 4, energy_tol=tolerance)) as master:
            result = master.run()
            landed = master.interval.landed
        assert isinstance(master.interval, ContactSteps) and result.stopped_at is None
        created = abs(result.energy[-1] - result.energy[0])
        assert rate_error(result, reference) < 1e-4 and created < tolerance, (tolerance, created)
        assert min(abs(events[0][0] - s) for s in landed) < 1e-8
    # with steps per contact too, each step is the shorter of the two
    both = run_system(system, MasterOptions(stop=STOP, step=STOP / 4, energy_tol=1e-4, contact_steps=50))
    assert both.macro_steps >= result.macro_steps and rate_error(both, reference) < 1e-4


def test_the_run_command_says_the_energy_steps_landed_on_the_contacts(strike, tmp_path, capsys):
    out = tmp_path / "run.csv"
    assert main(["run", str(strike[0].origin), "--energy-tolerance", "1e-3", "--out", str(out), "--quiet"]) == 0
    said = capsys.readouterr().out
    assert "macro steps chosen by the bonds' energy and landed on the contacts" in said, said
    assert len(out.read_text().splitlines()) == 1 + 5  # the header and the strike's five communication points
