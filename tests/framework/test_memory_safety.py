"""Memory safety of the FMUs: the behaviour, robustness, numerics, master, FMI 3.0, Jacobian, symmetric-method and
recorder tests again against an
AddressSanitizer + UndefinedBehaviorSanitizer build (CMake option FMU_SANITIZE), and the C drivers
under valgrind memcheck. Any report fails the test."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from fmpy import read_model_description

from harness.fmi.fmus import PROJECT_ROOT, build_dir

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


@pytest.fixture(scope="module")
def sanitized_build(tmp_path_factory) -> Path:
    directory = PROJECT_ROOT / "build-sanitize"
    # the objects' equations derived by sympy do not depend on the build type: the main build's are taken
    # (with their times, so that make derives again only what is older than its sources)
    if (build_dir() / "generated").is_dir():
        shutil.copytree(build_dir() / "generated", directory / "generated", dirs_exist_ok=True)
    for command in (["cmake", "-S", str(PROJECT_ROOT), "-B", str(directory), "-DCMAKE_BUILD_TYPE=Debug",
                     "-DFMU_SANITIZE=ON", "-DFMU_CROSS=OFF",
                     "-DFMU_WASM=OFF"], ["cmake", "--build", str(directory), "-j2"]):
        result = subprocess.run(command, capture_output=True, text=True)
        assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    return directory


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
