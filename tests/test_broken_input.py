"""The harness against broken input: one line on stderr, a non-zero exit code, no traceback, and
results written so far kept."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from harness.fmi.fmus import PROJECT_ROOT, build_dir


def harness(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "harness", *args], capture_output=True, text=True)


def one_line_error(result: subprocess.CompletedProcess, words: str, code: int = 2) -> None:
    lines = result.stderr.strip().splitlines()
    assert result.returncode == code, result.stderr
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in result.stderr, result.stderr


def rewrite_fmu(source: Path, target: Path, drop_prefix: str = "", replace: tuple[bytes, bytes] | None = None) -> Path:
    with zipfile.ZipFile(source) as original, zipfile.ZipFile(target, "w") as copy:
        for item in original.infolist():
            if drop_prefix and item.filename.startswith(drop_prefix):
                continue
            data = original.read(item)
            if replace and item.filename == "modelDescription.xml":
                data = data.replace(*replace)
            copy.writestr(item, data)
    return target


@pytest.fixture
def broken(fmu_paths, tmp_path) -> dict[str, Path]:
    simple = fmu_paths["SimplePendulum"]
    (tmp_path / "corrupt.fmu").write_bytes(b"PK\x03\x04 this is not a zip archive")
    return {
        "corrupt": tmp_path / "corrupt.fmu",
        "no binary": rewrite_fmu(simple, tmp_path / "nobinary.fmu", drop_prefix="binaries/"),
        "FMI 3.0": rewrite_fmu(simple, tmp_path / "fmi3.fmu", replace=(b'fmiVersion="2.0"', b'fmiVersion="3.0"')),
        "missing": tmp_path / "missing.fmu",
    }


@pytest.mark.parametrize("case,words", [("corrupt", "not an FMU (not a zip archive)"),
                                        ("no binary", "no binary for this platform"),
                                        ("FMI 3.0", "an FMI 3.0 FMU; this harness runs FMI 2.0"),
                                        ("missing", "no such FMU file")])
def test_broken_fmus(broken, tmp_path, case, words):
    one_line_error(harness("simulate", str(broken[case]), "--out", str(tmp_path / "x.csv")), words)
    if case != "missing":
        result = harness("validate", str(broken[case]))
        assert result.returncode == 1 and "FAIL" in result.stdout and "Traceback" not in result.stderr


def ssp_copy(tmp_path: Path) -> Path:
    folder = tmp_path / "ssp"
    shutil.copytree(build_dir() / "scenes" / "coupled_pendulums", folder)
    return folder


def test_malformed_ssd(fmu_paths, tmp_path):
    folder = ssp_copy(tmp_path)
    (folder / "SystemStructure.ssd").write_text("<ssd:SystemStructureDescription xmlns:ssd='x'><unclosed")
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "malformed SSD")


def test_ssd_connection_to_a_missing_variable(fmu_paths, tmp_path):
    folder = ssp_copy(tmp_path)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('endElement="spring" endConnector="a_x"',
                                           'endElement="spring" endConnector="a_z"'))
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "spring has no input 'a_z'")


def test_ssd_component_without_its_fmu(fmu_paths, tmp_path):
    folder = ssp_copy(tmp_path)
    (folder / "resources" / "Spring.fmu").unlink()
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "source resources/Spring.fmu not found")


def test_connection_between_different_units(fmu_paths, tmp_path):
    scene = json.loads((PROJECT_ROOT / "scenes" / "coupled_pendulums.json").read_text())
    scene["connections"][0] = ["left.phi", "spring.a_x"]  # an angle into a position
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    one_line_error(harness("run", str(path), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "units differ (rad to m)")


def test_a_stopped_run_keeps_its_rows(fmu_paths, tmp_path):
    scene = json.loads((PROJECT_ROOT / "scenes" / "coupled_pendulums.json").read_text())
    scene["components"]["spring"]["start"]["k"] = 4000.0
    for side in ("left", "right"):
        scene["components"][side]["start"].update(solver="euler", h=0.05)
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    out = tmp_path / "out.csv"
    result = harness("run", str(path), "--stop", "5", "--step", "0.05", "--out", str(out), "--quiet")
    assert result.returncode == 1 and "could not complete the step" in result.stderr
    rows = out.read_text().splitlines()
    assert rows[0].startswith("time,") and len(rows) > 5
