"""The FMI return codes are named once per language: in C by fmus/framework/fmi_status.h (the FMUs' core and the
harness's C loops), in Python by harness/fmi/fmu_instance.py, in the page's script by web/fmu.mjs. They agree with
each other and with the FMI headers' own numbering, and no other file names them again."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from harness.fmi import fmu_instance

ROOT = Path(__file__).resolve().parents[2]
NAMES = tuple("OK Warning Discard Error".split())  # as the FMI headers name them


def c_enum(text: str, type_name: str) -> list[str]:
    """The members of `typedef enum { ... } type_name;`, in order."""
    match = re.search(r"typedef enum \{([^}]*)\} " + type_name + ";", text)
    assert match, type_name
    return [member.split("=")[0].strip() for member in match.group(1).split(",")]


def c_codes() -> dict[str, int]:
    text = (ROOT / "fmus/framework/fmi_status.h").read_text()
    members = dict(re.findall(r"STATUS_(\w+) = (\d+)", text))
    return {name: int(members[name.upper()]) for name in NAMES}


def test_c_codes_number_as_both_fmi_versions_do():
    for header, type_name, prefix in (("fmi2_api.h", "fmi2Status", "fmi2"), ("fmi3_api.h", "fmi3Status", "fmi3")):
        members = c_enum((ROOT / "fmus/framework" / header).read_text(), type_name)
        assert {name: members.index(prefix + name) for name in NAMES} == c_codes(), header


def test_python_codes_agree_with_c():
    assert {name: fmu_instance.STATUS_NAMES.index(name) for name in NAMES} == c_codes()
    assert (fmu_instance.OK, fmu_instance.WARNING, fmu_instance.DISCARD, fmu_instance.ERROR) == tuple(
        c_codes()[name] for name in NAMES)


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_page_codes_agree_with_c():
    script = ("import('./web/fmu.mjs').then(m => console.log(JSON.stringify({names: m.STATUS_NAMES, "
              "codes: [m.OK, m.WARNING, m.DISCARD, m.ERROR]})))")
    result = json.loads(subprocess.run(["node", "-e", script], cwd=ROOT, capture_output=True, text=True,
                                       check=True).stdout)
    assert {name: result["names"].index(name) for name in NAMES} == c_codes()
    assert result["codes"] == [c_codes()[name] for name in NAMES]


def tracked(*patterns: str) -> list[Path]:
    listed = subprocess.run(["git", "ls-files", *patterns], cwd=ROOT, capture_output=True, text=True,
                            check=True).stdout.split()
    return [ROOT / name for name in listed]


def test_no_other_file_names_the_codes_again():
    """A second definition (an enum of the codes, a list of their names) in any of the three languages."""
    definitions = {
        "C": (tracked("*.c", "*.h"), re.compile(r"\b\w*OK\s*=\s*0\b"), {"fmus/framework/fmi_status.h"}),
        "Python": (tracked("*.py"), re.compile(r'"Warning",\s*"Discard"'), {"harness/fmi/fmu_instance.py"}),
        "JavaScript": (tracked("*.mjs", "*.js"), re.compile(r'"Warning",\s*"Discard"|\bDISCARD\s*=\s*2'),
                       {"web/fmu.mjs"}),
    }
    for language, (files, pattern, owners) in definitions.items():
        found = {str(path.relative_to(ROOT)) for path in files if pattern.search(path.read_text(errors="replace"))}
        assert found == owners, (language, found)
