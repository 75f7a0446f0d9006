from __future__ import annotations

import fcntl
import os
import pickle
import shutil
import sys
import tempfile
from pathlib import Path

import pytest
from fmpy import extract
from hypothesis import HealthCheck, settings

from harness.fmi.fmu_instance import FmuInstance
from harness.fmi.fmus import FMU_NAMES, PROJECT_ROOT, build_dir, build_fmus
from compatibility_record import CompatibilityPlugin, Row

# The tests, one folder per layer of the project (its objects, the FMUs' C framework, their FMI interface,
# co-simulation, the studies, the views, and the documentation with the command line). pytest puts this folder on
# sys.path (the shared helpers: method_checks, pair_reference, compatibility_record, conftest) and each test
# file's own folder as it imports the file; the layers' folders go there now, so that a test module imports
# what another one defines by its name whichever folder either sits in and whichever file runs alone
# (framework/test_free_motion_methods.py takes the cradle's period from objects/test_contact_objects.py).
TESTS = Path(__file__).resolve().parent
LAYER_FOLDERS = ("objects", "framework", "fmi", "cosim", "studies", "view", "docs")
sys.path[1:1] = [str(TESTS / layer) for layer in LAYER_FOLDERS if str(TESTS / layer) not in sys.path]

PENDULUMS = ("SimplePendulum", "DoublePendulum", "SpringPendulum")
# The coupling elements (hand-written, no states) alone, with ends that move: at their default inputs nothing
# changes. The Contact's centres pass each other: its overlap begins at 0.014 s and ends at 0.127 s.
ELEMENT_MOTION = {"Spring": {"a_vx": 0.5, "a_vy": -0.2, "b_x": 1.2, "b_y": 0.3},
                  "Contact": {"a_vx": 0.5, "a_vy": -0.2, "b_x": 0.045, "b_y": 0.01, "c": 0.5}}
ELEMENTS = tuple(ELEMENT_MOTION)

# The files that take a worker a minute or more (their shared set-up: the demo, the sanitizer build, the atlas),
# longest first. Run first (./run test keeps the collection order: --no-loadscope-reorder), they leave the many
# short files to even out the workers' ends; last, one of them would keep a worker busy while the others idle
# (the live view's and the WebAssembly files, last by name, did).
LONGEST_FILES = ("test_docs_measurements.py", "test_memory_safety.py", "test_docs.py", "test_demo.py",
                 "test_work_precision_objects.py", "test_fmu_package.py", "test_cli_bad_input.py", "test_view.py",
                 "test_work_precision.py", "test_registry.py", "test_charts.py", "test_checkers.py",
                 "test_platforms.py", "test_stability.py", "test_wasm.py", "test_chaos_plan.py", "test_peers.py",
                 "test_objects.py", "test_physics.py", "test_fmu_bad_input.py", "test_conformance.py",
                 "test_planner.py", "test_cli.py")


# the quick subset for daily work leaves these out: `-m "not slow"` (docs/explanation/testing.md)
SLOW_FILES = LONGEST_FILES[:10]


def pytest_configure(config) -> None:
    config.addinivalue_line("markers", "slow: a test of one of the longest files (SLOW_FILES), which the quick subset "
                                       "leaves out")
    config.addinivalue_line("markers", "compatibility(importer, version, interface, platform, criterion): the test "
                                       "measures a row of docs/compatibility.md (tests/compatibility_record.py)")
    config.pluginmanager.register(CompatibilityPlugin(PROJECT_ROOT / "docs" / "compatibility.md",
                                                      build_dir() / "compatibility.md"), "compatibility-record")


def pytest_collection_modifyitems(session, config, items) -> None:
    rank = {name: k for k, name in enumerate(LONGEST_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: the others keep their order
    for item in items:
        if item.path.name in SLOW_FILES:
            item.add_marker(pytest.mark.slow)


def shared_folder(tmp_path_factory, name: str) -> Path:
    """A folder of this test run that its workers share (beside their own temporary folders)."""
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    base = tmp_path_factory.getbasetemp()
    folder = base.parent / f"{name}-{run}" if run else base / name
    folder.mkdir(exist_ok=True)
    return folder


@pytest.fixture(scope="session", autouse=True)
def temporary_files(tmp_path_factory):
    """What the test process puts in the temporary folder goes with it: fmpy's simulate_fmu leaves its FMU's
    extraction behind when the run raises, which many tests provoke on purpose. (Short: sockets are made there.
    pytest's own folder is fixed first, so that it stays where it is, and a failed test's files with it.)"""
    tmp_path_factory.getbasetemp()
    folder = tempfile.mkdtemp(prefix="pendulum-tests-")
    before, tempfile.tempdir = tempfile.tempdir, folder
    yield folder
    tempfile.tempdir = before
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope="session", autouse=True)
def wasm_cache(tmp_path_factory):
    """The live view's modules, kept in the build's cache (where the build's own step put every FMU's module) or,
    without one, for this test run (its workers and the commands they start share them), rather than in the user's
    cache: a module is compiled once per build, not once per scene and page."""
    built = build_dir() / "wasm" / "cache"
    folder = built if built.is_dir() else shared_folder(tmp_path_factory, "wasm-cache")
    before = os.environ.get("PENDULUM_WASM_CACHE")
    os.environ["PENDULUM_WASM_CACHE"] = str(folder)
    yield folder
    if before is None:
        del os.environ["PENDULUM_WASM_CACHE"]
    else:
        os.environ["PENDULUM_WASM_CACHE"] = before


def once_per_run(tmp_path_factory, name: str, make) -> bytes:
    """What `make(folder)` returns, made once per test run for all its workers (a lock: one makes it, the others
    wait for it and read it); `folder` is for the files it makes."""
    folder = shared_folder(tmp_path_factory, "made-once")
    with open(folder / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        done = folder / f"{name}.done"
        if not done.exists():
            work = folder / name
            work.mkdir(exist_ok=True)
            done.write_bytes(make(work))
        return done.read_bytes()


@pytest.fixture(scope="session")
def free_fall_ball(tmp_path_factory) -> Path:
    """The free-fall ball's FMU (tests/method_checks.py), derived once per test run: the taylor and the
    extrapolation tests run it, and deriving and compiling it takes a quarter of a minute."""
    from method_checks import ball_fmu
    made = once_per_run(tmp_path_factory, "free-fall-ball", lambda folder: str(ball_fmu(folder)).encode())
    return Path(made.decode())


@pytest.fixture(scope="session")
def derivation(tmp_path_factory):
    """derivation(name) -> derive() of the registry's object file `name`, derived once per test run: the FMI 3.0
    descriptions and the peers' equations start from the same derivations (Chain5's takes a quarter of a minute)."""
    from harness.objects.derivation import derive
    from harness.objects.object_file import read_object_file
    from harness.objects.registry import object_file

    def derived(name: str):
        return pickle.loads(once_per_run(tmp_path_factory, f"derivation-{name}",
                                         lambda _: pickle.dumps(derive(read_object_file(object_file(name))))))
    return derived


@pytest.fixture
def compatibility(request) -> Row:
    """The compatibility row the test's marker declares: report each FMU it agrees on."""
    return request.node.compatibility_row


@pytest.fixture(scope="session")
def compatibility_record(request):
    """The whole record, for the reference results."""
    return request.config.pluginmanager.get_plugin("compatibility-record").record


@pytest.fixture(scope="session")
def fmu_paths() -> dict[str, Path]:
    build_fmus()
    return {name: build_dir() / "fmus" / f"{name}.fmu" for name in FMU_NAMES}


@pytest.fixture(scope="session")
def unzipped(fmu_paths, tmp_path_factory) -> dict[str, str]:
    """Each FMU extracted once per session."""
    return {name: extract(str(path), str(tmp_path_factory.mktemp(name))) for name, path in fmu_paths.items()}


@pytest.fixture
def open_fmu(fmu_paths, unzipped):
    """open_fmu(name, kind="CS") -> FmuInstance, freed after the test."""
    instances = []

    def factory(name: str, kind: str = "CS", **kwargs) -> FmuInstance:
        instance = FmuInstance(fmu_paths[name], kind=kind, unzipdir=unzipped[name], name=f"{name}{len(instances)}",
                               **kwargs)
        instances.append(instance)
        return instance

    yield factory
    for instance in instances:
        instance.free()


def rebuilt_with_fmpy(unzipped_folder: str, tmp_path: Path) -> Path:
    """A copy of an extracted FMU whose binaries fmpy's source build made again from sources/."""
    import shutil

    from fmpy.build import build_platform_binary
    copy = tmp_path / "fmu"
    shutil.copytree(unzipped_folder, copy)
    shutil.rmtree(copy / "binaries")
    (tmp_path / "build").mkdir()
    build_platform_binary(str(copy), str(tmp_path / "build"))
    return copy


def hostile(examples: int) -> settings:
    """hypothesis's settings for the hostile inputs (tests/docs/test_cli_bad_input.py, tests/framework/
    test_fmu_bad_input.py): reproducible runs (derandomized), no deadline: the FMUs' work bound, not a clock,
    bounds a call."""
    return settings(max_examples=examples, deadline=None, suppress_health_check=list(HealthCheck), derandomize=True,
                    database=None)
