"""Memory safety of the FMUs: the behaviour, robustness, numerics, master, FMI 3.0, Jacobian, symmetric-method and
recorder tests again against an
AddressSanitizer + UndefinedBehaviorSanitizer build (CMake option FMU_SANITIZE), and the C drivers
under valgrind memcheck. Any report fails the test."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from fmpy import read_model_description

from harness.fmi.fmus import FMU_NAMES, PROJECT_ROOT, build_dir

# the robustness tests: the calls out of place of the FMUs' bad-input suite (a NULL instance, a wrong order, a
# freed state)
ROBUSTNESS = [f"tests/framework/test_fmu_bad_input.py::{name}" for name in (
    "test_every_function_with_a_null_instance_returns_error", "test_no_mutable_static_data",
    "test_model_exchange_call_order", "test_debug_logging_categories", "test_free_state_clears_the_pointer")]
SANITIZED_TESTS = [
    "tests/fmi/test_fmi_behaviour.py", *ROBUSTNESS, "tests/framework/test_convergence.py", "tests/cosim/test_master.py",
    "tests/framework/test_concurrency.py", "tests/objects/test_physics.py",
    "tests/fmi/test_fmi3.py", "tests/framework/test_jacobian.py",  # the FMI 3.0 layer and the Jacobian
    "tests/framework/test_symmetric_methods.py", "tests/fmi/test_recorder.py",  # Newton, Verlet, the native loop
    "tests/framework/test_taylor.py", "tests/framework/test_extrapolation.py",  # Taylor arithmetic, extrapolation
    "tests/framework/test_free_motion_methods.py"]  # events with taylor and stormer_verlet


def compiler_file(name: str) -> str:
    return subprocess.run(["gcc", f"-print-file-name={name}"], capture_output=True, text=True,
                          check=True).stdout.strip()


def switch_values(model: str, generated: Path) -> set[tuple[str, str]]:
    """The framework's compile-time switches (the names its #if lines test) as the model's headers set them: a
    count (N_*) zero or positive, another value as it is, or unset. Two FMUs alike in all compile the same paths."""
    framework = PROJECT_ROOT / "fmus" / "framework"
    tested = {name for path in framework.glob("*.[ch]") for line in path.read_text().splitlines()
              if line.lstrip().startswith("#if") for name in re.findall(r"\b[A-Z][A-Za-z0-9_]*\b", line)}
    headers = "\n".join(p.read_text() for folder in (generated / model, PROJECT_ROOT / "fmus" / "models" / model)
                        for p in folder.glob("*.h"))
    defined = dict(re.findall(r"^#define ([A-Z][A-Za-z0-9_]*) +(\S+)", headers, re.MULTILINE))

    def value(name: str) -> str:
        if name not in defined:
            return "unset"
        if name.startswith("N_") and defined[name].isdigit():
            return "0" if defined[name] == "0" else "positive"
        return defined[name]
    return {(name, value(name)) for name in tested}


def covering_models(names: list[str], generated: Path, first: list[str]) -> list[str]:
    """`first`, then fewest FMUs (greedily) that together have every value of every switch some FMU has."""
    values = {name: switch_values(name, generated) for name in names}
    chosen = list(first)
    missing = set().union(*values.values()) - set().union(*(values[name] for name in chosen))
    while missing:
        best = max(names, key=lambda name: len(values[name] & missing))
        chosen.append(best)
        missing -= values[best]
    return chosen


# built sanitized in any case: the harness's programs (integrator_tables) and the exported scene link it
LINKED = ["SimplePendulum"]


@pytest.fixture(scope="module")
def sanitized_build(fmu_paths) -> Path:
    """The sanitized build of the FMUs that together compile every path of the framework (each value of each of its
    compile-time switches), with the harness's loops and the SSP scene; the other FMUs are the main build's, so that
    every test runs (under the sanitizers' runtime, but only the chosen FMUs' code instrumented)."""
    directory = PROJECT_ROOT / "build-sanitize"
    # the objects' equations derived by sympy do not depend on the build type: the main build's are taken
    # (with their times, so that make derives again only what is older than its sources)
    shutil.copytree(build_dir() / "generated", directory / "generated", dirs_exist_ok=True)
    chosen = covering_models(list(FMU_NAMES), build_dir() / "generated", LINKED)
    for name in chosen:  # packed again from the sanitized binaries, whatever an earlier run left there
        for folder in ("fmus", "fmus/fmi3"):
            (directory / folder / f"{name}.fmu").unlink(missing_ok=True)
    targets = [t for name in chosen for t in (f"{name}_fmu", f"{name}_fmi3_fmu")] + \
        ["cosim_core", "record_loop", "integrator_tables", "coupled_pendulums_ssp"]
    for command in (["cmake", "-S", str(PROJECT_ROOT), "-B", str(directory), "-DCMAKE_BUILD_TYPE=Debug",
                     "-DFMU_SANITIZE=ON", "-DFMU_CROSS=OFF", "-DFMU_WASM=OFF"],
                    ["cmake", "--build", str(directory), "-j2", "--target", *targets]):
        result = subprocess.run(command, capture_output=True, text=True)
        assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    for name in set(FMU_NAMES) - set(chosen):
        for folder in ("fmus", "fmus/fmi3"):
            (directory / folder).mkdir(parents=True, exist_ok=True)
            shutil.copy2(build_dir() / folder / f"{name}.fmu", directory / folder / f"{name}.fmu")
    return directory


def test_the_sanitized_fmus_cover_every_compile_time_path():
    """The cover takes each value of each switch that some FMU has; among them constraints with and without
    compliance, no states at all (Spring, Contact), the linear closed form and Taylor's absence."""
    generated = build_dir() / "generated"
    chosen = covering_models(list(FMU_NAMES), generated, LINKED)
    every = set().union(*(switch_values(name, generated) for name in FMU_NAMES))
    assert set().union(*(switch_values(name, generated) for name in chosen)) == every
    assert {("N_COMPLIANT", "positive"), ("N_COMPLIANT", "0"), ("N_STATES", "0"), ("HAS_LINEAR_MODEL", "1"),
            ("TAYLOR_AVAILABLE", "0"), ("N_CONSTRAINTS", "positive"), ("SPLIT_ACCELERATIONS", "1"),
            ("INT_n_events", "unset")} <= every
    assert len(chosen) < len(FMU_NAMES)


def test_suite_runs_clean_under_address_and_undefined_behaviour_sanitizers(sanitized_build):
    asan, ubsan = compiler_file("libasan.so"), compiler_file("libubsan.so")
    if not Path(asan).is_file() or not Path(ubsan).is_file():
        pytest.skip("gcc's sanitizer runtimes are not installed")
    environment = dict(os.environ, PENDULUM_BUILD_DIR=str(sanitized_build), PENDULUM_SKIP_BUILD="1",
                       LD_PRELOAD=f"{asan} {ubsan}", ASAN_OPTIONS="detect_leaks=0:abort_on_error=1",
                       UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1")
    # not the tests whose time goes to sympy or to a compiler rather than to the FMUs' code (the polynomial
    # motion tests derive and compile a ball of their own, without the sanitizers; the peers' hand-coded
    # equations call no FMU)
    deselected = "not no_mutable_static_data and not builds_the_binary_from_the_sources and " \
                 "not (match_lagrange and DoublePendulum) and not polynomial_motion_is_exact and " \
                 "not hand_coded_equations"
    result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-x", "-k", deselected,
                             *SANITIZED_TESTS],
                            cwd=PROJECT_ROOT, env=environment, capture_output=True, text=True, timeout=1200)
    report = result.stdout[-4000:] + result.stderr[-4000:]
    assert result.returncode == 0, report
    assert "AddressSanitizer" not in result.stderr and "runtime error" not in result.stderr, report


def memcheck(command: list[str]) -> None:
    result = subprocess.run(["valgrind", "--error-exitcode=99", "--leak-check=full", "--errors-for-leak-kinds=definite",
                             "-q", *command], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-4000:]


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
@pytest.mark.parametrize("model", ["SimplePendulum", "DoublePendulum", "SpringPendulum"])
def test_fmu_runs_clean_under_valgrind_memcheck(fmu_paths, model):
    """Instantiate, initialize, 2000 RK4 steps in fmi2DoStep, get outputs, free: no invalid access, no leak."""
    memcheck([str(build_dir() / "bin" / f"bench_{model}"), str(build_dir() / "lib" / model / f"{model}.so"),
              "fmu", "2000"])


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
def test_coupled_loop_runs_clean_under_valgrind_memcheck(fmu_paths):
    """Three instances of two FMUs exchanging values over 500 macro steps."""
    pendulum = read_model_description(str(fmu_paths["SimplePendulum"]))
    spring = read_model_description(str(fmu_paths["Spring"]))
    p = {v.name: v.valueReference for v in pendulum.modelVariables}
    s = {v.name: v.valueReference for v in spring.modelVariables}
    vrs = [p[n] for n in ("x", "y", "v_x", "v_y", "F_x", "F_y", "phi", "anchor_x", "h")] + \
          [s[n] for n in ("a_x", "a_y", "a_vx", "a_vy", "b_x", "b_y", "b_vx", "b_vy", "Fa_x", "Fa_y", "Fb_x", "Fb_y",
                          "k", "l0")]
    memcheck([str(build_dir() / "bin" / "coupled_native"),
              str(build_dir() / "lib" / "SimplePendulum" / "SimplePendulum.so"), pendulum.guid,
              str(build_dir() / "lib" / "Spring" / "Spring.so"), spring.guid, "500", "0.01"] + [str(v) for v in vrs])
