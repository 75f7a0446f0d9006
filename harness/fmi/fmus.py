"""Where the built FMUs are, and building them with CMake when they are missing."""
from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path

from harness.errors import HarnessError
from harness.objects.registry import PROJECT_ROOT, handwritten_names, object_names
from harness.processes import run_program

# Every object file in modelDescription/ and the hand-written models beside them.
FMU_NAMES = object_names() + handwritten_names()
# A project FMU in FMI 3.0 is named as it lies in the build: fmi3/<name>.
FMI3_FOLDER = "fmi3"


def project_fmu_name(name: str) -> bool:
    """One of the project's FMUs: <name> (FMI 2.0) or fmi3/<name> (FMI 3.0)."""
    return name in FMU_NAMES or (name.startswith(f"{FMI3_FOLDER}/") and name[len(FMI3_FOLDER) + 1:] in FMU_NAMES)


def build_dir() -> Path:
    return Path(os.environ.get("PENDULUM_BUILD_DIR", PROJECT_ROOT / "build"))


# The harness's own C loops (loaded through ctypes, harness/fmi/native_calls.py), built with any FMU.
LOOP_TARGETS = ("cosim_core", "record_loop")


def fmu_target(name: str) -> str:
    """The CMake target that packs a project FMU: <name>_fmu, or <name>_fmi3_fmu for fmi3/<name>."""
    prefix = f"{FMI3_FOLDER}/"
    return f"{name[len(prefix):]}_fmi3_fmu" if name.startswith(prefix) else f"{name}_fmu"


def build_fmus(fmus: Iterable[str] | None = None, quiet: bool = True, programs: Iterable[str] = (),
               every_platform: bool | None = None) -> None:
    """Configure and build with CMake (incremental: cheap when nothing changed): everything, or only the
    FMUs named (project names, fmi3/<name> for FMI 3.0) and `programs` (build/bin targets) with the
    harness's C loops. A build folder that a partial build configures first gets this machine's binaries
    only (FMU_CROSS=OFF: the other platforms' compilers take three times as long); a build of everything
    or one with every_platform (an export) turns the other platforms on for good. Skipped when
    PENDULUM_SKIP_BUILD=1, e.g. for a sanitizer build that must not be reconfigured."""
    if os.environ.get("PENDULUM_SKIP_BUILD") == "1":
        return
    if shutil.which("cmake") is None:
        raise HarnessError("cmake is not on PATH: it is needed to build the FMUs")
    targets = None if fmus is None and not programs else \
        [*dict.fromkeys(fmu_target(name) for name in fmus or ())] + [*LOOP_TARGETS, *programs]
    if every_platform is None:
        every_platform = targets is None
    # quiet: the tools' messages are kept back and only the first error line is reported (make's own
    # lines about an interrupt never reach the terminal)
    output = subprocess.DEVNULL if quiet else None
    errors = subprocess.PIPE if quiet else None
    try:
        build_dir().mkdir(parents=True, exist_ok=True)
        lock = open(build_dir() / ".build.lock", "w")
    except OSError as error:
        raise HarnessError(f"cannot write the build folder {build_dir()}: {error.strerror}") from None
    # one build at a time in a folder (parallel test workers, two commands at once): a second waits
    with lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        _build(output, errors, targets, every_platform)


def configured_cmake(folder: Path) -> str:
    """The CMake that configured the build folder, else the one on PATH. Another CMake (an activated
    environment's, from PyPI, beside Debian's) would regenerate the build system and rebuild every FMU."""
    recorded = cache_entries(folder).get("CMAKE_COMMAND")
    return recorded if recorded and os.access(recorded, os.X_OK) else "cmake"


def cache_entries(folder: Path) -> dict[str, str]:
    """The entries of a build folder's CMakeCache.txt (NAME:TYPE=value) by name; none when it has none."""
    cache = folder / "CMakeCache.txt"
    entries = {}
    if cache.is_file():
        for line in cache.read_text(errors="replace").splitlines():
            name, _, typed = line.partition(":")
            entries[name] = typed.partition("=")[2]
    return entries


def configured_alike(folder: Path, settings: dict[str, str]) -> bool:
    """Whether the build folder was configured, to the end, from this tree with these settings. Then
    `cmake --build` alone is enough for the harness: it configures again by itself when a CMake file,
    web/wasm.flags or the set of object files or generator modules changed. What only a configure looks
    for (compilers installed since, the generator's imports) `./run` finds: it always configures."""
    if not any((folder / name).is_file() for name in ("Makefile", "build.ninja")):
        return False  # a configure that failed writes its cache but no build system
    found = cache_entries(folder)
    expected = {"CMAKE_HOME_DIRECTORY": str(PROJECT_ROOT), **settings}
    return all(found.get(name) == value for name, value in expected.items())


def _build(output, errors, targets: list[str] | None, every_platform: bool) -> None:
    cmake = configured_cmake(build_dir())
    settings = {"CMAKE_BUILD_TYPE": "Release", "OBJECTS_PYTHON": sys.executable}
    if every_platform:
        settings["FMU_CROSS"] = "ON"
    elif "FMU_CROSS" not in cache_entries(build_dir()):
        settings["FMU_CROSS"] = "OFF"  # configured first for a part: this machine's binaries
    configure = [cmake, "-S", str(PROJECT_ROOT), "-B", str(build_dir())] + [f"-D{name}={value}"
                                                                            for name, value in settings.items()]
    build = [cmake, "--build", str(build_dir()), "-j2"] + (["--target", *targets] if targets else [])
    if configured_alike(build_dir(), settings):
        if run_program(build, stdout=output, stderr=errors).returncode == 0:
            return
        # a build alone can fail where a configure would mend it (a module removed from the generator):
        # once more from the configure, whose failure is then the one reported
    for command in (configure, build):
        result = run_program(command, stdout=output, stderr=errors)
        if result.returncode != 0:
            lines = (result.stderr or "").splitlines()
            first = next((line.strip() for line in lines if "error" in line.lower()), lines[0].strip() if lines else "")
            raise HarnessError(f"building the FMUs failed: {' '.join(command[:2])} exited with {result.returncode}"
                               + (f": {first}" if first else ""))


def locate_fmu(name: str, build_if_missing: bool = True) -> Path:
    """Path of build/fmus/<name>.fmu (a name such as SimplePendulum, or fmi3/SimplePendulum for FMI 3.0);
    a path to an existing .fmu is returned as it is."""
    candidate = Path(name)
    if candidate.suffix == ".fmu":
        if not candidate.is_file():
            raise HarnessError(f"{candidate}: no such FMU file")
        return candidate
    if not project_fmu_name(name):
        raise HarnessError(f"unknown FMU {name!r}: expected a .fmu path or one of {', '.join(FMU_NAMES)} "
                           f"(FMI 2.0; {FMI3_FOLDER}/<name> for FMI 3.0)")
    path = build_dir() / "fmus" / f"{name}.fmu"
    if not path.is_file() and build_if_missing:
        build_fmus([name])
    if not path.is_file():
        raise HarnessError(f"{path} does not exist: build the FMUs with cmake -S . -B build && cmake --build build")
    return path
