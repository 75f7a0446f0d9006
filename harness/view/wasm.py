"""An FMU's C sources built to a WebAssembly module for the live view: the sources the FMU carries
(its model description lists them), with the importer's callbacks (web/importer.c) beside them,
compiled by clang for wasm32-wasi with the flags of web/wasm.flags, which the CMake build uses too.
So any FMU this project makes, a user's derived object included, runs in the page. A module built once is
kept in a cache under the name of what went into it (the sources' bytes, the command, the compiler and the
libraries it links): the same FMU in another scene or another run takes it from there."""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
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
CACHED_MODULES = 64  # the cache's bound: the modules used longest ago go first
WASM_MAGIC = b"\0asm"


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


def cache_folder() -> Path | None:
    """Where built modules are kept: $PENDULUM_WASM_CACHE (empty: nowhere), else the user's cache folder."""
    configured = os.environ.get("PENDULUM_WASM_CACHE")
    if configured is not None:
        return Path(configured) if configured else None
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "pendulum-fmus" / "wasm"


def compiler_identity(clang: str) -> str:
    """The compiler's version and a digest of the libraries every module links (wasi-libc, clang's builtins):
    an upgrade of either that keeps the version builds the modules again."""
    version = subprocess.run([clang, "--version"], capture_output=True, text=True).stdout
    builtins = subprocess.run([clang, "--target=wasm32-wasi", "-print-libgcc-file-name"], capture_output=True,
                              text=True).stdout.strip()
    digest = hashlib.sha256()
    for library in (WASI_LIBC, Path(builtins)):
        try:
            digest.update(library.read_bytes())
        except OSError:  # not found: the compile says so
            digest.update(b"missing")
    return f"{version}\n{digest.hexdigest()}"


def module_key(compiler: str, command: list[str], work: Path) -> str:
    """The name of a module in the cache: what goes into it (the compiler's identity, the command with the
    files it names in their order, each file of the FMU's sources and the importer's), with the work folder's
    path and the project's replaced by a placeholder, so that neither where the work is done nor the clone
    counts."""
    digest = hashlib.sha256()
    for part in (compiler, *(word.replace(str(work), "<work>").replace(str(WEB), "<web>") for word in command[1:])):
        digest.update(part.encode() + b"\0")
    for path in sorted(p for p in (work / "sources").rglob("*") if p.is_file()):
        digest.update(str(path.relative_to(work)).encode() + b"\0" + path.read_bytes() + b"\0")
    digest.update((WEB / "importer.c").read_bytes())
    return digest.hexdigest()


def _cached(folder: Path | None, key: str) -> bytes | None:
    if folder is None:
        return None
    try:
        module = (folder / f"{key}.wasm").read_bytes()
        os.utime(folder / f"{key}.wasm")  # used now: the last to go
    except OSError:
        return None
    return module if module.startswith(WASM_MAGIC) else None  # anything else is built again


def _keep(folder: Path | None, key: str, module: bytes) -> None:
    """Into the cache, whole or not at all (another process may read it at once); a cache that cannot be
    written is no error: the module was built."""
    if folder is None:
        return
    part = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        handle, part = tempfile.mkstemp(dir=folder, prefix=f".{key}-", suffix=".part")
        with os.fdopen(handle, "wb") as sink:
            sink.write(module)
        os.replace(part, folder / f"{key}.wasm")
        part = None
        kept = sorted(folder.glob("*.wasm"), key=lambda p: p.stat().st_mtime)
        for old in kept[:max(0, len(kept) - CACHED_MODULES)]:
            old.unlink(missing_ok=True)
    except OSError:
        pass
    finally:
        if part is not None:
            Path(part).unlink(missing_ok=True)


def build_modules(fmus: list[Path], cache: Path | None = None) -> dict[Path, bytes]:
    """Each FMU's module, from the cache (`cache`, else cache_folder()) or compiled side by side; an interrupt
    ends every compiler still running, and the work folders go in any case."""
    clang = check_tools()
    compiler = compiler_identity(clang)
    cache = cache if cache is not None else cache_folder()
    with ExitStack() as stack:
        works = [stack.enter_context(scratch_folder("wasm-")) for _ in fmus]
        commands = [_prepared(fmu, work, clang) for fmu, work in zip(fmus, works)]
        keys = [module_key(compiler, command, work) for command, work in zip(commands, works)]
        modules = {fmu: module for fmu, key in zip(fmus, keys) if (module := _cached(cache, key)) is not None}
        built = [k for k, fmu in enumerate(fmus) if fmu not in modules]
        for k, result in zip(built, run_programs([commands[k] for k in built], PARALLEL_BUILDS)):
            module = works[k] / "module.wasm"
            if result.returncode != 0 or not module.is_file():
                first = next((line for line in result.stderr.splitlines() if "error" in line),
                             result.stderr.strip()[:300])
                raise HarnessError(f"{fmus[k]}: its sources do not build for WebAssembly: {first}")
            modules[fmus[k]] = module.read_bytes()
            _keep(cache, keys[k], modules[fmus[k]])
        return modules


def main(argv: list[str] | None = None) -> int:
    """The build's own step (CMakeLists.txt): an FMU's module written to --out and kept in --cache, the folder the
    tests' live views start from, so that a module is compiled once per build and not again per test run."""
    import argparse
    import sys
    parser = argparse.ArgumentParser(description=main.__doc__.splitlines()[0])
    parser.add_argument("fmu", type=Path)
    parser.add_argument("--out", type=Path, required=True, help="the module (.wasm)")
    parser.add_argument("--cache", type=Path, required=True, help="the build's cache of modules")
    args = parser.parse_args(argv)
    try:
        module = build_modules([args.fmu], args.cache)[args.fmu]
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_bytes(module)
    except (HarnessError, OSError) as error:
        print(f"harness.view.wasm: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
