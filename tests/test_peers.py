"""The coupled-pendulums scene and each FMU alone in three independent importers: libcosim and ecos
(PyPI) and Maestro (Maven Central). All three couple by Jacobi with a one-step delay, i.e. inputs
held from the previous communication point: with the harness set to the same semantics
(--algorithm jacobi --extrapolation hold) the results agree to rounding."""
from __future__ import annotations

import ctypes.util
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
from harness.fmi.fmus import build_dir

PEERS = Path(__file__).parent / "peers"
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


@pytest.fixture(scope="module")
def harness_rows(fmu_paths) -> np.ndarray:
    system = load_system(build_dir() / "scenes" / "coupled_pendulums.ssp")
    result = run_system(system, MasterOptions(stop=STEP * STEPS, step=STEP, algorithm="jacobi", extrapolation="hold"))
    table = np.column_stack([result["left.x"], result["left.y"], result["right.x"], result["right.y"]])
    return table[1:]  # the importers report after each step


def test_libcosim_agrees_with_the_harness(harness_rows):
    pytest.importorskip("libcosimpy")
    rows = run_peer("run_libcosim.py", str(build_dir() / "scenes" / "coupled_pendulums.ssp"), str(STEP), str(STEPS),
                    json.dumps({"left": 0.5, "right": 0.0}))
    assert rows.shape == harness_rows.shape
    assert np.max(np.abs(rows - harness_rows)) < 1e-12


def test_ecos_agrees_with_the_harness(harness_rows):
    pytest.importorskip("ecospy")
    if ctypes.util.find_library("tbb") is None:
        pytest.skip("ecos needs Debian's libtbb12, which is not installed (./run installs it when run as root)")
    rows = run_peer("run_ecos.py", str(build_dir() / "scenes" / "coupled_pendulums.ssp"), str(STEP), str(STEPS),
                    "initialValues")
    assert rows.shape == harness_rows.shape
    assert np.max(np.abs(rows - harness_rows)) < 1e-12


@pytest.fixture(scope="module")
def maestro() -> str:
    """Maestro's jar with dependencies, fetched from Maven Central once per build folder."""
    if shutil.which("mvn") is None or shutil.which("java") is None:
        pytest.skip("Maestro needs Maven and Java")
    tools = build_dir() / "tools"
    jar = tools / "maestro-3.1.1-jar-with-dependencies.jar"
    if not jar.is_file():
        tools.mkdir(parents=True, exist_ok=True)
        fetched = subprocess.run(["mvn", "-q", "dependency:copy", f"-Dartifact={MAESTRO}", f"-DoutputDirectory={tools}"],
                                 capture_output=True, text=True, timeout=900)
        assert fetched.returncode == 0, fetched.stdout[-2000:] + fetched.stderr[-2000:]
    return str(jar)


@pytest.mark.parametrize("scene", ["coupled_pendulums.json", "coupled_pendulums.ssp"])
def test_maestro_agrees_with_the_harness(maestro, harness_rows, tmp_path, scene):
    """The scene file (project FMUs by name) and the SSP, each run from a MaBL specification; the
    first column is the worst fmi2 status Maestro saw up to that step."""
    source = (Path(__file__).parents[1] / "scenes" / scene if scene.endswith(".json")
              else build_dir() / "scenes" / scene)
    rows = run_peer("run_maestro.py", maestro, str(source), str(STEP), str(STEPS), "{}", str(tmp_path),
                    "left.x", "left.y", "right.x", "right.y")
    assert np.all(rows[:, 0] == 0)
    assert rows[:, 1:].shape == harness_rows.shape
    assert np.max(np.abs(rows[:, 1:] - harness_rows)) < 1e-12


OUTPUTS = {"SimplePendulum": ["phi", "x", "y", "E_kin"], "DoublePendulum": ["phi1", "phi2", "x2", "y2"],
           "SpringPendulum": ["phi", "eps", "x", "y"], "Spring": ["Fa_x", "Fa_y", "Fb_x", "E_pot"]}
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
