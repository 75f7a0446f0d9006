"""`harness export SCENE --ssp FILE`: any scene written back as an SSP 1.0 archive that fmpy's schema
check accepts and that runs to the same bits as the scene itself, power bonds and step included, and
is looked at as the scene is (camera, traces, description)."""
from __future__ import annotations

import zipfile

import numpy as np
import pytest

from harness.cli import main
from harness.cosim.master import MasterOptions, run_system
from harness.cosim.system import load_system
from harness.fmi.fmus import PROJECT_ROOT

SCENES = PROJECT_ROOT / "scenes"


@pytest.mark.parametrize("scene", ["pendulums_in_a_row", "double_and_cart", "spring_chain", "pendulum_wave",
                                   "coupled_pendulums", "thesis_scene"])
def test_an_exported_scene_runs_to_the_same_bits(fmu_paths, tmp_path, capsys, scene):
    archive = tmp_path / f"{scene}.ssp"
    assert main(["export", str(SCENES / f"{scene}.json"), "--ssp", str(archive)]) == 0
    assert f"wrote {archive}" in capsys.readouterr().out
    with load_system(SCENES / f"{scene}.json") as original, load_system(archive) as exported:
        assert [c.name for c in exported.components] == [c.name for c in original.components]
        assert exported.connections == original.connections
        assert exported.bonds == original.bonds
        assert (exported.stop, exported.step) == (original.stop, original.step)
        # how the scene is looked at (harness view): its camera, traces and description
        assert exported.camera == original.camera and exported.description == original.description
        assert {k: [tuple(p) for p in v] for k, v in exported.traces.items()} == \
            {k: [tuple(p) for p in v] for k, v in original.traces.items()}
        options = MasterOptions(stop=min(2.0, original.stop), step=original.step, algorithm="gauss-seidel",
                                energy_correction=bool(original.bonds))
        a, b = run_system(original, options), run_system(exported, options)
        assert a.columns == b.columns
        assert np.array_equal(a.values, b.values)
    with zipfile.ZipFile(archive) as members:
        names = members.namelist()
    # each FMU once, however many components use it
    assert sorted(n for n in names if n.startswith("resources/")) == \
        sorted({f"resources/{c.fmu.name}" for c in load_system(SCENES / f"{scene}.json").components})


def test_an_existing_archive_is_replaced_and_other_files_are_refused(fmu_paths, tmp_path, capsys):
    archive = tmp_path / "row.ssp"
    scene = str(SCENES / "pendulums_in_a_row.json")
    assert main(["export", scene, "--ssp", str(archive)]) == 0
    assert main(["export", scene, "--ssp", str(archive)]) == 0  # exporting again replaces it
    assert main(["export", scene, "--ssp", str(tmp_path / "row.zip")]) == 2
    assert "must end in .ssp" in capsys.readouterr().err
    assert main(["export", str(archive), "--ssp", str(archive)]) == 2  # its own input
    assert "input" in capsys.readouterr().err
    assert main(["export", str(tmp_path / "none.json"), "--ssp", str(tmp_path / "x.ssp")]) == 2
    assert not (tmp_path / "x.ssp").exists()


@pytest.mark.parametrize("edit, message", [('layout="side by side"', "layout 'diagonal'"),
                                           ('x="x"', "'nowhere', which is not an output"),
                                           ('scale="250.0"', "scale = -1 must be a positive number")])
def test_a_bad_view_annotation_is_refused_by_name(fmu_paths, tmp_path, capsys, edit, message):
    archive = tmp_path / "thesis.ssp"
    assert main(["export", str(SCENES / "thesis_scene.json"), "--ssp", str(archive)]) == 0
    with zipfile.ZipFile(archive) as members:
        files = {name: members.read(name) for name in members.namelist()}
    replacement = {'layout="side by side"': 'layout="diagonal"', 'x="x"': 'x="nowhere"',
                   'scale="250.0"': 'scale="-1"'}[edit]
    assert edit.encode() in files["SystemStructure.ssd"]
    files["SystemStructure.ssd"] = files["SystemStructure.ssd"].replace(edit.encode(), replacement.encode(), 1)
    edited = tmp_path / "edited.ssp"
    with zipfile.ZipFile(edited, "w") as members:
        for name, data in files.items():
            members.writestr(name, data)
    assert main(["run", str(edited), "--out", str(tmp_path / "run.csv")]) == 2
    assert message in capsys.readouterr().err
