"""The spring scenes written by `harness export` (the coupled pendulums as the build exports them)
and each FMU alone in independent importers: libcosim and ecos (PyPI), Maestro
(Maven Central) and OMSimulator (PyPI, where it installs). All couple by Jacobi with a one-step
delay, i.e. inputs held from the previous communication point: with the harness set to the same
semantics (--algorithm jacobi --extrapolation hold) the results agree to rounding."""
from __future__ import annotations

import ctypes.util
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

from harness.cosim.master import MasterOptions, run_system
from harness.cosim.system import load_system
from harness.fmi.fmus import PROJECT_ROOT, build_dir

PEERS = Path(__file__).resolve().parents[1] / "peers"
STEP, STEPS = 0.01, 200
MAESTRO = "org.into-cps.maestro:maestro:3.1.1:jar:jar-with-dependencies"


def run_peer(script: str, *args: str) -> np.ndarray:
    # Some importers extract into the temporary folder and leave it there: give them one that goes.
    with tempfile.TemporaryDirectory(prefix="peer_") as scratch:
        result = subprocess.run([sys.executable, str(PEERS / script), *args], capture_output=True, text=True,
                                timeout=300, env={**os.environ, "TMPDIR": scratch})
    assert result.returncode == 0, result.stderr[-2000:]
    # libcosim writes its own log lines to stdout too: the rows are the line that holds a JSON array
    line = next(line for line in result.stdout.splitlines() if line.startswith("[["))
    return np.array(json.loads(line))


EXPORTED = ("pendulums_in_a_row", "double_and_cart", "spring_chain")  # written by `harness export`
SCENES = ("coupled_pendulums", *EXPORTED)


@pytest.fixture(scope="module")
def archives(fmu_paths, tmp_path_factory) -> dict[str, Path]:
    """The coupled scene's SSP as the build exports it, and the other spring scenes exported here."""
    from harness.cosim.ssp_export import write_ssp
    folder = tmp_path_factory.mktemp("exported")
    out = {"coupled_pendulums": build_dir() / "scenes" / "coupled_pendulums.ssp"}
    for name in EXPORTED:
        with load_system(PROJECT_ROOT / "scenes" / f"{name}.json") as system:
            write_ssp(system, folder / f"{name}.ssp")
        out[name] = folder / f"{name}.ssp"
    return out


def recorded_points(system) -> list[str]:
    """Every object point's position outputs, `component.variable`."""
    from harness.objects.proof import object_file_in
    names = []
    for component in system.components:
        spec = object_file_in(component.fmu)
        for point in spec.points if spec is not None else ():
            names += [f"{component.name}.{point.outputs[axis]}" for axis in ("x", "y") if axis in point.outputs]
    return names


def state_starts(system) -> dict[str, dict[str, float]]:
    """The bound start values of states (causality output), which libcosim's SSP loader skips."""
    from harness.fmi.fmu_instance import read_description
    starts = {}
    for component in system.components:
        outputs = {v.name for v in read_description(component.fmu).modelVariables if v.causality == "output"}
        chosen = {k: float(v) for k, v in component.start.items() if k in outputs}
        if chosen:
            starts[component.name] = chosen
    return starts


@pytest.fixture(scope="module")
def harness_rows(archives) -> dict[str, tuple[list[str], dict, np.ndarray]]:
    """Per scene: the recorded outputs, the state starts and the harness's rows (Jacobi, inputs held)."""
    out = {}
    for name, archive in archives.items():
        with load_system(archive) as system:
            recorded = recorded_points(system)
            result = run_system(system, MasterOptions(stop=STEP * STEPS, step=STEP, algorithm="jacobi",
                                                      extrapolation="hold"))
            # the importers report after each step
            out[name] = (recorded, state_starts(system), np.column_stack([result[n] for n in recorded])[1:])
    return out


@pytest.mark.parametrize("scene", SCENES)
def test_libcosim_agrees_with_the_harness(archives, harness_rows, scene):
    pytest.importorskip("libcosimpy")
    recorded, starts, expected = harness_rows[scene]
    rows = run_peer("run_libcosim.py", str(archives[scene]), str(STEP), str(STEPS), json.dumps(starts), *recorded)
    assert rows.shape == expected.shape
    assert np.ptp(expected, axis=0).max() > 1e-3  # the scene moves
    assert np.max(np.abs(rows - expected)) < 1e-12


def exported_at(tmp_path: Path, step: float, steps: int):
    """The coupled pendulums exported with a step of their own (not the scenes' 0.01 s), and the harness on
    them at that step (Jacobi, inputs held): the archive, the recorded outputs, the states' bound starts,
    the FMUs and the harness's rows."""
    from harness.cosim.ssp_export import write_ssp
    archive = tmp_path / "coupled.ssp"
    with load_system(PROJECT_ROOT / "scenes" / "coupled_pendulums.json") as system:
        system.step = step
        write_ssp(system, archive)
    with load_system(archive) as system:
        recorded = recorded_points(system)
        result = run_system(system, MasterOptions(stop=step * steps, step=step, algorithm="jacobi",
                                                  extrapolation="hold"))
        fmus = sorted({c.fmu.stem for c in system.components})
        return archive, recorded, state_starts(system), fmus, np.column_stack([result[n] for n in recorded])[1:]


def test_libcosim_takes_the_step_from_an_exported_file(fmu_paths, tmp_path):
    """Given no step, libcosim runs an exported scene at the step its DefaultExperiment annotation names
    (0.004 s here): its rows are the harness's at that step. (ecos cannot: its SSP loader reads no step,
    and ecospy asks for one.)"""
    pytest.importorskip("libcosimpy")
    archive, recorded, starts, _, expected = exported_at(tmp_path, 0.004, 250)
    rows = run_peer("run_libcosim.py", str(archive), "file", "250", json.dumps(starts), *recorded)
    assert rows.shape == expected.shape
    assert np.max(np.abs(rows - expected)) < 1e-12


@pytest.mark.parametrize("scene", SCENES)
def test_ecos_agrees_with_the_harness(archives, harness_rows, scene):
    pytest.importorskip("ecospy")
    if ctypes.util.find_library("tbb") is None:
        pytest.skip("ecos needs Debian's libtbb12, which is not installed (./run installs it when run as root)")
    recorded, _, expected = harness_rows[scene]
    rows = run_peer("run_ecos.py", str(archives[scene]), str(STEP), str(STEPS), "initialValues", *recorded)
    assert rows.shape == expected.shape
    assert np.max(np.abs(rows - expected)) < 1e-12


@pytest.fixture(scope="module")
def maestro() -> str:
    """Maestro's jar with dependencies, fetched from Maven Central once per build folder."""
    if shutil.which("mvn") is None or shutil.which("java") is None:
        pytest.skip("Maestro needs Maven and Java")
    tools = build_dir() / "tools"
    jar = tools / "maestro-3.1.1-jar-with-dependencies.jar"
    if not jar.is_file():
        tools.mkdir(parents=True, exist_ok=True)
        fetched = subprocess.run(["mvn", "-q", "dependency:copy", f"-Dartifact={MAESTRO}",
                                  f"-DoutputDirectory={tools}"],
                                 capture_output=True, text=True, timeout=900)
        assert fetched.returncode == 0, fetched.stdout[-2000:] + fetched.stderr[-2000:]
    return str(jar)


@pytest.mark.parametrize("scene", ["coupled_pendulums.json", *SCENES])
def test_maestro_agrees_with_the_harness(maestro, archives, harness_rows, tmp_path, scene):
    """The scene file (project FMUs by name) and the SSPs, each run from a MaBL specification; the
    first column is the worst fmi2 status Maestro saw up to that step."""
    source = PROJECT_ROOT / "scenes" / scene if scene.endswith(".json") else archives[scene]
    recorded, _, expected = harness_rows[scene.removesuffix(".json")]
    rows = run_peer("run_maestro.py", maestro, str(source), str(STEP), str(STEPS), "{}", str(tmp_path), *recorded)
    assert np.all(rows[:, 0] == 0)
    assert rows[:, 1:].shape == expected.shape
    assert np.max(np.abs(rows[:, 1:] - expected)) < 1e-12


# and the objects that touch, each through its first impacts within the second (the FMU handles its events
# inside fmi2DoStep, so a Co-Simulation importer sees the same numbers)
OUTPUTS = {"SimplePendulum": ["phi", "x", "y", "E_kin"], "DoublePendulum": ["phi1", "phi2", "x2", "y2"],
           "SpringPendulum": ["phi", "eps", "x", "y"], "Spring": ["Fa_x", "Fa_y", "Fb_x", "E_pot"],
           "BouncingBall": ["x", "y", "vy", "E"], "WallPendulum": ["phi", "omega", "x", "y"],
           "StringPendulum": ["x", "y", "vx", "vy"], "CartesianPendulum": ["x", "y", "vx", "rod_force"],
           "NewtonsCradle": ["phi1", "omega1", "phi5", "omega5"], "HertzCradle": ["phi1", "omega1", "phi5", "omega5"]}
# The Spring alone with its default inputs is at rest length and stays there: stretch it and move one end.
START = {"Spring": {"a_vx": 0.5, "a_vy": -0.2, "b_x": 1.2, "b_y": 0.3}}


@pytest.mark.compatibility(importer="{peer}", version="2.0", interface="CS", platform="x86_64 Linux",
                           criterion="the harness's simulate on 100 steps of 0.01 s, within 1e-12")
@pytest.mark.parametrize("peer", ["libcosim", "ecos", "maestro"])
@pytest.mark.parametrize("name", list(OUTPUTS))
def test_each_fmu_alone_agrees_with_the_harness(request, fmu_paths, unzipped, tmp_path, compatibility, peer, name):
    """Each FMU with its defaults (the Spring with moving ends), 100 steps of 0.01 s: the importer's
    outputs equal the harness's."""
    start = START.get(name, {})
    if peer == "maestro":
        rows = run_peer("run_maestro.py", request.getfixturevalue("maestro"), str(fmu_paths[name]), "0.01", "100",
                        json.dumps(start), str(tmp_path), *OUTPUTS[name])
        assert np.all(rows[:, 0] == 0)
        rows = rows[:, 1:]
    else:
        pytest.importorskip("libcosimpy" if peer == "libcosim" else "ecospy")
        if peer == "ecos" and ctypes.util.find_library("tbb") is None:
            pytest.skip("ecos needs Debian's libtbb12, which is not installed (./run installs it when run as root)")
        rows = run_peer("run_single.py", peer, str(fmu_paths[name]), "0.01", "100", json.dumps(start), *OUTPUTS[name])
    from harness.fmi.simulation import simulate
    ours = simulate(fmu_paths[name], 1.0, 0.01, start_values=start, unzipdir=unzipped[name])
    expected = np.column_stack([ours[n] for n in OUTPUTS[name]])[1:]
    assert rows.shape == expected.shape
    assert np.ptp(expected, axis=0).min() > 1e-3  # every compared output moves
    assert np.max(np.abs(rows - expected)) < 1e-12
    compatibility.agrees(name, float(np.max(np.abs(rows - expected) / np.maximum(1.0, np.abs(expected)))))


# OMSimulator's PyPI package is an sdist whose install fetches the binaries from OpenModelica's build
# server; where it cannot, the rows say so. The check is an import, so a run without it costs nothing.
OMSIMULATOR_MISSING = ("OMSimulator is not installed: PyPI has only its sdist 3.0.0.post198, whose install downloads "
                       "OMSimulator-linux-focal-amd64-v3.0.0.post198-gf14b85b.tar.gz from build.openmodelica.org, "
                       "which this machine cannot reach; `pip install OMSimulator` where it can")


def needs_omsimulator() -> None:
    if importlib.util.find_spec("OMSimulator") is None:
        pytest.skip(OMSIMULATOR_MISSING)


@pytest.mark.compatibility(importer="OMSimulator (PyPI)", version="2.0", interface="CS", platform="x86_64 Linux",
                           criterion="the harness's simulate on 100 steps of 0.01 s, within 1e-10")
@pytest.mark.parametrize("name", list(OUTPUTS))
def test_omsimulator_runs_each_fmu_alone_as_the_harness(fmu_paths, unzipped, compatibility, name):
    needs_omsimulator()
    start = START.get(name, {})
    rows = run_peer("run_omsimulator.py", "fmu", str(fmu_paths[name]), "0.01", "100", json.dumps(start),
                    *OUTPUTS[name])
    from harness.fmi.simulation import simulate
    ours = simulate(fmu_paths[name], 1.0, 0.01, start_values=start, unzipdir=unzipped[name])
    expected = np.column_stack([ours[n] for n in OUTPUTS[name]])[1:]
    assert rows.shape == expected.shape
    assert np.ptp(expected, axis=0).min() > 1e-3
    difference = float(np.max(np.abs(rows - expected) / np.maximum(1.0, np.abs(expected))))
    assert difference < 1e-10
    compatibility.agrees(name, difference)


@pytest.mark.compatibility(importer="OMSimulator (PyPI), an exported SSP", version="2.0", interface="CS",
                           platform="x86_64 Linux", criterion="the harness's Jacobi master at the step the file "
                                                               "names (no step given), within 1e-12")
def test_omsimulator_runs_an_exported_scene_at_its_step(fmu_paths, tmp_path, compatibility):
    """The coupled pendulums exported with a step of 0.004 s: OMSimulator, told no step, steps as the
    harness does at that step."""
    needs_omsimulator()
    archive, recorded, _, fmus, expected = exported_at(tmp_path, 0.004, 250)
    rows = run_peer("run_omsimulator.py", "ssp", str(archive), "250", *recorded)
    assert rows.shape == expected.shape
    difference = float(np.max(np.abs(rows - expected) / np.maximum(1.0, np.abs(expected))))
    assert difference < 1e-12
    for fmu in fmus:
        compatibility.agrees(fmu, difference)
