"""The master algorithms are registered once (harness/cosim/algorithm_registry.py): the Python loop implements each
name, the CLI offers them, the C loop knows each one by the registry's id and refuses an id it does not know, and
the page's master runs those the registry says it runs."""
from __future__ import annotations

import ctypes
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from harness.cosim import algorithms
from harness.cosim.algorithm_registry import DEFAULT, NAMES, REGISTRY
from harness.cosim.native_core import CORE_REFUSED, load_core

ROOT = Path(__file__).resolve().parents[2]


def test_the_python_loop_implements_each_registered_name():
    assert tuple(algorithms.ALGORITHMS) == NAMES and DEFAULT in NAMES


def test_the_c_loop_knows_each_registered_id():
    text = (ROOT / "harness/cosim/native/cosim_core.c").read_text()
    ids = {name.lower().replace("_", "-"): int(code)
           for name, code in re.findall(r"ALGORITHM_(\w+) = (\d+)", text)}
    assert ids == {entry.name: entry.code for entry in REGISTRY if entry.code is not None}


def test_the_c_loop_refuses_an_id_it_does_not_know(fmu_paths):
    core = load_core()
    if core is None:
        pytest.skip("the C loop (build/lib/cosim_core.so) is not built")
    grid = np.array([0.0, 0.1])
    rows, culprit = ctypes.c_long(7), ctypes.c_int(7)
    unknown = max(entry.code or 0 for entry in REGISTRY) + 1
    status = core.cosim_run(None, 0, grid.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 2, unknown, 0, None, 0,
                            None, None, None, None, ctypes.byref(rows), ctypes.byref(culprit))
    assert status == CORE_REFUSED and rows.value == 0 and culprit.value == -1


def test_the_cli_offers_the_registered_names(tmp_path):
    result = subprocess.run([sys.executable, "-m", "harness", "run", "scene.json", "--algorithm",
                             "no-such"], cwd=tmp_path, capture_output=True, text=True)
    assert result.returncode == 2
    assert all(f"'{name}'" in result.stderr for name in NAMES), result.stderr


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_the_page_runs_the_algorithms_the_registry_gives_it():
    script = "import('./web/master.mjs').then(m => console.log(JSON.stringify(m.ALGORITHMS)))"
    page = json.loads(subprocess.run(["node", "-e", script], cwd=ROOT, capture_output=True, text=True,
                                     check=True).stdout)
    assert page == [entry.name for entry in REGISTRY if entry.page]
