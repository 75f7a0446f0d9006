"""An FMU's C sources built to a WebAssembly module for the live view: the sources the FMU carries
(its model description lists them), with the importer's callbacks (web/importer.c) beside them,
compiled by clang for wasm32-wasi with the flags of web/wasm.flags, which the CMake build uses too.
So any FMU this project makes, a user's derived object included, runs in the page."""
from __future__ import annotations

import shutil
from contextlib import ExitStack
from pathlib import Path
from xml.etree import ElementTree

from harness.archives import extract_members, open_archive, scratch_folder
from harness.errors import HarnessError
from harness.fmi.fmu_instance import read_description
from harness.processes import run_programs

PROJECT_ROOT = Path(__file__).resolve().parents[2]
WEB = PROJECT_ROOT / "web"
WASI_LIBC = Path("/usr/lib/wasm32-wasi/libc.a")
MISSING_TOOLS = ("the live view builds the FMUs' WebAssembly modules with clang for wasm32-wasi and Debian's "
                 "wasi-libc: install clang, lld, wasi-libc and libclang-rt-14-dev-wasm32 (./run does, as root)")
PARALLEL_BUILDS = 4


def wasm_flags() -> list[str]:
    lines = (WEB / "wasm.flags").read_text().splitlines()
    return [line.strip() for line in lines if line.strip() and not line.lstrip().startswith("#")]


def check_tools() -> str:
    """The clang that builds the modules, or a HarnessError saying what to install."""
    clang = shutil.which("clang")
    if clang is None or not WASI_LIBC.exists() or shutil.which("wasm-ld") is None:
        raise HarnessError(MISSING_TOOLS)
    return clang


def _source_files(fmu: Path) -> list[str]:
    """The C files the model description lists for Co-Simulation (fmpy does not keep them)."""
    with open_archive(fmu, str(fmu)) as archive:
        root = ElementTree.fromstring(archive.read("modelDescription.xml"))
    return [f.get("name", "") for f in root.findall("./CoSimulation/SourceFiles/File")]


def _prepared(fmu: Path, work: Path, clang: str) -> list[str]:
    """The FMU's sources taken out into work/sources, and the command that builds work/module.wasm."""
    md = read_description(fmu)
    if md.fmiVersion != "2.0" or md.coSimulation is None:
        raise HarnessError(f"{fmu}: the live view runs FMI 2.0 Co-Simulation FMUs (this one is FMI {md.fmiVersion}"
                           f"{'' if md.coSimulation else ' without Co-Simulation'}): use its FMI 2.0 build")
    sources = _source_files(fmu)
    if not sources:
        raise HarnessError(f"{fmu}: carries no C sources (its model description lists none), so it cannot run in "
                           "the browser")
    with open_archive(fmu, str(fmu)) as archive:
        extract_members(archive, work, lambda name: name.startswith("sources/"), str(fmu))
    folder = work / "sources"
    missing = [name for name in sources if not (folder / name).is_file()]
    if missing:
        raise HarnessError(f"{fmu}: its model description lists sources it does not carry: {', '.join(missing)}")
    return [clang, *wasm_flags(), f"-I{folder}", *[str(folder / n) for n in sources], str(WEB / "importer.c"),
            "-o", str(work / "module.wasm")]


def build_modules(fmus: list[Path]) -> dict[Path, bytes]:
    """Each FMU's module, compiled side by side; an interrupt ends every compiler still running, and
    the work folders go in any case."""
    clang = check_tools()
    with ExitStack() as stack:
        works = [stack.enter_context(scratch_folder("wasm-")) for _ in fmus]
        commands = [_prepared(fmu, work, clang) for fmu, work in zip(fmus, works)]
        modules = {}
        for fmu, work, result in zip(fmus, works, run_programs(commands, PARALLEL_BUILDS)):
            module = work / "module.wasm"
            if result.returncode != 0 or not module.is_file():
                first = next((line for line in result.stderr.splitlines() if "error" in line),
                             result.stderr.strip()[:300])
                raise HarnessError(f"{fmu}: its sources do not build for WebAssembly: {first}")
            modules[fmu] = module.read_bytes()
        return modules
