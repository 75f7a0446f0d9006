"""What the FMU files contain, and that C and XML cannot disagree."""
from __future__ import annotations

import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from harness.fmi.fmus import FMU_NAMES, PROJECT_ROOT
from harness.fmi.simulation import simulate
from harness.objects.registry import handwritten_names, object_names

from conftest import rebuilt_with_fmpy

SPEC_DEFAULTS = {
    "SimplePendulum": {"g": 9.81, "d": 0, "anchor_x": 0, "anchor_y": 0, "h": 0.008, "tol": 1e-6, "L": 1, "m": 1,
                       "phi": 0.5, "omega": 0, "F_x": 0, "F_y": 0},
    "DoublePendulum": {"m1": 1, "m2": 1, "J1": 1 / 12, "J2": 1 / 12, "s1": 0.5, "s2": 0.5, "l1": 1, "l2": 1,
                       "phi1": np.pi / 2, "phi2": np.pi / 2, "omega1": 0, "omega2": 0, "h": 0.008},
    "SpringPendulum": {"m": 1, "D": 15, "l0": 1, "phi": 0.75 * np.pi, "eps": 0, "omega": 0, "v_eps": 0},
    "Spring": {"k": 10, "c": 0, "l0": 1},
}
PENDULUM_OUTPUTS = {"E_kin", "E_pot", "E", "n_rhs", "n_steps", "n_rejected", "n_jacobians", "n_iterations"}
SOLVERS = ["euler", "midpoint", "heun", "rk3", "rk4", "rkf45", "nystrom5", "ab2", "ab3", "ab4", "ab5", "ab6",
           "implicit_midpoint", "gauss_legendre4", "stormer_verlet", "abm2", "abm3", "abm4", "abm5", "abm6",
           "trapezoid", "taylor", "gbs"]


@pytest.mark.compatibility(importer=f"fmpy {fmpy.__version__} validate_fmu", version="2.0", interface="CS, ME",
                           platform="(model description)", criterion="no problem reported")
@pytest.mark.parametrize("name", FMU_NAMES)
def test_fmpy_validation_finds_no_problem(fmu_paths, compatibility, name):
    assert validate_fmu(str(fmu_paths[name])) == []
    compatibility.agrees(name)


@pytest.mark.parametrize("name", FMU_NAMES)
def test_contents_and_spec_defaults(fmu_paths, name):
    with zipfile.ZipFile(fmu_paths[name]) as archive:
        files = set(archive.namelist())
        html = archive.read("documentation/index.html").decode()
    assert {"modelDescription.xml", f"binaries/linux64/{name}.so", "documentation/index.html",
            "sources/model_description.h", "sources/physics.c"} <= files
    assert "<h2>Equations</h2>" in html and "<h2>Variables</h2>" in html
    md = read_model_description(str(fmu_paths[name]))
    variables = {v.name: v for v in md.modelVariables}
    for variable, value in SPEC_DEFAULTS.get(name, {}).items():
        assert float(variables[variable].start) == pytest.approx(value, rel=1e-15), variable
    if name in object_names():
        # The object file travels in the FMU, and its defaults (read here with plain tomllib) are the
        # FMU's start values.
        data = tomllib.loads(archive_text(fmu_paths[name], f"sources/{name}.toml"))
        for section in ("parameters", "coordinates"):
            for variable, entry in data[section].items():
                if "start" in entry:
                    assert float(variables[variable].start) == entry["start"], variable
                if section == "coordinates":
                    assert float(variables[entry["velocity"]].start) == entry.get("velocity_start", 0.0)
    if name not in handwritten_names():
        assert PENDULUM_OUTPUTS <= {n for n, v in variables.items() if v.causality == "output"}
        assert [item.name for item in variables["solver"].declaredType.items] == SOLVERS
        assert variables["solver"].start == "5" and variables["solver"].variability == "tunable"
        assert variables["L" if "L" in variables else "g"].variability == "fixed"
    cs = md.coSimulation
    assert cs.canHandleVariableCommunicationStepSize and cs.canGetAndSetFMUstate and cs.canSerializeFMUstate
    assert cs.canInterpolateInputs and cs.maxOutputDerivativeOrder == 1
    assert md.modelExchange is not None


def archive_text(fmu: Path, member: str) -> str:
    with zipfile.ZipFile(fmu) as archive:
        return archive.read(member).decode()


def test_guids_are_distinct(fmu_paths):
    guids = [read_model_description(str(p)).guid for p in fmu_paths.values()]
    assert len(set(guids)) == len(guids)


@pytest.mark.parametrize("name", FMU_NAMES)
def test_binary_exports_only_fmi2_and_needs_only_libc_and_libm(fmu_paths, unzipped, name):
    library = Path(unzipped[name]) / "binaries" / "linux64" / f"{name}.so"
    symbols = subprocess.run(["nm", "-D", "--defined-only", str(library)], capture_output=True, text=True,
                             check=True).stdout.split("\n")
    exported = [line.split()[-1] for line in symbols if line.strip()]
    assert exported and all(s.startswith("fmi2") for s in exported), exported
    assert len(exported) == 44  # the whole FMI 2.0 API: common, Model Exchange and Co-Simulation functions
    dynamic = subprocess.run(["readelf", "-d", str(library)], capture_output=True, text=True, check=True).stdout
    needed = {line.split("[")[1].rstrip("]") for line in dynamic.splitlines() if "(NEEDED)" in line}
    assert needed <= {"libc.so.6", "libm.so.6"}, needed


@pytest.mark.compatibility(importer="fmpy's source build (the macOS route)", version="2.0", interface="CS",
                           platform="x86_64 Linux, built from sources/", criterion="the shipped binary, within 1e-12")
@pytest.mark.parametrize("name", ["SimplePendulum", "Spring"])
def test_sources_rebuild_with_fmpy(fmu_paths, unzipped, tmp_path, compatibility, name):
    """fmpy.build.build_platform_binary compiles sources/ into a working binary with the same results."""
    copy = rebuilt_with_fmpy(unzipped[name], tmp_path)
    assert (copy / "binaries" / "linux64" / f"{name}.so").is_file()
    rebuilt = simulate(fmu_paths[name], 2.0, 0.1, unzipdir=str(copy))
    original = simulate(fmu_paths[name], 2.0, 0.1, unzipdir=unzipped[name])
    assert rebuilt.columns == original.columns
    assert np.allclose(rebuilt.values, original.values, rtol=1e-12, atol=1e-12)
    compatibility.agrees(name, float(np.max(np.abs(rebuilt.values - original.values)
                                            / np.maximum(1.0, np.abs(original.values)))))


def _plain_build(unzipped_folder: str, name: str, target: Path) -> Path:
    """The binary an importer gets from sources/ with a bare compiler call: no project flags (in
    particular no -fvisibility=hidden), every source file the model description lists."""
    import xml.etree.ElementTree as ET
    root = ET.parse(Path(unzipped_folder) / "modelDescription.xml").getroot()
    sources = [str(Path(unzipped_folder) / "sources" / f.get("name"))
               for f in root.findall("CoSimulation/SourceFiles/File")]
    assert sources
    library = target / f"{name}.so"
    subprocess.run(["gcc", "-shared", "-fPIC", "-O2", "-Wall", "-Wextra", "-Wsign-conversion", "-Wno-unused-parameter",
                    "-Werror", "-o", str(library), *sources, "-I", str(Path(unzipped_folder) / "sources"), "-lm"],
                   check=True, capture_output=True, text=True)
    return library


@pytest.fixture(scope="module")
def plain_builds(unzipped, tmp_path_factory):
    """plain_builds(name) -> the FMU's `_plain_build`, compiled once per module (ten seconds each): the
    symbol check and the two-FMU process load the same binaries."""
    built = {}

    def build(name: str) -> Path:
        if name not in built:
            built[name] = _plain_build(unzipped[name], name, tmp_path_factory.mktemp(f"plain-{name}"))
        return built[name]
    return build


@pytest.mark.parametrize("name", FMU_NAMES)
def test_sources_compiled_plainly_keep_internal_names_private(plain_builds, name):
    """Without the project's build flags too, and warning-free at -Wall -Wextra -Wsign-conversion: only
    the fmi2 functions are exported."""
    library = plain_builds(name)
    symbols = subprocess.run(["nm", "-D", "--defined-only", str(library)], capture_output=True, text=True,
                             check=True).stdout.split("\n")
    exported = [line.split()[-1] for line in symbols if line.strip()]
    assert all(s.startswith("fmi2") for s in exported), [s for s in exported if not s.startswith("fmi2")]


def test_two_plainly_compiled_fmus_in_one_process_with_global_symbols(fmu_paths, unzipped, plain_builds, tmp_path):
    """Loaded RTLD_GLOBAL one after the other (as some importers do), each FMU still calls its own
    internals: the double pendulum's outer mass moves as it does from the project's own binary."""
    import ctypes
    libraries = {}
    for name in ("SimplePendulum", "DoublePendulum"):
        folder = tmp_path / name
        shutil.copytree(unzipped[name], folder)
        libraries[name] = Path(shutil.copy(plain_builds(name), folder / "binaries" / "linux64" / f"{name}.so"))
    handles = [ctypes.CDLL(str(libraries[n]), mode=ctypes.RTLD_GLOBAL) for n in ("SimplePendulum", "DoublePendulum")]
    assert handles
    rebuilt = simulate(fmu_paths["DoublePendulum"], 1.0, 0.1, unzipdir=str(tmp_path / "DoublePendulum"))
    original = simulate(fmu_paths["DoublePendulum"], 1.0, 0.1, unzipdir=unzipped["DoublePendulum"])
    column = rebuilt.columns.index("x2")
    assert np.allclose(rebuilt.values[:, column], original.values[:, column], rtol=1e-12, atol=1e-12)
    assert np.ptp(rebuilt.values[:, column]) > 0.1  # it moves


def test_prototypes_match_the_standard_headers(tmp_path):
    """The framework compiles against the FMI standard's own headers (shipped with fmpy) too."""
    headers = Path(fmpy.__file__).parent / "c-code"
    generated = PROJECT_ROOT / "build" / "generated" / "SimplePendulum"
    for source in ("fmi2_functions.c", "core.c", "stepper.c", "instance.c"):
        subprocess.run(["gcc", "-std=c99", "-fsyntax-only", "-Werror=incompatible-pointer-types",
                        "-DUSE_STANDARD_FMI2_HEADERS", f"-I{headers}", f"-I{generated}",
                        f"-I{PROJECT_ROOT / 'fmus' / 'framework'}", f"-I{generated}",
                        str(PROJECT_ROOT / "fmus" / "framework" / source)], check=True)


def run_codegen(tmp_path: Path, xml_files: list[Path]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(PROJECT_ROOT / "tools" / "fmu_codegen.py"),
                           "--out", str(tmp_path / "gen"),
                           "--models", str(PROJECT_ROOT / "fmus" / "models"),
                           "--sources", "fmi2_functions.c", "core.c", "stepper.c", "instance.c", "integrators.c",
                           "linear_model.c", "constraints.c",
                           "physics.c",
                           "--xml", *map(str, xml_files)], capture_output=True, text=True)


def model_xml(name: str) -> Path:
    """The model description the build compiles against: generated from an object file, or written by hand."""
    written = PROJECT_ROOT / "modelDescription" / f"{name}.xml"
    return written if written.is_file() else PROJECT_ROOT / "build" / "generated" / name / "modelDescription.xml"


def broken_copy(tmp_path: Path, name: str, old: str, new: str) -> Path:
    text = model_xml(name).read_text()
    assert old in text
    path = tmp_path / name / "modelDescription.xml"
    path.parent.mkdir()
    path.write_text(text.replace(old, new, 1))
    (path.parent / "equations.html").write_text("<h2>Equations</h2>")
    return path


def test_codegen_accepts_the_repository_xml(tmp_path):
    xml = [model_xml(n) for n in FMU_NAMES]
    result = run_codegen(tmp_path, xml)
    assert result.returncode == 0, result.stderr
    header = (tmp_path / "gen" / "SimplePendulum" / "model_description.h").read_text()
    assert "#define VR_phi 0" in header and "#define SOLVER_RK4 5" in header


@pytest.mark.parametrize("old,new,message", [
    ('name="omega" valueReference="1"', 'name="omega" valueReference="7"', "value references must be"),
    ('<File name="fmu_fmi2.c"/>', '<File name="core.c"/>', "SourceFiles"),
    ('name="der(omega)"', 'name="der(phi)"', "is the derivative of omega"),
    ('<Real unit="m" start="1" min="1e-09"/>', '<Real unit="m" start="-1" min="1e-09"/>', "below its min"),
])
def test_codegen_refuses_inconsistent_xml(tmp_path, old, new, message):
    broken = broken_copy(tmp_path, "SimplePendulum", old, new)
    result = run_codegen(tmp_path, [broken])
    assert result.returncode == 1 and message in result.stderr, result.stderr


def test_codegen_refuses_a_duplicated_guid(tmp_path):
    simple = model_xml("SimplePendulum").read_text()
    guid = simple.split('guid="')[1].split('"')[0]
    double = model_xml("DoublePendulum").read_text()
    other = double.split('guid="')[1].split('"')[0]
    path = broken_copy(tmp_path, "DoublePendulum", other, guid)
    result = run_codegen(tmp_path, [model_xml("SimplePendulum"), path])
    assert result.returncode == 1 and "share a GUID" in result.stderr
    # the build's own check over every description (it generates each FMU alone), naming both files
    check = subprocess.run([sys.executable, str(PROJECT_ROOT / "tools" / "fmu_codegen.py"), "--unique-guids",
                            "--xml", str(model_xml("SimplePendulum")), str(path)], capture_output=True, text=True)
    assert check.returncode == 1 and "share a GUID" in check.stderr and "DoublePendulum" in check.stderr
    fine = subprocess.run([sys.executable, str(PROJECT_ROOT / "tools" / "fmu_codegen.py"), "--unique-guids",
                           "--xml", str(model_xml("SimplePendulum")), str(model_xml("DoublePendulum"))],
                          capture_output=True, text=True)
    assert fine.returncode == 0, fine.stderr
