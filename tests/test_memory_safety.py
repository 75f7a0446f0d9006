"""Memory safety of the FMUs: the behaviour, robustness, numerics, master, FMI 3.0, Jacobian, symmetric-method and
recorder tests again against an
AddressSanitizer + UndefinedBehaviorSanitizer build (CMake option FMU_SANITIZE), and the C drivers
under valgrind memcheck. Any report fails the test. The sanitized build and run go on in the
background from the moment the test is selected (`SanitizedSuite`)."""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from fmpy import read_model_description

from harness.fmi.fmus import PROJECT_ROOT, build_dir

SANITIZED_TESTS = ["tests/test_fmi_behaviour.py", "tests/test_robustness.py", "tests/test_convergence.py",
                   "tests/test_master.py", "tests/test_concurrency.py", "tests/test_physics.py",
                   "tests/test_fmi3.py", "tests/test_jacobian.py",  # the FMI 3.0 layer and the Jacobian
                   "tests/test_symmetric_methods.py", "tests/test_recorder.py"]  # Newton, Verlet, the native loop


def compiler_file(name: str) -> str:
    return subprocess.run(["gcc", f"-print-file-name={name}"], capture_output=True, text=True, check=True).stdout.strip()


class SanitizedSuite:
    """The sanitized build and the sanitized test run, in a thread of their own: started when the
    test is collected, so that it uses what the rest of the suite leaves of the machine's cores (the
    test only waits for its outcome). The child processes run in a process group of their own, which
    `stop()` ends if the session ends first."""

    def __init__(self) -> None:
        self.process: subprocess.Popen | None = None
        self.outcome: tuple[str, int, str, str] | None = None  # (stage, return code, stdout, stderr)
        self.stopped = False
        self.thread = threading.Thread(target=self._run, name="sanitized suite", daemon=True)

    def start(self) -> None:
        self.thread.start()

    def _step(self, stage: str, command: list[str], **options) -> bool:
        if self.stopped:
            return False
        self.process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                        start_new_session=True, **options)
        stdout, stderr = self.process.communicate()
        self.outcome = (stage, self.process.returncode, stdout, stderr)
        return self.process.returncode == 0

    def _run(self) -> None:
        directory = PROJECT_ROOT / "build-sanitize"
        asan, ubsan = compiler_file("libasan.so"), compiler_file("libubsan.so")
        if not Path(asan).is_file() or not Path(ubsan).is_file():
            self.outcome = ("skip", 0, "", "gcc's sanitizer runtimes are not installed")
            return
        if not (self._step("configure", ["cmake", "-S", str(PROJECT_ROOT), "-B", str(directory),
                                          "-DCMAKE_BUILD_TYPE=Debug", "-DFMU_SANITIZE=ON", "-DFMU_CROSS=OFF"])
                and self._step("build", ["cmake", "--build", str(directory), "-j2"])):
            return
        environment = dict(os.environ, PENDULUM_BUILD_DIR=str(directory), PENDULUM_SKIP_BUILD="1",
                           LD_PRELOAD=f"{asan} {ubsan}", ASAN_OPTIONS="detect_leaks=0:abort_on_error=1",
                           UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1")
        self._step("tests", [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-x",
                             "-k", "not no_mutable_static_data", *SANITIZED_TESTS], cwd=PROJECT_ROOT, env=environment)

    def result(self, timeout: float = 1800) -> tuple[str, int, str, str]:
        self.thread.join(timeout)
        assert not self.thread.is_alive(), "the sanitized suite did not finish in time"
        return self.outcome

    def stop(self) -> None:
        self.stopped = True
        if self.process is not None and self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGKILL)
        self.thread.join(10)


SANITIZED = SanitizedSuite()  # started by conftest.py as soon as this test is selected


def test_suite_runs_clean_under_address_and_undefined_behaviour_sanitizers():
    if SANITIZED.outcome is None and not SANITIZED.thread.is_alive():
        SANITIZED.start()  # selected in a way conftest.py did not see: run it now
    stage, code, stdout, stderr = SANITIZED.result()
    if stage == "skip":
        pytest.skip(stderr)
    report = f"{stage}: " + stdout[-4000:] + stderr[-4000:]
    assert stage == "tests" and code == 0, report
    assert "AddressSanitizer" not in stderr and "runtime error" not in stderr, report


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
