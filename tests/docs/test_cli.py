"""The command line: user errors give one line and exit code 2; results so far are kept."""
from __future__ import annotations

import csv

import re
import subprocess
import sys

import numpy as np
import pytest


def harness(*args: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "harness", *args], capture_output=True, text=True, cwd=cwd)


@pytest.mark.parametrize("args,words", [
    (["simulate", "Nope"], "unknown FMU 'Nope'"),
    (["simulate", "SimplePendulum", "--set", "L=-1"], "L (value reference 10) = -1 is out of its allowed range"),
    (["simulate", "SimplePendulum", "--solver", "rk9"], "'rk9' is not one of euler"),
    (["simulate", "missing.fmu"], "no such FMU file"),
    (["simulate", "SimplePendulum", "--set", "foo=1"], "no variable 'foo'"),
    (["simulate", "SimplePendulum", "--step", "-1"], "argument --step: '-1' must be a positive finite number"),
    (["simulate", "SimplePendulum", "--set", "L=1_000"], "L = '1_000' is not a number"),
    (["simulate", "SimplePendulum", "--set", "L=\u0967"], "L = '\u0967' is not a number"),  # a Devanagari one
])
def test_user_errors_are_one_line(fmu_paths, tmp_path, args, words):
    result = harness(*args, "--out", str(tmp_path / "x.csv"))
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("harness: error:") and words in lines[0], result.stderr
    assert "Traceback" not in result.stderr


def test_discard_keeps_the_results_so_far(fmu_paths, tmp_path):
    out = tmp_path / "blow.csv"
    result = harness("simulate", "SpringPendulum", "--solver", "euler", "--h", "0.3", "--set", "D=5000",
                     "--out", str(out))
    assert result.returncode == 1 and "euler with h = 0.3" in result.stderr
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert len(table) > 10 and np.all(np.isfinite(table))


def test_a_step_discarded_without_progress_adds_no_second_row(fmu_paths, tmp_path):
    """h equal to the communication step: the discarded step got nowhere, so the last row is the last
    good state, once."""
    out = tmp_path / "stuck.csv"
    result = harness("simulate", "SimplePendulum", "--set", "g=1e308", "--set", "h=0.01", "--step", "0.01",
                     "--solver", "euler", "--out", str(out))
    assert result.returncode == 1 and "stopped at t = 0" in result.stderr, result.stderr
    table = np.loadtxt(out, delimiter=",", skiprows=1, ndmin=2)
    assert len(table) == 1 and table[0, 0] == 0.0 and np.all(np.isfinite(table))


def test_step_doubling_that_stops_at_once_counts_no_macro_step(fmu_paths, tmp_path):
    from harness.fmi.fmus import PROJECT_ROOT
    result = harness("run", str(PROJECT_ROOT / "scenes" / "coupled_pendulums.json"), "--tolerance", "1e-30",
                     "--stop", "1", "--out", str(tmp_path / "c.csv"))
    assert result.returncode == 1 and "could not meet the tolerance 1e-30 after t = 0" in result.stderr
    assert ": 0 macro steps chosen by step doubling" in result.stdout, result.stdout


def test_simulate_writes_csv_and_plot(fmu_paths, tmp_path):
    result = harness("simulate", "DoublePendulum", "--stop", "1", "--solver", "ab4", "--h", "0.01",
                     "--out", str(tmp_path / "d.csv"), "--plot", str(tmp_path / "d.png"))
    assert result.returncode == 0, result.stderr
    header = (tmp_path / "d.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "time" and {"x2", "y2", "E", "n_rhs"} <= set(header)
    assert (tmp_path / "d.png").stat().st_size > 10_000


def test_run_writes_every_output_of_every_component(fmu_paths, tmp_path):
    from harness.fmi.fmus import PROJECT_ROOT
    out = tmp_path / "run.csv"
    result = harness("run", str(PROJECT_ROOT / "scenes" / "coupled_pendulums.json"), "--stop", "0.5", "--step", "0.05",
                     "--algorithm", "jacobi", "--extrapolation", "hold", "--out", str(out), "--quiet")
    assert result.returncode == 0, result.stderr
    lines = out.read_text().splitlines()
    assert lines[0].startswith("time,spring.Fa_x,") and "left.n_rhs" in lines[0] and len(lines) == 12


@pytest.mark.parametrize("content,words", [
    ("{not json", "not valid JSON (line 1, column 2"),
    ('{"components": {"a": {"fmu": "SimplePendulum"}}, "connections": [["a.x", "a.nothing"]]}', "no input 'nothing'"),
    ('{"components": {"a": {"fmu": "SimplePendulum"}, "b": {"fmu": "SimplePendulum"}}, '
     '"connections": [["a.phi", "b.F_x"]]}', "units differ (rad to N)"),
])
def test_run_rejects_broken_systems(fmu_paths, tmp_path, content, words):
    scene = tmp_path / "scene.json"
    scene.write_text(content)
    result = harness("run", str(scene), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv"))
    assert result.returncode == 2 and words in result.stderr and "Traceback" not in result.stderr, result.stderr


def test_validate_passes_our_fmu_and_fails_a_broken_one(fmu_paths, tmp_path):
    import zipfile
    result = harness("validate", "SimplePendulum")
    assert result.returncode == 0, result.stdout
    assert "FAIL" not in result.stdout and "order of rk4" in result.stdout and "Euler-Lagrange" in result.stdout
    broken = tmp_path / "Broken.fmu"
    with zipfile.ZipFile(fmu_paths["Spring"]) as source, zipfile.ZipFile(broken, "w") as target:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "modelDescription.xml":
                dropped = re.sub(rb'<Unknown index="16"[^>]*/>', b"", data, count=1)  # an output from ModelStructure
                assert dropped != data
                data = dropped
            target.writestr(item, data)
    result = harness("validate", str(broken))
    assert result.returncode == 1 and "FAIL  modelDescription (fmpy)" in result.stdout


def test_a_long_run_reports_its_progress(capsys, monkeypatch):
    """Where the run is and the time left, from the elapsed time and the fraction done."""
    from harness.fmi import simulation
    clock = iter([100.0, 103.0, 103.5, 110.0])
    monkeypatch.setattr(simulation.time, "monotonic", lambda: next(clock))
    progress = simulation.Progress(stop=50.0)  # started at 100 s
    progress(12.5, 0.25)   # 103 s: 3 s for a quarter, 9 s left
    progress(13.0, 0.26)   # 103.5 s: within two seconds of the last line, nothing
    progress(25.0, 0.5)    # 110 s: 10 s for half, 10 s left
    lines = capsys.readouterr().err.splitlines()
    assert lines == ["  t = 12.5 of 50 s (25%, about 9 s left)", "  t = 25 of 50 s (50%, about 10 s left)"]


def test_charts_take_each_object_once_and_the_methods_asked_for(fmu_paths, tmp_path):
    """An object named twice is charted once: each (object, method, step, tolerance) has one row, as it would
    have two if the object were swept twice; --methods limits the points to those methods and peers."""
    result = harness("chart", "work-precision", "--quick", "--repeats", "1", "--methods", "rk4", "scipy-DOP853",
                     "--objects", "SimplePendulum", "SimplePendulum", "--out", str(tmp_path))
    assert result.returncode == 0, result.stderr
    rows = list(csv.DictReader(open(tmp_path / "work-precision.csv")))
    assert {row["object"] for row in rows} == {"SimplePendulum"}
    assert {row["method"] for row in rows} == {"rk4", "scipy-DOP853"}
    keys = [(row["method"], row["h"], row["tol"]) for row in rows]
    assert len(rows) == 6 and len(set(keys)) == len(keys)  # quick: 4 steps of rk4, 2 tolerances of DOP853


@pytest.mark.parametrize("arguments, message", [
    (["work-precision", "--methods", "rk5"], "--methods: rk5 is not one of euler, midpoint"),
    (["stability", "--methods", "rk4"], "--methods: chart stability takes every method (only work-precision"),
    (["work-precision", "--methods", "taylor", "--objects", "HertzCradle"],
     "--methods: none of taylor runs on HertzCradle")])
def test_methods_a_chart_cannot_take_are_refused_before_anything_is_written(fmu_paths, tmp_path, arguments, message):
    out = tmp_path / "charts"
    result = harness("chart", *arguments, "--out", str(out))
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and message in result.stderr, result.stderr
    assert not out.exists()


@pytest.mark.parametrize("name", ["CartPendulum", "SphericalPendulum", "DoublePendulum", "Spring"])
def test_every_fmu_plots_its_moving_points(fmu_paths, tmp_path, name):
    """The picture shows the points the object file names (CartPendulum's coordinate x is no point);
    --plot of an FMU without points is refused before the run, with nothing written."""
    result = harness("simulate", name, "--stop", "0.1", "--out", str(tmp_path / "p.csv"), "--plot",
                     str(tmp_path / "p.png"))
    if name == "Spring":
        assert result.returncode == 2 and result.stderr.count("\n") == 1, result.stderr
        assert "--plot: Spring.fmu has no moving point to draw" in result.stderr
        assert not (tmp_path / "p.csv").exists() and not (tmp_path / "p.png").exists()
        return
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "p.png").stat().st_size > 10_000


def test_a_stage_report_speaks_only_when_a_stage_is_slow(capsys):
    import time

    from harness.cli import StageReport
    report = StageReport("job: ", delay=0.2)
    report("quick")
    report("slow")
    time.sleep(0.6)
    report("after")
    report.close()
    time.sleep(0.4)
    assert capsys.readouterr().err == "job: slow ...\n"
