"""Scenes of objects that touch across FMUs (Contact elements) and their monolithic reference: the
reference against the same physics as one object (the HertzCradle FMU, whose contacts are generated from
its object file and integrated with its own event handling), its energy, its events, and the scene
files against their rules."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from harness.cosim.master import MasterOptions, run_system
from harness.cosim.system import load_system
from harness.errors import HarnessError
from harness.fmi.fmu_instance import FmuInstance
from harness.objects.registry import PROJECT_ROOT
from harness.scene.contact_scenes import pendulum_cradle, repository_scenes
from harness.studies.monolithic import MonolithicScene

SCENES = PROJECT_ROOT / "scenes"


def scene_system(tmp_path, data: dict, name: str = "scene.json"):
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return load_system(path)


def test_the_contact_scene_files_are_what_their_rules_write():
    for name, data in repository_scenes().items():
        assert json.loads((SCENES / name).read_text()) == data, name


@pytest.mark.parametrize("solver", ["rkf45", "gbs"])
def test_the_reference_of_five_pendulum_fmus_is_the_single_object_cradle(fmu_paths, solver):
    """The cradle of five SimplePendulum FMUs and four Contacts, as one system of equations (lambdified from
    the pendulum's object file, the Hertz law written in Python), against the HertzCradle FMU (one object,
    its contacts generated C) at tol 1e-12: every ball's angle and rate after the strike within 1e-9 rad
    and 1e-8 rad/s, and as many contact onsets and ends as the object counts events."""
    system = load_system(SCENES / "contact_cradle.json")
    scene = MonolithicScene(system)
    columns = scene.solve(np.linspace(0.0, 0.5, 51))
    with FmuInstance(fmu_paths["HertzCradle"]) as cradle:
        cradle.initialize(solver=solver, tol=1e-12)
        assert cradle.do_step(0.0, 0.5) == 0
        angles = cradle.get(*(f"phi{k}" for k in range(1, 6)))
        rates = cradle.get(*(f"omega{k}" for k in range(1, 6)))
        events = cradle.get("n_events")[0]
    for k in range(5):
        assert columns[f"ball{k + 1}.phi"][-1] == pytest.approx(angles[k], abs=1e-9)
        assert columns[f"ball{k + 1}.omega"][-1] == pytest.approx(rates[k], abs=1e-8)
    assert rates[4] > 0.8 and rates[3] > 0.05  # the motion spread over the last balls, as a real cradle's does
    assert len(scene.events) == events == 8
    # the strike travels along the row: each contact begins after the one before it
    onsets = [(t, name) for t, name, what in scene.events if what == "onset"]
    assert [name for _, name in onsets] == ["contact12", "contact23", "contact34", "contact45"]
    assert all(a[0] < b[0] for a, b in zip(onsets, onsets[1:]))


def test_the_reference_keeps_the_energy_through_a_contact(tmp_path):
    """Two balls, no damping: the pendulums' energies and the energy stored in the contact add up to the
    start's to 1e-10 J at every grid point, also the points inside the 0.14 ms the balls touch."""
    system = scene_system(tmp_path, pendulum_cradle(2, stop=0.4))
    scene = MonolithicScene(system)
    times = np.concatenate([np.linspace(0.0, 0.279, 280), np.linspace(0.27904, 0.27920, 17), [0.3, 0.4]])
    columns = scene.solve(times)
    total = columns["ball1.E"] + columns["ball2.E"] + columns["contact12.E_pot"]
    assert np.max(columns["contact12.E_pot"]) > 1e-3  # points inside the contact were met
    assert np.max(np.abs(total - total[0])) < 1e-10
    assert [what for _, _, what in scene.events] == ["onset", "end"]


def test_a_contact_with_its_centres_at_one_point_is_refused_by_name(tmp_path):
    data = pendulum_cradle(2)
    data["components"]["ball2"]["start"]["anchor_x"] = data["components"]["ball1"]["start"]["anchor_x"]
    data["components"]["ball1"]["start"]["phi"] = 0.0
    with pytest.raises(HarnessError, match="a Contact has both centres at one point"):
        MonolithicScene(scene_system(tmp_path, data)).solve(np.linspace(0.0, 0.1, 3))


def test_a_contact_fed_by_something_else_than_positions_is_refused_by_name(tmp_path):
    system = load_system(SCENES / "contact_cradle.json")
    connections = [dataclasses.replace(c, output="rod_tension") if c.input == "a_x" and c.target == "contact12" else c
                   for c in system.connections]
    with pytest.raises(HarnessError, match="does not lead a position or velocity into a Contact"):
        MonolithicScene(dataclasses.replace(system, connections=connections))


def test_an_object_with_constraints_of_its_own_is_refused_by_name(tmp_path):
    """The reference is Lagrange's equations of the second kind: an object that carries its own contacts (the
    rigid cradle) would pass through them there, so it is refused, naming its constraints."""
    data = {"name": "one rigid cradle", "stop": 0.1, "step": 0.01,
            "components": {"cradle": {"fmu": "NewtonsCradle"}}, "connections": []}
    with pytest.raises(HarnessError, match=r"cradle \(NewtonsCradle.fmu\) has constraints of its own \(contact12, "):
        MonolithicScene(scene_system(tmp_path, data))


@pytest.mark.parametrize("scene, columns, bound", [
    ("colliding_carts.json", ("left.v", "right.v", "left.omega", "right.omega"), 3e-4),
    # the double pendulum is chaotic: 0.9 s after the strike its rates have grown the strike's error tenfold
    ("double_strikes_ball.json", ("double.omega1", "double.omega2", "ball.omega"), 2e-3)])
def test_the_other_contact_scenes_meet_their_references(scene, columns, bound):
    """The impact-aware master (100 steps per contact) against each scene's monolithic reference at its end,
    relative to the largest of the compared rates; the struck ball's string stays taut throughout (its
    tension above 1 N), so a rod models it exactly."""
    system = load_system(SCENES / scene)
    reference = MonolithicScene(system).solve(np.linspace(0.0, system.stop, 3))
    result = run_system(system, MasterOptions(stop=system.stop, step=0.01, contact_steps=100))
    scale = max(abs(reference[c][-1]) for c in columns)
    assert max(abs(result[c][-1] - reference[c][-1]) for c in columns) < bound * scale
    assert result.macro_steps < 1000
    if "ball.rod_tension" in result.columns:
        assert np.min(result["ball.rod_tension"]) > 1.0


def test_the_coupling_chart_sends_a_contact_scene_to_the_contact_chart(capsys, tmp_path):
    from harness.cli import main
    assert main(["chart", "coupling", "--scene", str(SCENES / "contact_cradle.json"), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "step over: chart it with `harness chart contacts`" in err and err.count("\n") == 1, err
    assert not (tmp_path / "coupling.csv").exists()
