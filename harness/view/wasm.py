"""An FMU's C sources built to a WebAssembly module for the live view: the sources the FMU carries
(its model description lists them), with the importer's callbacks (web/importer.c) beside them,
compiled by clang for wasm32-wasi with the flags of web/wasm.flags, which the CMake build uses too.
So any FMU this project makes, a user's derived object included, runs in the page."""
from __future__ import annotations

import shutil
from xml.etree import ElementTree
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from harness.archives import extract_members, open_archive, scratch_folder
from harness.errors import HarnessError
from harness.fmi.fmu_instance import read_description
from harness.processes import run_program

PROJECT_ROOT = Path(__file__).resolve().parents[2]
WEB = PROJECT_ROOT / "web"
WASI_LIBC = Path("/usr/lib/wasm32-wasi/libc.a")
MISSING_TOOLS = ("the live view builds the FMUs' WebAssembly modules with clang for wasm32-wasi and Debian's "
                 "wasi-libc: install clang, lld, wasi-libc and libclang-rt-14-dev-wasm32 (./run does, as root)")


def wasm_flags() -> list[str]:
    lines = (WEB / "wasm.flags").read_text().splitlines()
    return [line.strip() for line in lines if line.strip() and not line.lstrip().startswith("#")]


def check_tools() -> str:
    """The clang that builds the modules, or a HarnessError saying what to install."""
    clang = shutil.which("clang")
    if clang is None or not WASI_LIBC.exists() or shutil.which("wasm-ld") is None:
        raise HarnessError(MISSING_TOOLS)
    return clang


def build_module(fmu: Path, clang: str) -> bytes:
    """The FMU's sources compiled to a module exporting the fmi2* functions, or a HarnessError."""
    md = read_description(fmu)
    if md.fmiVersion != "2.0" or md.coSimulation is None:
        raise HarnessError(f"{fmu}: the live view runs FMI 2.0 Co-Simulation FMUs (this one is FMI {md.fmiVersion}"
                           f"{'' if md.coSimulation else ' without Co-Simulation'}): use its FMI 2.0 build")
    sources = _source_files(fmu)
    if not sources:
        raise HarnessError(f"{fmu}: carries no C sources (its model description lists none), so it cannot run in "
                           "the browser")
    with scratch_folder("wasm-") as work:
        with open_archive(fmu, str(fmu)) as archive:
            extract_members(archive, work, lambda name: name.startswith("sources/"), str(fmu))
        folder = work / "sources"
        missing = [name for name in sources if not (folder / name).is_file()]
        if missing:
            raise HarnessError(f"{fmu}: its model description lists sources it does not carry: {', '.join(missing)}")
        module = work / "module.wasm"
        result = run_program([clang, *wasm_flags(), f"-I{folder}", *[str(folder / n) for n in sources],
                              str(WEB / "importer.c"), "-o", str(module)])
        if result.returncode != 0 or not module.is_file():
            first = next((line for line in result.stderr.splitlines() if "error" in line), result.stderr.strip()[:300])
            raise HarnessError(f"{fmu}: its sources do not build for WebAssembly: {first}")
        return module.read_bytes()


def _source_files(fmu: Path) -> list[str]:
    """The C files the model description lists for Co-Simulation (fmpy does not keep them)."""
    with open_archive(fmu, str(fmu)) as archive:
        root = ElementTree.fromstring(archive.read("modelDescription.xml"))
    return [f.get("name", "") for f in root.findall("./CoSimulation/SourceFiles/File")]


def build_modules(fmus: list[Path]) -> dict[Path, bytes]:
    """Each FMU's module, built side by side (clang runs in processes of its own)."""
    clang = check_tools()
    with ThreadPoolExecutor(max_workers=4) as pool:
        built = list(pool.map(lambda fmu: build_module(fmu, clang), fmus))
    return dict(zip(fmus, built))
