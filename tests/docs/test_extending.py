"""docs/explanation/extending.md stays true: each kind of extension touches the files it lists and no other place.
A change that would need a further place (a framework switch naming a method, a kind of constraint the guide does
not know, an FMI function declared and not defined) fails here, naming it."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

from harness.fmi.fmu_instance import ERROR, FmuInstance
from harness.fmi.fmus import build_dir
from harness.fmi.methods import ENGINES, METHODS
from harness.objects.object_file import ObjectFileError, read_object_file

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "explanation" / "extending.md"
FRAMEWORK = ROOT / "fmus" / "framework"
CODE = ("*.py", "*.c", "*.h", "*.mjs")


def section(title: str) -> str:
    text = GUIDE.read_text()
    start = text.index(f"## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else len(text)]


def listed_files(title: str) -> set[str]:
    """The files a section's bullets name: a path, or a name in the folder of the path before it."""
    files, folder = set(), ""
    for line in section(title).splitlines():
        if not line.startswith("* "):
            continue
        for name in re.findall(r"`([^`]+)`", line.split(":")[0]):
            if "/" in name:
                folder = name.rsplit("/", 1)[0]
                files.add(name)
            elif re.search(r"\.(py|c|h|mjs)$", name):
                files.add(f"{folder}/{name}")
    return files


def code_files_matching(pattern: str) -> set[str]:
    """The tracked code files (tests aside) in which the regular expression occurs."""
    result = subprocess.run(["git", "grep", "-l", "-E", pattern, "--", *CODE], cwd=ROOT, capture_output=True,
                            text=True)
    return {name for name in result.stdout.split() if not name.startswith("tests/")}


def test_every_file_the_guide_names_exists():
    named = re.findall(r"`((?:harness|fmus|web|docs|tools)/[^`]+)`", GUIDE.read_text())
    assert named and [name for name in named if not (ROOT / name).exists()] == []


# ---- an integration method

TABLE_METHODS = [m for m in METHODS if ENGINES[m.engine].table is not None]


def test_a_method_with_coefficients_needs_the_table_and_its_coefficients_only():
    assert listed_files("An integration method") == {"harness/fmi/methods.py", "fmus/framework/integrators.c"}
    framework = {path.name: path.read_text() for path in FRAMEWORK.glob("*.[ch]")}
    for method in TABLE_METHODS:
        naming = [name for name, text in framework.items() if re.search(rf"\bSOLVER_{method.name.upper()}\b", text)]
        assert naming == [], f"{method.name} is named in {naming}: the switches take it from the methods table"
        definitions = re.findall(rf"^INTERNAL_DATA const \w+ {method.c_table} =", framework["integrators.c"],
                                 re.MULTILINE)
        assert len(definitions) == 1, method.name


STEP, H = 0.05, 1.0


def steps_taken(fmu_paths, method: str, tol: float) -> tuple[int, int]:
    """SimplePendulum over H with substeps of STEP: the call's status and the steps it took."""
    with FmuInstance(fmu_paths["SimplePendulum"]) as instance:
        instance.initialize(0.0, solver=method, h=STEP, tol=tol)
        status = instance.do_step(0.0, H)
        return status, int(instance.get("n_steps")[0])


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m.name)
def test_the_generated_adaptive_test_follows_the_engines_step_control(fmu_paths, method):
    """With tol > 0 a method of an engine that picks its steps takes other steps than H / h; every other method
    takes exactly H / h. At tol = 0 a method whose steps come from tol alone is refused."""
    control = ENGINES[method.engine].step_control
    status, steps = steps_taken(fmu_paths, method.name, 1e-10)
    assert status == 0
    if control == "h":
        assert steps == round(H / STEP)
    else:
        assert steps != round(H / STEP)
    status, steps = steps_taken(fmu_paths, method.name, 0.0)
    assert status == (ERROR if control == "tol" else 0)
    if control == "tol or h":
        assert steps == round(H / STEP)


# ---- an FMI function

def declared(version: int) -> set[str]:
    text = (FRAMEWORK / f"fmi{version}_api.h").read_text()
    # fmi3GetFloat64 FMI3_VALUES(fmi3Float64): a name before its argument list or the macro that writes it
    return set(re.findall(rf"^FMI{version}_Export\s[\w\s*]*?\b(fmi{version}\w+)\s*(?:\(|FMI{version}_\w+\()", text,
                          re.MULTILINE))


def defined(version: int) -> set[str]:
    text = (FRAMEWORK / f"fmi{version}_functions.c").read_text()
    functions = re.findall(rf"^\w[\w\s\*]*?\b(fmi{version}\w+)\([^;]*?\)\s*\{{", text, re.MULTILINE)
    by_macro = re.findall(rf"^[A-Z_]+\((fmi{version}\w+)\b", text, re.MULTILINE)  # NO_CLOCKS(fmi3GetClock, ...)
    return set(functions) | set(by_macro)


@pytest.mark.parametrize("version", [2, 3])
def test_each_declared_fmi_function_is_defined_and_exported(fmu_paths, version):
    assert declared(version) and declared(version) <= defined(version)
    assert declared(version) == exported(version)


def exported(version: int) -> set[str]:
    """The functions the x86_64 Linux binary of SimplePendulum exports."""
    import zipfile
    folder = {2: "linux64", 3: "x86_64-linux"}[version]
    path = build_dir() / "fmus" / ("SimplePendulum.fmu" if version == 2 else "fmi3/SimplePendulum.fmu")
    with zipfile.ZipFile(path) as archive:
        binary = archive.read(f"binaries/{folder}/SimplePendulum.so")
    scratch = build_dir() / f"exports-{version}.so"
    scratch.write_bytes(binary)
    try:
        text = subprocess.run(["objdump", "-T", str(scratch)], capture_output=True, text=True, check=True).stdout
    finally:
        scratch.unlink()
    return {line.split()[-1] for line in text.splitlines() if " DF " in line and "*UND*" not in line}


# ---- a kind of constraint

KIND_MARKER = r'(\.|->)bilateral\b|\bbilateral\s*[=:;]|"bilateral"'


def test_the_kinds_of_constraint_are_those_the_guide_lists(tmp_path):
    text = (ROOT / "modelDescription" / "BouncingBall.toml").read_text()
    broken = tmp_path / "BouncingBall.toml"
    broken.write_text(text.replace('floor = { gap = "y - R",', 'floor = { kind = "no-such", gap = "y - R",'))
    with pytest.raises(ObjectFileError) as refused:
        read_object_file(broken)
    accepted = set(re.findall(r'"(\w+)"', str(refused.value).split("must be")[1]))
    guide = re.split(r"and\s+the\s+compliant", section("A kind of constraint").split("The kinds today:")[1])[0]
    assert accepted == set(re.findall(r"`(\w+)`", guide))


def test_the_files_that_tell_the_kinds_apart_are_those_the_guide_lists():
    listed = {name for name in listed_files("A kind of constraint") if not name.endswith(".md")}
    assert code_files_matching(KIND_MARKER) == listed
