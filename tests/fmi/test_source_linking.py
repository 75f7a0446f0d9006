"""Source FMUs an importer compiles into one program: each FMU's sources/ with its own
FMI2_FUNCTION_PREFIX (FMI 3.0: FMI3_FUNCTION_PREFIX), two FMUs linked statically into one executable,
both run in it, and each gives the numbers of its own shipped binary (run through fmpy)."""
from __future__ import annotations

import subprocess
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description

from harness.fmi.fmus import build_dir
from harness.fmi.simulation import simulate

STEP, STEPS = 0.01, 100
PAIRS = {2: ("SimplePendulum", "DoublePendulum"), 3: ("SpringPendulum", "Chain3")}

# A minimal importer: Co-Simulation, default start values, STEPS steps of STEP, then one output printed
# per FMU. Written against the standard's signatures; FMU(name) is the prefixed name.
DRIVER = {2: r"""
#include <stdio.h>
#include <stdlib.h>
typedef void *C;
typedef struct { void (*logger)(void *, const char *, int, const char *, const char *, ...);
                 void *(*allocate)(size_t, size_t); void (*release)(void *); void *finished; void *env; } Callbacks;
static void logger(void *env, const char *name, int status, const char *category, const char *message, ...)
{ fprintf(stderr, "%s: %s\n", name, message); }
#define DECLARE(P) \
    C P##fmi2Instantiate(const char *, int, const char *, const char *, const Callbacks *, int, int); \
    int P##fmi2SetupExperiment(C, int, double, double, int, double); \
    int P##fmi2EnterInitializationMode(C); int P##fmi2ExitInitializationMode(C); \
    int P##fmi2DoStep(C, double, double, int); int P##fmi2GetReal(C, const unsigned *, size_t, double *); \
    void P##fmi2FreeInstance(C);
DECLARE(A_) DECLARE(B_)
#define RUN(P, guid, vr, out) do { \
    static const Callbacks callbacks = {logger, calloc, free, NULL, NULL}; \
    unsigned r = (vr); int k; \
    C c = P##fmi2Instantiate(#P, 1, guid, "", &callbacks, 0, 0); \
    if (!c || P##fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) || P##fmi2EnterInitializationMode(c) \
        || P##fmi2ExitInitializationMode(c)) return 1; \
    for (k = 0; k < STEPS; k++) if (P##fmi2DoStep(c, k * STEP, STEP, 1)) return 1; \
    if (P##fmi2GetReal(c, &r, 1, &out)) return 1; \
    P##fmi2FreeInstance(c); \
} while (0)
""", 3: r"""
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
typedef void *C;
static void logger(void *env, int status, const char *category, const char *message)
{ fprintf(stderr, "%s\n", message); }
#define DECLARE(P) \
    C P##fmi3InstantiateCoSimulation(const char *, const char *, const char *, bool, bool, bool, bool, \
                                     const uint32_t *, size_t, void *, void *, void *); \
    int P##fmi3EnterInitializationMode(C, bool, double, double, bool, double); \
    int P##fmi3ExitInitializationMode(C); \
    int P##fmi3DoStep(C, double, double, bool, bool *, bool *, bool *, double *); \
    int P##fmi3GetFloat64(C, const uint32_t *, size_t, double *, size_t); void P##fmi3FreeInstance(C);
DECLARE(A_) DECLARE(B_)
#define RUN(P, guid, vr, out) do { \
    uint32_t r = (vr); int k; bool event, terminate, early; double last; \
    C c = P##fmi3InstantiateCoSimulation(#P, guid, "", false, false, false, false, NULL, 0, NULL, \
                                         (void *)logger, NULL); \
    if (!c || P##fmi3EnterInitializationMode(c, false, 0.0, 0.0, false, 0.0) || P##fmi3ExitInitializationMode(c)) \
        return 1; \
    for (k = 0; k < STEPS; k++) \
        if (P##fmi3DoStep(c, k * STEP, STEP, true, &event, &terminate, &early, &last)) return 1; \
    if (P##fmi3GetFloat64(c, &r, 1, &out, 1)) return 1; \
    P##fmi3FreeInstance(c); \
} while (0)
"""}
MAIN = r"""
#define STEP {step}
#define STEPS {steps}
int main(void)
{{
    double a = 0.0, b = 0.0;
    RUN(A_, "{guid_a}", {vr_a}, a);
    RUN(B_, "{guid_b}", {vr_b}, b);
    printf("%.17g %.17g\n", a, b);
    return 0;
}}
"""
OUTPUT = {"SimplePendulum": "x", "DoublePendulum": "x2", "SpringPendulum": "x", "Chain3": "x3"}


def _fmu(version: int, name: str) -> Path:
    return build_dir() / "fmus" / ("fmi3" if version == 3 else "") / f"{name}.fmu"


def _guid(description) -> str:
    return description.guid if description.fmiVersion == "2.0" else description.instantiationToken


@pytest.mark.parametrize("version", [2, 3])
def test_two_source_fmus_link_into_one_program(tmp_path, version):
    objects, details = [], []
    for prefix, name in zip(("A_", "B_"), PAIRS[version]):
        folder = tmp_path / name
        with zipfile.ZipFile(_fmu(version, name)) as archive:
            archive.extractall(folder)
        description = read_model_description(str(_fmu(version, name)))
        units = _source_files(folder, version)
        assert units == [f"fmu_fmi{version}.c"]  # one translation unit, which includes the rest
        obj = tmp_path / f"{name}.o"
        # the importer's own flags: none of the project's (no -fvisibility=hidden), warnings as errors
        subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", "-Wextra", "-Wno-unused-parameter", "-Werror", "-c",
                        f"-DFMI{version}_FUNCTION_PREFIX={prefix}", f"-I{folder / 'sources'}", "-o", str(obj),
                        str(folder / "sources" / units[0])], check=True, capture_output=True, text=True)
        symbols = subprocess.run(["nm", "-g", "--defined-only", str(obj)], capture_output=True, text=True,
                                 check=True).stdout.split()[2::3]
        assert symbols and all(s.startswith(f"{prefix}fmi{version}") for s in symbols), symbols[:5]
        objects.append(str(obj))
        variable = next(v for v in description.modelVariables if v.name == OUTPUT[name])
        details.append((_guid(description), variable.valueReference))
    driver = tmp_path / "driver.c"
    driver.write_text(DRIVER[version] + MAIN.format(step=STEP, steps=STEPS, guid_a=details[0][0], vr_a=details[0][1],
                                                    guid_b=details[1][0], vr_b=details[1][1]))
    program = tmp_path / "two_fmus"
    subprocess.run(["gcc", "-std=c99", "-O2", "-o", str(program), str(driver), *objects, "-lm"], check=True,
                   capture_output=True, text=True)
    ran = subprocess.run([str(program)], capture_output=True, text=True, timeout=60)
    assert ran.returncode == 0, ran.stderr
    linked = [float(v) for v in ran.stdout.split()]
    for name, value in zip(PAIRS[version], linked):
        shipped = simulate(_fmu(version, name), STEP * STEPS, STEP)
        expected = shipped.values[-1, shipped.columns.index(OUTPUT[name])]
        assert value == pytest.approx(expected, rel=1e-12, abs=1e-12), name
    assert abs(linked[0] - linked[1]) > 1e-3  # two different objects, not one binary run twice


def _source_files(folder: Path, version: int) -> list[str]:
    """What the FMU tells an importer to compile: SourceFiles (FMI 2.0), buildDescription.xml (FMI 3.0)."""
    if version == 2:
        root = ET.parse(folder / "modelDescription.xml").getroot()
        return [f.get("name") for f in root.findall("CoSimulation/SourceFiles/File")]
    root = ET.parse(folder / "sources" / "buildDescription.xml").getroot()
    return [f.get("name") for f in root.iter("SourceFile")]
