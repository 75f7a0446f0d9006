"""`harness export SCENE --ssp FILE`: any scene written back as an SSP 1.0 archive that fmpy's schema
check accepts and that runs to the same bits as the scene itself, power bonds and step included, and
is looked at as the scene is (camera, traces, description)."""
from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

from harness.cli import main
from harness.cosim.master import MasterOptions, run_system
from harness.cosim.system import load_system
from harness.errors import HarnessError
from harness.fmi.fmus import PROJECT_ROOT, build_dir

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


# Where other importers read the step, by the names their sources use (not this project's constants):
# OMSimulator 2.x (src/OMSimulatorLib: System.cpp reads the system's first annotation, SystemWC.cpp its
# FixedStepMaster), OMSimulator 3.0 (src/OMSimulatorPython/utils.py: SimulationInformation's attributes
# are a solver, a component's names the one it runs under) and libcosim (src/cosim/ssp/ssp_parser.cpp:
# DefaultExperiment's annotation). The C++ readers compare qualified names, prefixes included.
NAMESPACES = {"ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
              "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
              "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
              "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations"}


def exported_with(tmp_path, step: float, stop: float):
    """The coupled pendulums exported with another step and stop time than the scene's (0.01 s, 10 s)."""
    from harness.cosim.ssp_export import write_ssp
    archive = tmp_path / "coupled.ssp"
    with load_system(SCENES / "coupled_pendulums.json") as system:
        system.step, system.stop = step, stop
        write_ssp(system, archive)
    with zipfile.ZipFile(archive) as members:
        files = {name: members.read(name) for name in members.namelist()}
    return archive, files


def rezipped(path, files: dict[str, bytes], ssd: bytes):
    with zipfile.ZipFile(path, "w") as members:
        for name, data in {**files, "SystemStructure.ssd": ssd}.items():
            members.writestr(name, data)
    return path


def test_the_step_and_stop_time_are_where_other_importers_read_them(fmu_paths, tmp_path):
    from lxml import etree
    archive, files = exported_with(tmp_path, 0.004, 3.0)
    root = etree.fromstring(files["SystemStructure.ssd"])
    first = root.find("ssd:System/ssd:Annotations", NAMESPACES)[0]
    assert (first.prefix, etree.QName(first).localname, first.get("type")) == ("ssc", "Annotation", "org.openmodelica")
    information = first.find("oms:Annotations/oms:SimulationInformation", NAMESPACES)
    master = information.find("oms:FixedStepMaster", NAMESPACES)
    assert master.prefix == "oms" and master.get("description") == "oms-ma"
    assert float(master.get("stepSize")) == 0.004
    assert information.get("method") == "oms_ma" and float(information.get("fixedStepSize")) == 0.004
    for component in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NAMESPACES):
        chosen = component.find("ssd:Annotations/ssc:Annotation[@type='org.openmodelica']/oms:Annotations/"
                                "oms:SimulationInformation", NAMESPACES)
        assert chosen.get("name") == information.get("name"), component.get("name")
    experiment = root.find("ssd:DefaultExperiment", NAMESPACES)
    assert float(experiment.get("startTime")) == 0.0 and float(experiment.get("stopTime")) == 3.0
    osp = experiment.find("ssd:Annotations/ssc:Annotation[@type='com.opensimulationplatform']", NAMESPACES)
    algorithm = osp.find("osp:Algorithm", NAMESPACES)
    # libcosim takes every child of osp:Algorithm (attributes too) for an algorithm, and knows this one
    assert algorithm.prefix == "osp" and not algorithm.attrib
    assert [(c.prefix, etree.QName(c).localname) for c in algorithm] == [("osp", "FixedStepAlgorithm")]
    assert float(algorithm[0].get("baseStepSize")) == 0.004
    own = root.find("ssd:System/ssd:Annotations/ssc:Annotation[@type='org.pendulum-harness.step']/Step", NAMESPACES)
    assert float(own.get("stepSize")) == 0.004
    with load_system(archive) as exported:  # read back, through fmpy's SSP 1.0 schema check
        assert (exported.step, exported.stop) == (0.004, 3.0)


def test_the_harness_annotation_decides_and_the_others_stand_in_for_it(fmu_paths, tmp_path):
    from lxml import etree
    archive, files = exported_with(tmp_path, 0.004, 3.0)
    root = etree.fromstring(files["SystemStructure.ssd"])
    own = root.find("ssd:System/ssd:Annotations/ssc:Annotation[@type='org.pendulum-harness.step']", NAMESPACES)
    own[0].set("stepSize", "0.005")
    with load_system(rezipped(tmp_path / "own.ssp", files, etree.tostring(root))) as system:
        assert system.step == 0.005
    own.getparent().remove(own)
    algorithm = root.find("ssd:DefaultExperiment/ssd:Annotations/ssc:Annotation/osp:Algorithm", NAMESPACES)
    algorithm[0].set("baseStepSize", "0.002")
    with load_system(rezipped(tmp_path / "osp.ssp", files, etree.tostring(root))) as system:
        assert system.step == 0.002
    experiment = root.find("ssd:DefaultExperiment", NAMESPACES)
    experiment.remove(experiment[0])
    information = root.find("ssd:System/ssd:Annotations/ssc:Annotation/oms:Annotations/oms:SimulationInformation",
                            NAMESPACES)
    information.set("fixedStepSize", "0.003")
    with load_system(rezipped(tmp_path / "oms.ssp", files, etree.tostring(root))) as system:
        assert system.step == 0.004  # OMSimulator 2.x's FixedStepMaster
    information.remove(information[0])
    with load_system(rezipped(tmp_path / "oms3.ssp", files, etree.tostring(root))) as system:
        assert system.step == 0.003  # OMSimulator 3.0's solver
    information.set("fixedStepSize", "fast")
    with pytest.raises(HarnessError, match="SimulationInformation fixedStepSize = 'fast' is not a number"):
        load_system(rezipped(tmp_path / "bad.ssp", files, etree.tostring(root)))


def test_the_builds_coupled_scene_is_its_scene_file_exported(fmu_paths, tmp_path, capsys):
    """build/scenes/coupled_pendulums.ssp (and the folder beside it) carries the step, the stop time and
    the power bonds of scenes/coupled_pendulums.json, so that a run given neither --step nor --stop
    writes the scene file's rows, bond energy included."""
    from lxml import etree
    scene = json.loads((SCENES / "coupled_pendulums.json").read_text())
    archive = build_dir() / "scenes" / "coupled_pendulums.ssp"
    with zipfile.ZipFile(archive) as members:
        files = {name: members.read(name) for name in members.namelist() if not name.endswith("/")}
    folder = build_dir() / "scenes" / "coupled_pendulums"
    assert {name: (folder / name).read_bytes() for name in files} == files  # the folder is the archive unpacked
    root = etree.fromstring(files["SystemStructure.ssd"])
    assert float(root.find("ssd:DefaultExperiment", NAMESPACES).get("stopTime")) == scene["stop"]
    own = root.find("ssd:System/ssd:Annotations/ssc:Annotation[@type='org.pendulum-harness.step']/Step", NAMESPACES)
    assert float(own.get("stepSize")) == scene["step"]
    bonds = root.find("ssd:System/ssd:Annotations/ssc:Annotation[@type='org.pendulum-harness.bonds']/Bonds",
                      NAMESPACES)
    # a bond of the scene file names force, velocity and position as component.variable, one component
    assert [[f"{b.get('component')}.{b.get(k)}" for k in ("force", "velocity", "position")] for b in bonds] == \
        scene["bonds"]
    for source in (folder, archive):
        with load_system(source) as system:
            assert (system.stop, system.step) == (scene["stop"], scene["step"])
            assert [[f"{b.component}.{b.force}", f"{b.component}.{b.velocity}", f"{b.component}.{b.position}"]
                    for b in system.bonds] == scene["bonds"]
    steps = round(scene["stop"] / scene["step"])
    for extra in ([], ["--energy-correction"]):  # the second puts the bonds to work
        lines, rows = {}, {}
        for name, source in (("scene", SCENES / "coupled_pendulums.json"), ("ssp", archive)):
            out = tmp_path / f"{name}.csv"
            assert main(["run", str(source), "--out", str(out), "--quiet", *extra]) == 0
            lines[name], rows[name] = capsys.readouterr().out.replace(str(out), "OUT"), out.read_text()
        assert lines["ssp"] == lines["scene"] and f"{steps} macro steps of {scene['step']:g} s" in lines["ssp"]
        assert ("the power bonds created" in lines["ssp"]) == bool(extra)
        assert rows["ssp"] == rows["scene"] and len(rows["ssp"].splitlines()) == 1 + steps + 1  # header, t = 0, steps
