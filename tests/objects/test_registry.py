"""One registry: an object file dropped into `modelDescription/` is built by CMake and known to
validate, the work-precision and stability charts, the planner and scenes, with no edit anywhere else.

The test copies the project's tracked files into a temporary folder (with the SimplePendulum and the
Spring, which the build's scene packing needs, and without the other objects, to keep the build
short), drops a new object file there and uses only the commands a user would."""
from __future__ import annotations

import csv
import json
import os
import re
import shutil
import subprocess
import sys

import pytest

from harness.fmi.fmus import PROJECT_ROOT
from test_objects import CART_PENDULUM

# The cart pendulum of the object-file tests under a new name.
TROLLEY = CART_PENDULUM.replace('identifier = "CartPendulumTest"', 'identifier = "Trolley"')


@pytest.fixture(scope="module")
def project_with_a_new_object(tmp_path_factory):
    if shutil.which("git") is None or not (PROJECT_ROOT / ".git").exists():
        pytest.skip("needs the project as a git checkout (git ls-files names what to copy)")
    copy = tmp_path_factory.mktemp("project")
    tracked = subprocess.run(["git", "ls-files"], cwd=PROJECT_ROOT, check=True, capture_output=True,
                             text=True).stdout.splitlines()
    keep_objects = {"modelDescription/SimplePendulum.toml"}
    for name in tracked:
        if name.startswith("modelDescription/") and name.endswith(".toml") and name not in keep_objects:
            continue
        source = PROJECT_ROOT / name
        if source.is_file():
            (copy / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, copy / name)
    (copy / "modelDescription" / "Trolley.toml").write_text(TROLLEY)
    # no other platforms' binaries nor WebAssembly modules: none of the commands below loads them (the live view's
    # modules of any object are tests/view/test_view.py's)
    subprocess.run(["cmake", "-S", str(copy), "-B", str(copy / "build"), "-DCMAKE_BUILD_TYPE=Release",
                    "-DFMU_CROSS=OFF", "-DFMU_WASM=OFF", f"-DOBJECTS_PYTHON={sys.executable}"], check=True,
                   capture_output=True)
    subprocess.run(["cmake", "--build", str(copy / "build"), "-j2"], check=True, capture_output=True)
    return copy


def harness(copy, *arguments) -> subprocess.CompletedProcess:
    environment = {k: v for k, v in os.environ.items() if not k.startswith("PENDULUM_")}
    environment["PYTHONPATH"] = str(copy)
    return subprocess.run([sys.executable, "-m", "harness", *arguments], cwd=copy, capture_output=True, text=True,
                          env=environment)


def test_cmake_builds_the_dropped_object(project_with_a_new_object):
    fmu = project_with_a_new_object / "build" / "fmus" / "Trolley.fmu"
    assert fmu.is_file()


def test_one_fmu_builds_without_deriving_the_others(project_with_a_new_object, tmp_path):
    """A newcomer's demo waits on its own FMUs only: in a folder never built, one FMU's target derives and
    describes that object and no other (make's dry run lists what it would do)."""
    copy = project_with_a_new_object
    subprocess.run(["cmake", "-G", "Unix Makefiles", "-S", str(copy), "-B", str(tmp_path), "-DFMU_CROSS=OFF",
                    "-DFMU_WASM=OFF", f"-DOBJECTS_PYTHON={sys.executable}"], check=True, capture_output=True)
    # -k: a dry run makes no object files, so the link steps after them stop it; it lists the rest all the same
    dry = subprocess.run(["cmake", "--build", str(tmp_path), "--target", "Trolley_fmu", "--", "-n", "-k"],
                         capture_output=True, text=True)
    assert set(re.findall(r"harness\.objects\.generate \S*/(\w+)\.toml", dry.stdout)) == {"Trolley"}
    assert set(re.findall(r"fmu_codegen\.py .*--xml \S*/(\w+)/modelDescription\.xml", dry.stdout)) == {"Trolley"}
    everything = subprocess.run(["cmake", "--build", str(tmp_path), "--", "-n", "-k"], capture_output=True,
                                text=True)
    assert set(re.findall(r"harness\.objects\.generate \S*/(\w+)\.toml", everything.stdout)) == \
        {"Trolley", "SimplePendulum"}  # the whole build derives every object


def test_validate_proves_it(project_with_a_new_object):
    result = harness(project_with_a_new_object, "validate", "build/fmus/Trolley.fmu")
    assert result.returncode == 0, result.stdout + result.stderr
    assert "FAIL" not in result.stdout and "numeric route" in result.stdout and "order of ab6" in result.stdout


def test_the_stability_chart_has_its_normal_modes(project_with_a_new_object, tmp_path):
    result = harness(project_with_a_new_object, "chart", "stability", "--objects", "Trolley", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    with open(tmp_path / "stability.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert rows and {row["object"] for row in rows} == {"Trolley"}
    for row in rows:  # a linear mode: the measured limit where the method's amplification predicts it
        if row["theory_limit"] == "inf":  # A-stable: as long a step as the scan takes (one per 100 periods)
            assert float(row["measured_limit"]) > 100, row
        else:
            assert float(row["measured_limit"]) == pytest.approx(float(row["theory_limit"]), rel=0.05)


def test_the_work_precision_chart_measures_it(project_with_a_new_object, tmp_path):
    result = harness(project_with_a_new_object, "chart", "work-precision", "--objects", "Trolley", "--quick",
                     "--repeats", "1", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert "Trolley: Pareto front" in result.stdout
    with open(tmp_path / "work-precision.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert {row["object"] for row in rows} == {"Trolley"}
    rk4 = sorted((row for row in rows if row["method"] == "rk4"), key=lambda row: -float(row["h"]))
    # one step a quarter of the last: the error of a fourth-order method falls by about 4^4 = 256
    assert 256 / 2 < float(rk4[0]["error"]) / float(rk4[1]["error"]) < 256 * 2
    assert {"scipy-DOP853", "fmpy-CVode", "rkf45"} <= {row["method"] for row in rows}


def test_a_scene_runs_and_plans_it_by_name(project_with_a_new_object, tmp_path):
    scene = tmp_path / "trolley.json"
    scene.write_text(json.dumps({"name": "trolley", "stop": 2.0, "step": 0.01,
                                 "components": {"trolley": {"fmu": "Trolley", "start": {"phi": 0.4}}},
                                 "connections": []}))
    run = harness(project_with_a_new_object, "run", str(scene), "--out", str(tmp_path / "run.csv"), "--quiet")
    assert run.returncode == 0, run.stderr
    with open(tmp_path / "run.csv") as handle:
        header = next(csv.reader(handle))
    assert {"trolley.phi", "trolley.bob_x", "trolley.cart_x", "trolley.E"} <= set(header), header
    plan = harness(project_with_a_new_object, "plan", str(scene), "--tolerance", "1e-3")
    assert plan.returncode == 0, plan.stderr
    assert "trolley" in plan.stdout and "total cost" in plan.stdout
