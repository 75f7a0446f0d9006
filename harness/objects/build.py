"""`harness derive`: an object file to a finished FMU, without CMake.

Generates the model's C and model description (harness.objects.generate), the C header and
documentation from that description (tools/fmu_codegen.py, as the CMake build does), compiles the
framework and the model with the system's C compiler into the platform binary, and packs the FMU.
Everything happens in a temporary folder that is removed also on errors; the FMU appears only
when it is complete.
"""
from __future__ import annotations

import os
import re
import shlex
import shutil
import sys
import tempfile
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from harness.errors import HarnessError
from harness.objects.generate import no_progress, generate
from harness.objects.model_description import SOURCE_FILES
from harness.objects.model_description_fmi3 import build_description
from harness.objects.object_file import ObjectFileError, read_object_file
from harness.output import writable_file, written
from harness.processes import run_program

PROJECT_ROOT = Path(__file__).resolve().parents[2]
FRAMEWORK = PROJECT_ROOT / "fmus" / "framework"
# the version-neutral headers every FMU's sources carry (each version adds its API header: LAYERS)
CORE_HEADERS = tuple(sorted(path.name for path in FRAMEWORK.glob("*.h") if not path.name.endswith("_api.h")))
# The flags of the CMake Release build: same code, same numbers.
C_FLAGS = ("-std=c99", "-O3", "-DNDEBUG", "-fPIC", "-fvisibility=hidden", "-Wall", "-Wextra", "-Wno-unused-parameter")


@dataclass
class DerivedFmu:
    identifier: str
    path: Path       # FMI 2.0: <out>/<identifier>.fmu
    fmi3_path: Path  # FMI 3.0: <out>/fmi3/<identifier>.fmu, as the build lays them out


# What each FMI version's FMU carries besides the model: its API layer (source, header) and platform folder.
LAYERS = {2: ("fmi2_functions.c", "fmi2_api.h", "linux64"), 3: ("fmi3_functions.c", "fmi3_api.h", "x86_64-linux")}


def single_unit(version: int) -> str:
    """The translation unit an importer compiles (SOURCE_FILES for FMI 2.0)."""
    return f"fmu_fmi{version}.c"


def unit_sources(version: int) -> tuple[str, ...]:
    """The C files the single unit includes: the one list of what an FMU compiles."""
    text = (FRAMEWORK / single_unit(version)).read_text()
    return tuple(re.findall(r'^#include "([^"]+[.]c)"', text, flags=re.M))


assert SOURCE_FILES == (single_unit(2),)


def derive_fmu(object_file: str | Path, out: str | Path, progress: Callable[[str], None] = no_progress) -> DerivedFmu:
    """Builds out/<identifier>.fmu (FMI 2.0) and out/fmi3/<identifier>.fmu (FMI 3.0) from an object
    file. Raises HarnessError with one line. `progress` is told each stage as it begins."""
    out = Path(out)
    compiler = shlex.split(os.environ.get("CC", "cc"))
    if shutil.which(compiler[0]) is None:
        raise HarnessError(f"no C compiler: {compiler[0]} is not on PATH (set CC)")
    try:
        identifier = read_object_file(object_file).identifier
    except ObjectFileError as error:
        raise HarnessError(str(error)) from None
    targets = {2: out / f"{identifier}.fmu", 3: out / "fmi3" / f"{identifier}.fmu"}
    for target in targets.values():
        writable_file(target, "--out")  # refused before the work, not after it
    with tempfile.TemporaryDirectory(prefix="derive-") as scratch:
        work = Path(scratch)
        try:
            generated = generate(object_file, work / "generated", progress)
        except ObjectFileError as error:
            raise HarnessError(str(error)) from None
        folder = generated.folder
        result = run_program([sys.executable, str(PROJECT_ROOT / "tools" / "fmu_codegen.py"), "--out",
                              str(work / "generated"), "--models", str(PROJECT_ROOT / "fmus" / "models"),
                              "--sources", *unit_sources(2), "--xml", str(folder / "modelDescription.xml")])
        if result.returncode != 0:
            raise HarnessError(f"{object_file}: the generated model description was refused: "
                               f"{result.stderr.strip().splitlines()[-1]}")
        progress("compiling")
        packed = {version: _package(version, compiler, object_file, generated.identifier, folder, work)
                  for version in targets}
        for version, target in targets.items():
            try:
                target.parent.mkdir(parents=True, exist_ok=True)
            except OSError as error:
                raise HarnessError(f"--out {out}: cannot create the folder {target.parent} "
                                   f"({error.strerror})") from None
            with written(target, binary=True) as sink:  # each FMU appears whole or not at all
                sink.write(packed[version].read_bytes())
    return DerivedFmu(generated.identifier, targets[2], targets[3])


def _package(version: int, compiler: list[str], object_file, identifier: str, folder: Path, work: Path) -> Path:
    """The FMU of one FMI version, packed in work/: the model description, the binary, the sources
    (with buildDescription.xml for FMI 3.0), the object file and the documentation."""
    layer_source, layer_header, platform = LAYERS[version]
    fmu = work / f"fmi{version}"
    sources = fmu / "sources"
    binaries = fmu / "binaries" / platform
    for directory in (sources, binaries, fmu / "documentation"):
        directory.mkdir(parents=True)
    compiled = unit_sources(version)
    for name in (single_unit(version), *(n for n in compiled if n != "physics.c"), layer_header, *CORE_HEADERS):
        shutil.copy(FRAMEWORK / name, sources / name)
    for name in ("physics.c", "physics.h", "model_description.h"):
        shutil.copy(folder / name, sources / name)
    shutil.copy(object_file, sources / f"{identifier}.toml")
    description = folder / "modelDescription.xml" if version == 2 else folder / "fmi3" / "modelDescription.xml"
    shutil.copy(description, fmu / "modelDescription.xml")
    if version == 3:
        (sources / "buildDescription.xml").write_text(build_description(identifier, [single_unit(version)]))
    shutil.copy(folder / "documentation" / "index.html", fmu / "documentation" / "index.html")
    library = binaries / f"{identifier}.so"
    result = run_program([*compiler, *C_FLAGS, "-shared", f"-I{sources}", "-o", str(library),
                          *(str(sources / name) for name in compiled), "-lm"])
    if result.returncode != 0:
        first = next((line for line in result.stderr.splitlines() if "error" in line), result.stderr.strip())
        raise HarnessError(f"{object_file}: compiling the generated C failed: {first}")
    partial = work / f"{identifier}-fmi{version}.fmu"
    with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
        for path in sorted(fmu.rglob("*")):
            if path.is_file():
                archive.write(path, path.relative_to(fmu).as_posix())
    return partial
