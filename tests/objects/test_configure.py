"""CMake's configure step refuses a Python that cannot run the objects' generator, naming what is
missing and what to do, instead of failing half-way through the build."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# Imported first by a Python that has it on PYTHONPATH: makes the named top-level modules unimportable,
# as in a Python where they were never installed.
BLOCKER = """
import os, sys

class _Blocked:
    names = set(filter(None, os.environ.get("BLOCKED_MODULES", "").split(",")))

    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in self.names:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None

sys.meta_path.insert(0, _Blocked())
"""


def python_without(tmp_path: Path, *modules: str) -> Path:
    """An executable that runs this test's Python with `modules` unimportable."""
    folder = tmp_path / "blocker"
    folder.mkdir()
    (folder / "sitecustomize.py").write_text(BLOCKER)
    wrapper = tmp_path / "python-without"
    wrapper.write_text(f'#!/bin/sh\nPYTHONPATH="{folder}${{PYTHONPATH:+:$PYTHONPATH}}" '
                       f'BLOCKED_MODULES="{",".join(modules)}" '
                       f'exec "{sys.executable}" "$@"\n')
    wrapper.chmod(0o755)
    return wrapper


def configure(tmp_path: Path, python: Path | str) -> subprocess.CompletedProcess:
    return subprocess.run(["cmake", "-S", str(ROOT), "-B", str(tmp_path / "build"), "-DFMU_CROSS=OFF", "-DFMU_WASM=OFF",
                           f"-DOBJECTS_PYTHON={python}"], capture_output=True, text=True)


pytestmark = pytest.mark.skipif(shutil.which("cmake") is None, reason="cmake is not installed")


def test_a_python_without_numpy_is_refused_at_configure(tmp_path):
    python = python_without(tmp_path, "numpy")
    # the wrapper really is such a Python: SymPy imports, NumPy does not
    assert subprocess.run([str(python), "-c", "import sympy"]).returncode == 0
    assert subprocess.run([str(python), "-c", "import numpy"], capture_output=True).returncode != 0
    result = configure(tmp_path, python)
    assert result.returncode != 0
    message = " ".join(result.stderr.split())  # CMake wraps its messages
    assert f"{python} cannot import numpy, which deriving the objects" in message, message
    assert "./run demo" in message and "-DOBJECTS_PYTHON=" in message
    assert not (tmp_path / "build" / "Makefile").exists()


def test_every_missing_module_is_named_in_one_message(tmp_path):
    result = configure(tmp_path, python_without(tmp_path, "numpy", "sympy"))
    assert result.returncode != 0
    message = " ".join(result.stderr.split())
    assert "cannot import numpy, sympy, which deriving" in message, message
    assert message.count("CMake Error") == 1


def test_a_python_that_does_not_run_is_refused_too(tmp_path):
    result = configure(tmp_path, tmp_path / "no-such-python")
    assert result.returncode != 0
    message = " ".join(result.stderr.split())
    assert "no-such-python cannot run the generator's import check" in message, message
    assert "-DOBJECTS_PYTHON=" in message


def test_the_check_passes_with_the_projects_python():
    """The probe itself, as CMake runs it: this Python has everything, so nothing is named."""
    result = subprocess.run([sys.executable, str(ROOT / "tools" / "generator_imports.py"), "harness.objects.generate",
                             "harness.objects.model_description_fmi3"], capture_output=True, text=True,
                            env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"})
    assert (result.returncode, result.stdout) == (0, ""), result.stdout + result.stderr


def _cached_python(build: Path) -> str:
    return next(line.split("=", 1)[1] for line in (build / "CMakeCache.txt").read_text().splitlines()
                if line.startswith("Python3_EXECUTABLE:"))


def test_an_activated_environment_does_not_reconfigure_the_build(tmp_path):
    """FindPython prefers an activated virtual environment: without the kept interpreter, a build
    configured once from `./run` and once after `source .venv/bin/activate` rebuilt every FMU."""
    assert configure(tmp_path, sys.executable).returncode == 0
    first = _cached_python(tmp_path / "build")
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python3").symlink_to(sys.executable)
    activated = {**os.environ, "VIRTUAL_ENV": str(venv), "PATH": f"{venv / 'bin'}{os.pathsep}{os.environ['PATH']}"}
    again = subprocess.run(["cmake", "-S", str(ROOT), "-B", str(tmp_path / "build")], capture_output=True, text=True,
                           env=activated)
    assert again.returncode == 0, again.stderr
    assert _cached_python(tmp_path / "build") == first != str(venv / "bin" / "python3")


def test_the_build_is_driven_by_the_cmake_that_configured_it(tmp_path):
    """An activated environment puts PyPI's CMake before Debian's on PATH; a build configured by one and
    built by the other regenerated its build system and rebuilt every FMU."""
    from harness.fmi.fmus import configured_cmake
    assert configured_cmake(tmp_path) == "cmake"  # not configured yet: the one on PATH
    recorded = tmp_path / "bin" / "cmake"
    recorded.parent.mkdir()
    recorded.write_text("#!/bin/sh\n")
    recorded.chmod(0o755)
    (tmp_path / "CMakeCache.txt").write_text(f"CMAKE_BUILD_TYPE:STRING=Release\nCMAKE_COMMAND:INTERNAL={recorded}\n")
    assert configured_cmake(tmp_path) == str(recorded)
    recorded.unlink()  # a CMake since removed: the one on PATH again
    assert configured_cmake(tmp_path) == "cmake"
    run_script = (ROOT / "run").read_text()
    assert "CMAKE_COMMAND:INTERNAL=" in run_script  # ./run follows the same rule


def test_run_starts_in_a_folder_never_built(tmp_path):
    """A fresh clone has no build/CMakeCache.txt: reading the recorded CMake from it must not end
    `./run` (under `set -e` the failed read once stopped it with exit code 2 before the build)."""
    import hashlib
    import shutil
    (tmp_path / "run").write_bytes((ROOT / "run").read_bytes())
    (tmp_path / "run").chmod(0o755)
    (tmp_path / "pyproject.toml").write_bytes((ROOT / "pyproject.toml").read_bytes())
    venv_bin = tmp_path / ".venv" / "bin"
    venv_bin.mkdir(parents=True)
    stamp = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()[:16]
    (tmp_path / ".venv" / f".installed-{stamp}").touch()
    calls = tmp_path / "calls.txt"
    tools = tmp_path / "tools"
    tools.mkdir()
    for name, body in (("python", f'echo "python $*" >> {calls}\n'), ("cmake", f'echo "cmake $*" >> {calls}\n')):
        target = (venv_bin if name == "python" else tools) / name
        target.write_text(f"#!/bin/sh\n{body}")
        target.chmod(0o755)
    # only what the script uses: no apt-get or npm, so it installs nothing from the network
    for tool in ("bash", "sh", "sed", "cat", "sha256sum", "cut", "mkdir", "id", "dirname", "basename", "nproc"):
        (tools / tool).symlink_to(shutil.which(tool))
    result = subprocess.run([str(tmp_path / "run"), "demo", "--out", "x"], capture_output=True, text=True,
                            env={"PATH": str(tools), "HOME": str(tmp_path)})
    assert result.returncode == 0, result.stdout + result.stderr
    lines = calls.read_text().splitlines()
    assert lines[-1] == "python -m harness demo --out x", lines
    # the demo builds what it shows itself (harness demo, for this machine): ./run builds nothing for it
    assert not any(line.startswith("cmake") for line in lines), lines
    # before it: bytecode for the environment (once: where its packages are, then them) and for the
    # project's modules (each time)
    assert any("sysconfig" in line for line in lines[:-1])
    assert [line for line in lines[:-1] if "compileall" in line] == \
        ["python -m compileall -q -j0 ", "python -m compileall -q -j0 harness tools benchmarks tests"], lines
    calls.unlink()
    again = subprocess.run([str(tmp_path / "run"), "demo", "--out", "x"], capture_output=True, text=True,
                           env={"PATH": str(tools), "HOME": str(tmp_path)})
    assert again.returncode == 0, again.stdout + again.stderr
    lines = calls.read_text().splitlines()
    assert lines == ["python -m compileall -q -j0 harness tools benchmarks tests", "python -m harness demo --out x"]
    calls.unlink()
    # the tests: every FMU, for every platform whose compiler is installed, before pytest starts
    tests = subprocess.run([str(tmp_path / "run"), "test", "-x"], capture_output=True, text=True,
                           env={"PATH": str(tools), "HOME": str(tmp_path)})
    assert tests.returncode == 0, tests.stdout + tests.stderr
    lines = calls.read_text().splitlines()
    assert lines[-3] == "cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DFMU_CROSS=ON", lines
    assert lines[-2] == "cmake --build build -j2" and lines[-1].startswith("python -m pytest -n "), lines


@pytest.mark.parametrize("cache, makefile, fails_once, calls_made", [
    ({}, True, False, ["build"]),
    ({"OBJECTS_PYTHON:FILEPATH": "/another/python"}, True, False, ["configure", "build"]),
    ({"CMAKE_BUILD_TYPE:STRING": "Debug"}, True, False, ["configure", "build"]),
    ({"CMAKE_HOME_DIRECTORY:INTERNAL": "/another/tree"}, True, False, ["configure", "build"]),
    ({}, False, False, ["configure", "build"]),  # a configure that failed: its cache, no build system
    ({}, True, True, ["build", "configure", "build"]),  # a build alone that fails: once more, configured
])
def test_a_build_folder_configured_alike_is_only_built(tmp_path, monkeypatch, cache, makefile, fails_once,
                                                        calls_made):
    """Configuring again costs seconds per command; `cmake --build` configures by itself when a CMake file or
    the set of object files changes, so the harness configures only a folder set up otherwise, or one whose
    build alone fails."""
    from harness.fmi.fmus import PROJECT_ROOT, build_fmus
    log, failed = tmp_path / "calls.log", tmp_path / "failed-once"
    recorded = tmp_path / "bin" / "cmake"
    recorded.parent.mkdir()
    fail = f'if [ "$1" = --build ] && [ ! -f {failed} ]; then : > {failed}; exit 2; fi\n' if fails_once else ""
    recorded.write_text(f'#!/bin/sh\necho "$*" >> {log}\n{fail}')
    recorded.chmod(0o755)
    entries = {"CMAKE_COMMAND:INTERNAL": str(recorded), "CMAKE_BUILD_TYPE:STRING": "Release",
               "OBJECTS_PYTHON:UNINITIALIZED": sys.executable, "CMAKE_HOME_DIRECTORY:INTERNAL": str(PROJECT_ROOT),
               "FMU_CROSS:BOOL": "ON"}
    for key, value in cache.items():  # replaces the entry of the same name, whatever its type
        entries = {k: v for k, v in entries.items() if k.split(":")[0] != key.split(":")[0]} | {key: value}
    (tmp_path / "CMakeCache.txt").write_text("".join(f"{key}={value}\n" for key, value in entries.items()))
    if makefile:
        (tmp_path / "Makefile").write_text("all:\n")
    monkeypatch.setenv("PENDULUM_BUILD_DIR", str(tmp_path))
    monkeypatch.delenv("PENDULUM_SKIP_BUILD", raising=False)
    build_fmus()
    calls = log.read_text().splitlines()
    assert ["build" if call.startswith("--build") else "configure" for call in calls] == calls_made, calls
    assert calls[-1] == f"--build {tmp_path} -j2"
    for call in calls:
        if not call.startswith("--build"):
            assert call.startswith(f"-S {PROJECT_ROOT} -B {tmp_path} ") and "-DCMAKE_BUILD_TYPE=Release" in call


def test_a_python_with_sympy_alone_is_refused_naming_what_it_lacks(tmp_path):
    """Without fmpy the FMU instance module hands a stand-in to ctypes at import, which took the check's
    process down with a segmentation fault: the missing modules are named all the same."""
    result = configure(tmp_path, python_without(tmp_path, "numpy", "fmpy", "scipy", "matplotlib"))
    assert result.returncode != 0
    message = " ".join(result.stderr.split())
    assert "cannot import fmpy, numpy" in message and "Segmentation" not in message, message


def test_an_import_that_ends_the_process_still_names_what_was_missing(tmp_path):
    """A module that crashes after a missing import (an extension handed a stand-in): the names found before
    the crash are the answer, with exit status 1."""
    (tmp_path / "crashing.py").write_text("print('what a module prints is no missing name')\nimport numpy\nimport os\n"
                                          "os.abort()\n")
    python = python_without(tmp_path, "numpy")
    result = subprocess.run([str(python), str(ROOT / "tools" / "generator_imports.py"), "crashing"],
                            capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(tmp_path)})
    assert (result.returncode, result.stdout) == (1, "numpy\n"), result


@pytest.mark.parametrize("cross, fmus, every_platform, calls_made", [
    # a folder that a part configures first: this machine's binaries only, the targets asked for
    (None, ["SimplePendulum", "fmi3/Spring"], None,
     ["-DFMU_CROSS=OFF", "--target SimplePendulum_fmu Spring_fmi3_fmu cosim_core record_loop"]),
    ("OFF", None, None, ["-DFMU_CROSS=ON", ""]),  # everything: every platform, for good
    ("ON", ["SimplePendulum"], None, ["--target SimplePendulum_fmu cosim_core record_loop"]),  # kept as it is
    ("OFF", ["Spring"], True, ["-DFMU_CROSS=ON", "--target Spring_fmu cosim_core record_loop"]),  # an export
])
def test_a_part_is_built_for_this_machine_and_everything_for_every_platform(tmp_path, monkeypatch, cross, fmus,
                                                                            every_platform, calls_made):
    """A newcomer's demo waits for the FMUs it shows and this machine's binaries; the tests, the benchmarks
    and an export ask for the other platforms' binaries too (FMU_CROSS)."""
    from harness.fmi.fmus import PROJECT_ROOT, build_fmus
    log = tmp_path / "calls.log"
    tools = tmp_path / "bin"
    tools.mkdir()
    (tools / "cmake").write_text(f'#!/bin/sh\necho "$*" >> {log}\n')
    (tools / "cmake").chmod(0o755)
    monkeypatch.setenv("PATH", f"{tools}{os.pathsep}{os.environ['PATH']}")
    folder = tmp_path / "build"
    folder.mkdir()
    if cross is not None:
        (folder / "CMakeCache.txt").write_text(
            f"CMAKE_COMMAND:INTERNAL={tools / 'cmake'}\nCMAKE_BUILD_TYPE:STRING=Release\n"
            f"OBJECTS_PYTHON:FILEPATH={sys.executable}\nCMAKE_HOME_DIRECTORY:INTERNAL={PROJECT_ROOT}\n"
            f"FMU_CROSS:BOOL={cross}\n")
        (folder / "Makefile").write_text("all:\n")
    monkeypatch.setenv("PENDULUM_BUILD_DIR", str(folder))
    monkeypatch.delenv("PENDULUM_SKIP_BUILD", raising=False)
    build_fmus(fmus, every_platform=every_platform)
    calls = log.read_text().splitlines()
    assert len(calls) == len(calls_made), calls
    for call, expected in zip(calls, calls_made):
        if expected.startswith("-D"):
            assert call.startswith(f"-S {PROJECT_ROOT} -B {folder} ") and call.endswith(expected), calls
        else:
            assert call == f"--build {folder} -j2" + (f" {expected}" if expected else ""), calls
