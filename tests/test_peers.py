"""The coupled-pendulums SSP in two independent importers from PyPI, libcosim and ecos. Both couple
by Jacobi with a one-step delay, i.e. inputs held from the previous communication point: with the
harness set to the same semantics (--algorithm jacobi --extrapolation hold) the results agree to
rounding."""
from __future__ import annotations

import ctypes.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from harness.fmus import build_dir
from harness.master import MasterOptions, run_system
from harness.system import load_system

PEERS = Path(__file__).parent / "peers"
STEP, STEPS = 0.01, 200


def run_peer(script: str, *args: str) -> np.ndarray:
    result = subprocess.run([sys.executable, str(PEERS / script), *args], capture_output=True, text=True, timeout=300)
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


OUTPUTS = {"SimplePendulum": ["phi", "x", "y", "E"], "DoublePendulum": ["phi1", "phi2", "x2", "y2"],
           "SpringPendulum": ["phi", "eps", "x", "y"]}


@pytest.mark.parametrize("peer", ["libcosim", "ecos"])
@pytest.mark.parametrize("name", list(OUTPUTS))
def test_each_pendulum_alone_agrees_with_the_harness(fmu_paths, unzipped, peer, name):
    """Each FMU with its defaults, 100 steps of 0.01 s: the importer's outputs equal the harness's."""
    pytest.importorskip("libcosimpy" if peer == "libcosim" else "ecospy")
    if peer == "ecos" and ctypes.util.find_library("tbb") is None:
        pytest.skip("ecos needs Debian's libtbb12, which is not installed (./run installs it when run as root)")
    rows = run_peer("run_single.py", peer, str(fmu_paths[name]), "0.01", "100", *OUTPUTS[name])
    from harness.simulation import simulate
    ours = simulate(fmu_paths[name], 1.0, 0.01, unzipdir=unzipped[name])
    expected = np.column_stack([ours[n] for n in OUTPUTS[name]])[1:]
    assert rows.shape == expected.shape
    assert np.max(np.abs(rows - expected)) < 1e-12
