"""The derived monolithic reference of scenes of objects joined by Springs: it agrees with a
hand-coded reference and with the exact pendulum, keeps the energy a conservative scene must keep,
and every spring scene's co-simulation converges to it at the coupling's order; `run --reference`
writes it under the run's own column names; what it cannot derive is refused by name."""
from __future__ import annotations

import csv
import dataclasses
import json

import numpy as np
import pytest

from harness.cli import main
from harness.cosim.master import MasterOptions, run_system
from harness.cosim.system import load_system
from harness.errors import HarnessError
from harness.fmi.fmus import PROJECT_ROOT
from harness.objects.thesis.reference import exact_simple_pendulum, slope
from harness.scene.spring_scenes import repository_scenes
from harness.studies.monolithic import MonolithicScene, largest_point_error
from pair_reference import CoupledPair

SCENES = PROJECT_ROOT / "scenes"
SPRING_SCENES = ["coupled_pendulums.json", "pendulums_in_a_row.json", "double_and_cart.json", "spring_chain.json"]


def with_starts(system, **changes: dict):
    """The system with some components' start values changed."""
    return dataclasses.replace(system, components=[
        dataclasses.replace(c, start={**c.start, **changes[c.name]}) if c.name in changes else c
        for c in system.components])


@pytest.mark.parametrize("damped", [False, True])
def test_the_derived_reference_is_the_hand_coded_one(fmu_paths, damped):
    """The coupled pendulums, derived from the object file and the Spring's contract, against their
    equations written out by hand (tests/pair_reference.py); with spring and pendulum damping too."""
    system = load_system(SCENES / "coupled_pendulums.json")
    if damped:
        system = with_starts(system, spring={"c": 0.7}, left={"d": 0.2}, right={"d": 0.05})
    times = np.linspace(0.0, 10.0, 501)
    derived = MonolithicScene(system).solve(times)
    left, right = CoupledPair.from_system(system).reference(times)
    assert np.max(np.abs(derived["left.x"] - left[:, 0])) < 1e-10
    assert np.max(np.abs(derived["right.y"] - right[:, 1])) < 1e-10
    assert np.ptp(derived["right.x"]) > 0.05  # the spring moved the right pendulum


def test_the_pendulum_wave_is_fifteen_exact_pendulums(fmu_paths):
    """Without springs the scene is its pendulums alone: each angle is the exact elliptic solution."""
    system = load_system(SCENES / "pendulum_wave.json")
    scene = MonolithicScene(system)
    times = np.linspace(0.0, 20.0, 201)
    derived = scene.solve(times)
    assert len(system.components) == 15
    for component in system.components:
        phi, _ = exact_simple_pendulum(component.start["phi"], times, L=component.start["L"])
        assert np.max(np.abs(derived[f"{component.name}.phi"] - phi)) < 1e-9, component.name


@pytest.mark.parametrize("scene", SPRING_SCENES)
def test_a_conservative_scene_keeps_its_energy(fmu_paths, scene):
    """The objects' energies plus the springs' potentials stay constant: the springs' forces act at
    the points whose positions they read, as power bonds."""
    system = load_system(SCENES / scene)
    columns = MonolithicScene(system).solve(np.linspace(0.0, 10.0, 1001))
    springs = [c.name for c in system.components if c.fmu.stem == "Spring"]
    objects = [c.name for c in system.components if c.name not in springs]
    total = sum(columns[f"{name}.E"] for name in objects) + sum(columns[f"{name}.E_pot"] for name in springs)
    exchanged = max(np.ptp(columns[f"{name}.E"]) for name in objects)
    assert exchanged > 0.01  # energy did flow between the objects
    assert np.max(np.abs(total - total[0])) < 1e-9 * max(1.0, np.max(np.abs(total)))


@pytest.mark.parametrize("scene", SPRING_SCENES[1:])
def test_every_spring_scene_converges_to_its_reference_at_second_order(fmu_paths, scene):
    """Gauss-Seidel with linear extrapolation, the objects' own method error made negligible
    (nystrom5 at 0.5 ms): the largest point error falls with H squared."""
    system = load_system(SCENES / scene)
    objects = {c.name: {"solver": "nystrom5", "h": 0.0005} for c in system.components if c.fmu.stem != "Spring"}
    system = with_starts(system, **objects)
    steps, errors = [0.04, 0.02, 0.01], []
    scene_equations = MonolithicScene(system)
    reference = scene_equations.solve(np.arange(0, 301) * 0.01)
    for H in steps:
        result = run_system(system, MasterOptions(stop=3.0, step=H, algorithm="gauss-seidel", extrapolation="linear"))
        every = round(H / 0.01)
        errors.append(largest_point_error(result, {k: v[::every] for k, v in reference.items()},
                                          scene_equations.point_columns()))
    assert 1.7 <= slope(steps, errors) <= 2.5, errors
    assert errors[-1] < 1e-3


def test_run_writes_the_reference_under_the_runs_columns(fmu_paths, tmp_path, capsys):
    out, reference = tmp_path / "run.csv", tmp_path / "reference.csv"
    scene = SCENES / "double_and_cart.json"
    assert main(["run", str(scene), "--stop", "2", "--out", str(out), "--reference", str(reference),
                 "--quiet"]) == 0
    assert "derived monolithic reference" in capsys.readouterr().out
    run_rows = list(csv.reader(out.read_text().splitlines()))
    reference_rows = list(csv.reader(reference.read_text().splitlines()))
    header = reference_rows[0]
    # a subsequence of the run's columns: every state and float output, no counters
    assert [c for c in run_rows[0] if c in header] == header
    assert {"time", "double.phi1", "double.omega2", "double.x2", "cart.x", "cart.bob_y", "spring.Fa_x",
            "spring.E_pot"} <= set(header)
    assert not any(c.endswith((".n_rhs", ".n_steps")) for c in header)
    assert len(reference_rows) == len(run_rows) == 202
    run_table = np.array(run_rows[1:], dtype=float)
    reference_table = np.array(reference_rows[1:], dtype=float)
    index = {c: k for k, c in enumerate(run_rows[0])}
    for k, column in enumerate(header):
        assert np.max(np.abs(run_table[:, index[column]] - reference_table[:, k])) < 5e-2, column
    assert np.array_equal(run_table[:, 0], reference_table[:, 0])


@pytest.mark.parametrize("change, words", [
    ("object to object", "joins two objects directly"),
    ("spring to spring", "joins two elements directly"),
    ("linear model", "left.model = 'linear': the monolithic reference is the nonlinear model"),
    ("velocity into a force", "does not lead a Spring's force into a force input"),
])
def test_what_cannot_be_derived_is_refused_before_the_run(fmu_paths, tmp_path, capsys, change, words):
    scene = json.loads((SCENES / "coupled_pendulums.json").read_text())
    scene.pop("bonds")  # the connections change: the bonds are not what is tested here
    if change == "object to object":
        scene["connections"].append(["left.x", "right.F2_x"])
    elif change == "spring to spring":
        scene["components"]["other"] = {"fmu": "Spring"}
        scene["connections"].append(["other.Fa_x", "spring.a_x"])
        scene["connections"] = [c for c in scene["connections"] if c != ["left.x", "spring.a_x"]]
    elif change == "linear model":
        scene["components"]["left"]["start"]["model"] = "linear"
    else:
        scene["connections"] = [["spring.E_pot", "left.F_x"] if c == ["spring.Fa_x", "left.F_x"] else c
                                for c in scene["connections"]]
    path = tmp_path / "changed.json"
    path.write_text(json.dumps(scene))
    out = tmp_path / "run.csv"
    assert main(["run", str(path), "--out", str(out), "--reference", str(tmp_path / "ref.csv"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1, err
    assert not out.exists()  # refused before the run


def test_a_scene_without_energies_is_refused_by_name(fmu_paths, tmp_path):
    """A pendulum FMU that does not carry its object file has no energies to derive from."""
    import zipfile
    bare = tmp_path / "Bare.fmu"
    with zipfile.ZipFile(fmu_paths["SimplePendulum"]) as source, zipfile.ZipFile(bare, "w") as target:
        for item in source.infolist():
            if not item.filename.endswith(".toml"):
                target.writestr(item, source.read(item))
    system = load_system(SCENES / "coupled_pendulums.json")
    broken = dataclasses.replace(system, components=[
        dataclasses.replace(c, fmu=bare) if c.name == "left" else c for c in system.components])
    with pytest.raises(HarnessError, match=r"left .Bare.fmu. is neither an element \(Spring, Contact\) "
                                           r"nor made from an object file"):
        MonolithicScene(broken)


def test_the_spring_scene_files_are_what_their_rules_write():
    for name, data in repository_scenes().items():
        assert json.loads((SCENES / name).read_text()) == data, name


def test_a_reference_that_cannot_be_written_leaves_the_out_file_alone(fmu_paths, tmp_path, capsys, monkeypatch):
    """The reference is written before the run: when it cannot be (a full disk, a read-only folder),
    the command stops with one line and the --out file is not touched; an empty name is refused."""
    import harness.cli
    out, reference = tmp_path / "run.csv", tmp_path / "ref.csv"
    out.write_text("kept\n")

    def full_disk(*arguments):
        raise HarnessError(f"{reference}: cannot write here: No space left on device")
    monkeypatch.setattr(harness.cli, "write_reference", full_disk)
    scene = str(SCENES / "coupled_pendulums.json")
    assert main(["run", scene, "--stop", "0.1", "--out", str(out), "--reference", str(reference), "--quiet"]) == 2
    assert "No space left" in capsys.readouterr().err and out.read_text() == "kept\n"
    assert main(["run", scene, "--stop", "0.1", "--out", str(out), "--reference", "", "--quiet"]) == 2
    assert "--reference '': names no file" in capsys.readouterr().err and out.read_text() == "kept\n"
