"""The binaries for other platforms in every FMU (Windows x86_64 and x86, aarch64 Linux), made by
Debian's cross compilers: where each sits, that each exports exactly the FMI functions of the
x86_64 Linux binary and needs only the platform's C runtime, and that each gives the x86_64 Linux
binary's numbers bit for bit when it runs: the Windows DLLs under Wine, the aarch64 binaries under
qemu-user, each loaded by the same small importer (tools/fmu_driver.c) built for its platform."""
from __future__ import annotations

import math
import os
import re
import shutil
import struct
import subprocess
import tempfile
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description

from harness.fmi.fmus import FMU_NAMES, PROJECT_ROOT, build_dir
from harness.fmi.methods import METHOD, SOLVERS

DRIVER = PROJECT_ROOT / "tools" / "fmu_driver.c"
INSTALL = "./run installs it when it runs as root"
# platform folder -> (FMI version, cross compiler, suffix)
PLATFORMS = {
    "win64": (2, "x86_64-w64-mingw32-gcc", "dll"), "win32": (2, "i686-w64-mingw32-gcc", "dll"),
    "x86_64-windows": (3, "x86_64-w64-mingw32-gcc", "dll"), "x86-windows": (3, "i686-w64-mingw32-gcc", "dll"),
    "aarch64-linux": (3, "aarch64-linux-gnu-gcc", "so"),
}
NATIVE = {2: "linux64", 3: "x86_64-linux"}
# 32-bit Wine lives in an i386 Debian of its own, which ./run test makes when run as root
I386_ROOT = Path(os.environ.get("PENDULUM_I386_ROOT", "/var/cache/pendulum-fmus/i386-wine"))


def i386_problem() -> str | None:
    """Why the x86 Windows DLLs cannot run here, or None."""
    if shutil.which("i686-w64-mingw32-gcc") is None:
        return f"i686-w64-mingw32-gcc is not installed (Debian package gcc-mingw-w64-i686; {INSTALL})"
    if not (I386_ROOT / "usr" / "bin" / "wine").is_file():
        return (f"32-bit Wine cannot be installed beside wine64 on this Debian, and there is no i386 Debian with "
                f"wine32 at {I386_ROOT} (./run test makes it when it runs as root)")
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        return f"entering the i386 Debian at {I386_ROOT} (chroot, and a mount of /proc) needs root"
    return None
RUNTIME = {"dll": {"kernel32.dll", "msvcrt.dll"}, "so": {"libc.so.6", "libm.so.6"}}


def fmu_path(name: str, version: int) -> Path:
    return build_dir() / "fmus" / (f"{name}.fmu" if version == 2 else f"fmi3/{name}.fmu")


def needs(program: str, package: str) -> None:
    if shutil.which(program) is None:
        pytest.skip(f"{program} is not installed (Debian package {package}; {INSTALL})")


def member(name: str, version: int, platform: str) -> str:
    suffix = PLATFORMS[platform][2] if platform in PLATFORMS else "so"
    return f"binaries/{platform}/{name}.{suffix}"


def extracted_binary(tmp_path: Path, name: str, version: int, platform: str) -> Path:
    with zipfile.ZipFile(fmu_path(name, version)) as archive:
        target = tmp_path / f"{platform}-{version}-{Path(member(name, version, platform)).name}"
        target.write_bytes(archive.read(member(name, version, platform)))
    return target


def exported_functions(binary: Path) -> set[str]:
    if binary.suffix == ".dll":
        text = subprocess.run(["x86_64-w64-mingw32-objdump", "-p", str(binary)], capture_output=True, text=True,
                              check=True).stdout
        table = text.split("[Ordinal/Name Pointer] Table")[1].split("\n\n")[0]
        return set(re.findall(r"\]\s+(\S+)\s*$", table, re.MULTILINE))
    tool = "aarch64-linux-gnu-objdump" if "aarch64" in binary.name else "objdump"
    text = subprocess.run([tool, "-T", str(binary)], capture_output=True, text=True, check=True).stdout
    return {line.split()[-1] for line in text.splitlines() if " DF " in line and "*UND*" not in line}


def needed_libraries(binary: Path) -> set[str]:
    tool = {"dll": "x86_64-w64-mingw32-objdump", "so": "aarch64-linux-gnu-objdump"}[binary.suffix[1:]]
    text = subprocess.run([tool, "-p", str(binary)], capture_output=True, text=True, check=True).stdout
    return {m.lower() for m in re.findall(r"(?:DLL Name:|NEEDED)\s+(\S+)", text)}


@pytest.mark.parametrize("platform", sorted(PLATFORMS))
def test_every_fmu_carries_the_platform_binary_exporting_the_fmi_functions_only(fmu_paths, tmp_path, platform):
    version, compiler, suffix = PLATFORMS[platform]
    needs(compiler, {"x86_64-w64-mingw32-gcc": "gcc-mingw-w64-x86-64", "i686-w64-mingw32-gcc": "gcc-mingw-w64-i686",
                     "aarch64-linux-gnu-gcc": "gcc-aarch64-linux-gnu"}[compiler])
    for name in FMU_NAMES:
        binary = extracted_binary(tmp_path, name, version, platform)
        native = extracted_binary(tmp_path, name, version, NATIVE[version])
        assert exported_functions(binary) == exported_functions(native), (name, platform)
        assert len(exported_functions(binary)) == (44 if version == 2 else 75)
        assert needed_libraries(binary) <= RUNTIME[suffix], (name, platform, needed_libraries(binary))


def test_fmi2_has_no_aarch64_folder(fmu_paths):
    """FMI 2.0 names no aarch64 Linux platform: its FMUs carry none rather than an invented folder."""
    for name in FMU_NAMES:
        with zipfile.ZipFile(fmu_path(name, 2)) as archive:
            folders = {n.split("/")[1] for n in archive.namelist() if n.startswith("binaries/") and n.count("/") == 2}
        assert folders <= {"linux64", "win64", "win32"}, folders


class Importer:
    """The driver built for one platform, and how to run it there."""

    def __init__(self, tmp_path: Path, kind: str):
        self.kind = kind
        self.environment = dict(os.environ)
        if kind == "native":
            self.program = tmp_path / "driver"
            subprocess.run(["cc", "-std=c99", "-O2", "-o", str(self.program), str(DRIVER), "-ldl"], check=True)
            self.prefix = []
        elif kind == "wine32":  # in the i386 Debian: its /proc mounted in a mount namespace of the run's own
            self.work = Path(tempfile.mkdtemp(prefix="fmu-driver-", dir=I386_ROOT / "tmp"))
            self.program = self.work / "driver.exe"
            subprocess.run(["i686-w64-mingw32-gcc", "-std=c99", "-O2", "-o", str(self.program), str(DRIVER)],
                           check=True)
            inside = f"/tmp/{self.work.name}"
            self.prefix = ["unshare", "--mount", "--fork", "sh", "-c",
                           'mount -t proc proc "$0/proc" && exec chroot "$0" env "$@"', str(I386_ROOT),
                           f"HOME={inside}", f"WINEPREFIX={inside}/wine", "WINEDEBUG=-all", "wine"]
        elif kind == "wine":
            self.program = tmp_path / "driver.exe"
            subprocess.run(["x86_64-w64-mingw32-gcc", "-std=c99", "-O2", "-o", str(self.program), str(DRIVER)],
                           check=True)
            self.environment.update(WINEPREFIX=str(tmp_path / "wine"), WINEDEBUG="-all")
            self.prefix = ["wine"]
        else:
            self.program = tmp_path / "driver-aarch64"
            subprocess.run(["aarch64-linux-gnu-gcc", "-std=c99", "-O2", "-o", str(self.program), str(DRIVER), "-ldl"],
                           check=True)
            self.prefix = ["qemu-aarch64", "-L", "/usr/aarch64-linux-gnu"]

    def run(self, jobs: list[tuple[Path, int, str, list[int], list[str]]]) -> list[list[str]]:
        """Each job (binary, version, token, outputs, settings) over 10 s at 0.05 s, all in one process
        of the driver (under Wine or qemu the process start costs more than a run): per job its lines."""
        lines = []
        for binary, version, token, outputs, settings in jobs:
            if self.kind == "wine32":  # inside the i386 Debian, named as it sees it
                shutil.copy(binary, self.work / binary.name)
                binary = Path(f"/tmp/{self.work.name}/{binary.name}")
            library = f"Z:{binary}".replace("/", "\\") if self.kind.startswith("wine") else str(binary)
            lines.append(" ".join([library, str(version), token, "10", "0.05", ",".join(map(str, outputs)),
                                   *settings]))
        program = f"/tmp/{self.work.name}/driver.exe" if self.kind == "wine32" else str(self.program)
        result = subprocess.run([*self.prefix, program, "--jobs"], input="\n".join(lines) + "\n",
                                capture_output=True, text=True, env=self.environment, timeout=900)
        assert result.returncode == 0, result.stderr[-2000:]
        runs, current = [], []
        for line in result.stdout.splitlines():
            current.append(line)
            if line.startswith("status "):
                assert line == "status 0", result.stderr[-2000:]
                runs.append(current)
                current = []
        assert len(runs) == len(jobs), result.stdout[-2000:]
        return runs

    def close(self) -> None:
        if self.kind == "wine":  # the Wine server outlives its programs: stop it with the prefix
            subprocess.run(["wineserver", "-k"], env=self.environment, capture_output=True)
        if self.kind == "wine32":
            subprocess.run([*self.prefix[:-1], "wineserver", "-k"], capture_output=True)
            shutil.rmtree(self.work, ignore_errors=True)


@pytest.fixture(scope="module")
def importers(fmu_paths, tmp_path_factory):
    made = {}
    folder = tmp_path_factory.mktemp("drivers")
    made["native"] = Importer(folder, "native")
    if shutil.which("wine") and shutil.which("x86_64-w64-mingw32-gcc"):
        made["wine"] = Importer(folder, "wine")
    if shutil.which("qemu-aarch64") and shutil.which("aarch64-linux-gnu-gcc"):
        made["qemu"] = Importer(folder, "qemu")
    if i386_problem() is None:
        made["wine32"] = Importer(folder, "wine32")
    yield made
    for importer in made.values():
        importer.close()


def run_everywhere(importers, tmp_path, names: list[str], version: int, platform: str, kind: str,
                   settings: list[list[str]]) -> list[tuple[list[str], list[str]]]:
    """Each (FMU, settings) pair on the x86_64 Linux binary and on the platform's: their lines."""
    if kind == "wine32" and i386_problem():
        pytest.skip(i386_problem())
    if kind not in importers:
        needs({"wine": "wine", "qemu": "qemu-aarch64"}[kind], {"wine": "wine64", "qemu": "qemu-user"}[kind])
    native_jobs = [driver_job(tmp_path, name, version, NATIVE[version], s) for name, s in zip(names, settings)]
    other_jobs = [driver_job(tmp_path, name, version, platform, s) for name, s in zip(names, settings)]
    return list(zip(importers["native"].run(native_jobs), importers[kind].run(other_jobs)))


def driver_job(tmp_path, name: str, version: int, platform: str, settings: list[str]):
    """The driver's job for the FMU's binary for platform: every Real output over 10 s with these settings."""
    md = read_model_description(str(fmu_path(name, version)))
    token = md.guid if version == 2 else md.instantiationToken
    outputs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type in ("Real", "Float64")]
    return extracted_binary(tmp_path, name, version, platform), version, token, outputs, settings


def deviations(native: list[str], other: list[str]) -> list[float]:
    """Per communication point, the largest |a - b| / max(1, |a|) over its outputs (lines of IEEE 754 bits)."""
    worst = []
    for a, b in zip(native[:-1], other[:-1]):
        point = 0.0
        for x, y in zip(a.split()[1:], b.split()[1:]):
            x, y = struct.unpack(">d", bytes.fromhex(x))[0], struct.unpack(">d", bytes.fromhex(y))[0]
            point = max(point, abs(x - y) / max(1.0, abs(x)))
        worst.append(point)
    return worst


def largest_deviation(native: list[str], other: list[str]) -> float:
    """The largest |a - b| / max(1, |a|) over every output at every point."""
    return max(deviations(native, other), default=0.0)


# Where a motion is chaotic (the Hertz cradle's balls), an ulp that Wine's C runtime rounds otherwise grows
# without bound: the comparison runs while the x86_64 binary's own motion keeps a change of one ulp of its
# start below PREDICTABLE, 10 times under the criterion.
PREDICTABLE = 1e-12
AGREEMENT = 1e-11


def one_ulp_later(name: str, version: int) -> list[str]:
    """The driver's setting that moves the object's first nonzero state start by one ulp (none for an element
    without states)."""
    md = read_model_description(str(fmu_path(name, version)))
    states = [unknown.variable.derivative for unknown in md.derivatives]
    moved = [f"real:{v.valueReference}={math.nextafter(float(v.start), math.inf)!r}" for v in states
             if v.start is not None and float(v.start) != 0.0]
    return moved[:1]


def predictable_points(importers, tmp_path, names: list[str], version: int,
                       from_start: list[list[str]]) -> dict[str, int]:
    """Per object, the communication points (from the start) through which the x86_64 binary's motion from a
    start one ulp away stays within PREDICTABLE of its motion from the start itself (from_start: those lines)."""
    moved = importers["native"].run([driver_job(tmp_path, name, version, NATIVE[version], one_ulp_later(name, version))
                                     for name in names])
    counts = {}
    for name, start, away in zip(names, from_start, moved):
        apart = [d > PREDICTABLE for d in deviations(start, away)]
        counts[name] = apart.index(True) if any(apart) else len(apart)
    return counts


@pytest.mark.compatibility(importer="tools/fmu_driver.c under {kind}", version="{version}", interface="CS",
                           platform="{platform}", criterion="the x86_64 Linux binary under the same driver: "
                                                            "{criterion}")
@pytest.mark.parametrize("platform, kind, version, criterion", [
    *[(platform, kind, version, f"within {AGREEMENT:g} while one ulp of the start stays within {PREDICTABLE:g}")
      for platform, kind, version in [("win64", "wine", "2.0"), ("x86_64-windows", "wine", "3.0"),
                                      ("win32", "wine32", "2.0"), ("x86-windows", "wine32", "3.0")]],
    ("aarch64-linux", "qemu", "3.0", "bit for bit")])
def test_each_binary_gives_the_x86_64_linux_numbers(importers, tmp_path, compatibility, platform, kind, version,
                                                    criterion):
    """10 s of every model at its defaults (201 communication points, every Real output). The aarch64
    binary runs the same arithmetic with the same C library (glibc's libm) and agrees bit for bit.
    Under Wine, sin and cos come from Wine's C runtime, which differs from glibc's by an ulp at some
    arguments: the first such ulp grows with the motion, to 1e-12 at most over 10 s where the motion is
    regular (the Kapitza pendulum's fast drive, cos(Omega t) at large arguments). Where it is chaotic (the
    Hertz cradle: one ulp of the start grows to 1e-11 in 2.6 s, 4e-3 in 10 s) the comparison runs for as long
    as the x86_64 binary's motion from a start one ulp away stays within 1e-12 of its own, and that must be a
    second at least."""
    version = PLATFORMS[platform][0]
    runs = run_everywhere(importers, tmp_path, FMU_NAMES, version, platform, kind, [[] for _ in FMU_NAMES])
    horizon = predictable_points(importers, tmp_path, FMU_NAMES, version, [native for native, _ in runs]) \
        if kind != "qemu" else {}
    for name, (native, other) in zip(FMU_NAMES, runs):
        assert len(native) == 202 and len(other) == 202
        if kind == "qemu":
            differing = [a for a, b in zip(native, other) if a != b]
            assert not differing, f"{name}: first difference at line {native.index(differing[0])}"
            compatibility.agrees(name, largest_deviation(native, other))
        else:
            points = horizon[name]
            assert points >= 21, f"{name}: one ulp of the start grows past {PREDICTABLE:g} within {points} points"
            compared = native[:points] + native[-1:], other[:points] + other[-1:]  # the status line last
            assert largest_deviation(*compared) < AGREEMENT, (name, points)
            compatibility.agrees(name, largest_deviation(*compared))


@pytest.mark.parametrize("platform, kind", [("win64", "wine"), ("aarch64-linux", "qemu")])
def test_every_method_agrees_across_platforms(importers, tmp_path, platform, kind):
    """Bit for bit on the chaotic double pendulum under qemu; under Wine on the simple pendulum, whose
    regular motion does not amplify the C runtime's ulps beyond recognition as the double pendulum's
    does (there euler exceeds 1e-11 within 10 s)."""
    version = PLATFORMS[platform][0]
    name = "DoublePendulum" if kind == "qemu" else "SimplePendulum"
    # stormer_verlet is the simple pendulum's only: the double pendulum refuses it
    names = ["SimplePendulum" if METHOD[method].needs_constant_mass else name for method in SOLVERS]
    settings = []
    for solver, run_name in enumerate(names, start=1):
        refs = {v.name: v.valueReference
                for v in read_model_description(str(fmu_path(run_name, version))).modelVariables}
        settings.append([f"int:{refs['solver']}={solver}", f"real:{refs['h']}=0.01", f"real:{refs['tol']}=1e-8"])
    runs = run_everywhere(importers, tmp_path, names, version, platform, kind, settings)
    for method, (native, other) in zip(SOLVERS, runs):
        assert native == other if kind == "qemu" else largest_deviation(native, other) < 1e-11, method
