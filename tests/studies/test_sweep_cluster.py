"""A sweep on a Dask cluster whose workers cannot see the project's files: the FMUs travel with the
sweep, each to each worker once, into the worker's own local directory, and the numbers are those
of the local process pool."""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import pytest

from harness.errors import HarnessError
from harness.fmi.fmus import PROJECT_ROOT, build_dir
from harness.studies.shipping import FOLDER, TOPIC
from harness.studies.sweep import run_sweep
from harness.studies.work_precision import settings, work_precision

distributed = pytest.importorskip("distributed")

STARTUP = 60  # seconds a scheduler or a worker may take to come up on a busy machine
# Loaded into each worker first: it may not open a file in (or load a library from) the folders named
# by SWEEP_TEST_HIDDEN, the project's build folder, so that what the sweep needs from there has to travel.
HIDE = '''
import os, sys
HIDDEN = os.environ["SWEEP_TEST_HIDDEN"].split(os.pathsep)
def hide(event, args):
    if event in ("open", "ctypes.dlopen", "os.listdir", "os.scandir") and args \\
            and isinstance(args[0], (str, bytes, os.PathLike)):
        path = os.path.abspath(os.fsdecode(args[0]))
        if any(path == hidden or path.startswith(hidden + os.sep) for hidden in HIDDEN):
            raise PermissionError(13, "this worker cannot see the project's build folder", path)
sys.addaudithook(hide)
'''


class Cluster:
    """A Dask scheduler and workers, each a process of its own in an empty folder, with an empty build
    folder (PENDULUM_BUILD_DIR) and no access to the project's."""

    def __init__(self, folder: Path):
        self.folder, self.processes, self.logs = folder, [], {}
        empty = folder / "empty-build"
        empty.mkdir()
        (folder / "tmp").mkdir()
        (folder / "hide.py").write_text(HIDE)
        hidden = {os.path.abspath(build_dir()), str(build_dir().resolve())}
        self.env = {**os.environ, "PENDULUM_BUILD_DIR": str(empty), "PENDULUM_SKIP_BUILD": "1",
                    "SWEEP_TEST_HIDDEN": os.pathsep.join(hidden), "TMPDIR": str(folder / "tmp"),
                    "PYTHONPATH": str(PROJECT_ROOT)}  # this checkout's harness, not one installed elsewhere
        self.address = ""

    def start(self) -> None:
        scheduler_file = self.folder / "scheduler.json"
        self._start("scheduler", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
                    "--no-dashboard", "--scheduler-file", str(scheduler_file), "--idle-timeout", "300")
        deadline = time.monotonic() + STARTUP
        while not scheduler_file.is_file() or not scheduler_file.read_text().strip():
            self._check_running("scheduler", deadline)
            time.sleep(0.1)
        self.address = json.loads(scheduler_file.read_text())["address"]

    def start_worker(self, name: str) -> Path:
        """A worker process, once it has joined; returns its local directory's parent."""
        space = self.folder / name
        space.mkdir()
        self._start(name, "distributed.cli.dask_worker", self.address, "--name", name, "--nthreads", "1",
                    "--no-nanny", "--no-dashboard", "--local-directory", str(space), "--death-timeout", "60",
                    "--preload", str(self.folder / "hide.py"))
        deadline = time.monotonic() + STARTUP
        while "Registered to:" not in self.logs[name].read_text():  # logged once its plugins are set up
            self._check_running(name, deadline)
            time.sleep(0.1)
        return space

    def _start(self, name: str, module: str, *args: str) -> None:
        cwd = self.folder / f"{name}-cwd"
        cwd.mkdir()
        self.logs[name] = self.folder / f"{name}.log"
        with open(self.logs[name], "w") as log:
            self.processes.append((name, subprocess.Popen([sys.executable, "-m", module, *args], cwd=cwd, env=self.env,
                                                          stdout=log, stderr=subprocess.STDOUT,
                                                          start_new_session=True)))

    def _check_running(self, name: str, deadline: float) -> None:
        process = dict(self.processes)[name]
        if process.poll() is not None or time.monotonic() > deadline:
            pytest.fail(f"the {name} did not start:\n{self.logs[name].read_text()[-3000:]}")

    def stop(self, name: str) -> None:
        """Ends a process, gently first (a worker then removes its local directory)."""
        process = dict(self.processes)[name]
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(timeout=10)

    def close(self) -> None:
        for name, _ in reversed(self.processes):
            self.stop(name)


@pytest.fixture
def cluster(fmu_paths):
    folder = Path(tempfile.mkdtemp(prefix="sweep-cluster-"))
    cluster = Cluster(folder)
    try:
        cluster.start()
        yield cluster
    finally:
        cluster.close()
        shutil.rmtree(folder, ignore_errors=True)


def _comparable(points) -> list[tuple]:
    return [(p.object, p.method, repr(p.h), repr(p.tol), p.error, p.rhs_evals, p.jacobian_columns,
             repr(p.event_error)) for p in points]


def _deliveries(client) -> Counter:
    """(worker name, bundle key) -> how often the scheduler gave that worker the bundle."""
    names = {address: info["name"] for address, info in client.scheduler_info()["workers"].items()}
    return Counter((names.get(msg["worker"], msg["worker"]), msg["key"]) for _, msg in client.get_events(TOPIC))


def _plugin_starts(log: Path) -> Counter:
    """The bundles Dask's worker log says it was given, as it logs every plugin it starts."""
    return Counter(re.findall(r"Starting Worker plugin harness-fmu-(\S+)", log.read_text()))


@pytest.mark.timeout(300)  # a bound on everything: the fixture's clean-up still ends the processes
def test_fmus_travel_once_to_workers_that_cannot_see_them(cluster, fmu_paths):
    # a pendulum and an object with events (whose event times come from its FMI 3.0 build, beside it)
    tasks = [t for t in settings(["SimplePendulum", "BouncingBall"], repeats=1, quick=True)
             if t.method in ("rk4", "scipy-DOP853", "fmpy-CVode")]
    local = work_precision(tasks, workers=2)
    space = cluster.start_worker("w1")
    started = time.monotonic()
    remote = work_precision(tasks, scheduler=cluster.address)
    seconds = time.monotonic() - started
    assert _comparable(remote) == _comparable(local)

    # another sweep over the same FMUs sends nothing again
    def digest(path: str) -> str:  # defined here, it travels by value: the workers cannot import the tests
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    fmus = sorted({task.fmu for task in tasks})
    assert run_sweep(digest, fmus, scheduler=cluster.address) == [digest(fmu) for fmu in fmus]

    with distributed.Client(cluster.address, timeout="10s") as client:
        # a worker that joins later is given what the scheduler holds, once
        cluster.start_worker("w2")
        deadline = time.monotonic() + 10  # its plugins' events reach the scheduler with its first messages
        while len(client.get_events(TOPIC)) < 4 and time.monotonic() < deadline:
            time.sleep(0.1)
        deliveries = _deliveries(client)
        events = [msg for _, msg in client.get_events(TOPIC)]
        bundles = {msg["key"]: msg["files"] for msg in events}

        def local_copies(dask_worker) -> dict[str, str]:
            folder = Path(dask_worker.local_directory) / FOLDER
            return {str(path.relative_to(folder)): hashlib.sha256(path.read_bytes()).hexdigest()
                    for path in folder.rglob("*.fmu")}
        copies = client.run(local_copies)
    assert deliveries == Counter({(worker, key): 1 for worker in ("w1", "w2") for key in bundles})
    assert all(msg["stored"] for msg in events)
    # what travelled: each FMU the tasks name, with the FMI 3.0 build beside it where there is one
    folder = build_dir() / "fmus"
    assert {task.fmu for task in tasks} == {str(folder / "SimplePendulum.fmu"), str(folder / "BouncingBall.fmu")}
    expected = [[name, *([f"fmi3/{name}"] if (folder / "fmi3" / name).is_file() else [])]
                for name in ("BouncingBall.fmu", "SimplePendulum.fmu")]
    assert ["fmi3/BouncingBall.fmu"] in [names[1:] for names in expected]  # its events come from that build
    assert sorted(sorted(files) for files in bundles.values()) == expected
    for files in bundles.values():
        assert files == {name: (folder / name).stat().st_size for name in files}
    # each worker's local directory holds the copies, the FMUs to the byte
    listing = {f"{key}/{name}": hashlib.sha256((folder / name).read_bytes()).hexdigest()
               for key, files in bundles.items() for name in files}
    assert list(copies.values()) == [listing, listing]
    cluster.stop("w1")
    cluster.stop("w2")
    # Dask's own log agrees: one plugin start per bundle and worker; a worker leaves nothing behind
    for name in ("w1", "w2"):
        assert _plugin_starts(cluster.logs[name]) == Counter(bundles.keys())
    assert not list(space.rglob("*.fmu")) and not list((cluster.folder / "w2").rglob("*.fmu"))
    sizes = [size for files in bundles.values() for size in files.values()]
    print(f"\n{len(sizes)} FMU files ({sum(sizes) / 1e6:.2f} MB) to each of 2 workers once; "
          f"{len(tasks)} points in {seconds:.1f} s on the cluster")


@pytest.mark.timeout(120)
def test_an_item_sees_the_workers_copy_and_the_caller_its_own_path(cluster, fmu_paths):
    space = cluster.start_worker("w1")
    fmu = fmu_paths["SimplePendulum"]
    digest = hashlib.sha256(fmu.read_bytes()).hexdigest()

    def look(item):
        path = item["fmu"]
        beside = Path(path).parent / "fmi3" / Path(path).name  # the FMI 3.0 build travels with it
        return {"fmu": path, "kind": type(path).__name__, "folder": str(Path(path).parent),
                "digest": hashlib.sha256(Path(path).read_bytes()).hexdigest(), "both": [path, str(path)],
                "beside": (beside, beside.is_file())}
    results = run_sweep(look, [{"fmu": fmu}, {"fmu": str(fmu)}], scheduler=cluster.address)
    # the item function read the worker's copy ...
    assert [r["kind"] for r in results] == ["PosixPath", "str"]
    assert all(r["digest"] == digest for r in results)
    assert all(r["folder"].startswith(str(space)) and f"/{FOLDER}/SimplePendulum-" in r["folder"] for r in results)
    # ... and the paths it returns are the caller's again, of the type they had
    assert [r["fmu"] for r in results] == [fmu, str(fmu)]
    assert [type(r["fmu"]) for r in results] == [type(fmu), str]
    assert results[0]["both"] == [fmu, str(fmu)] and results[1]["both"] == [str(fmu), str(fmu)]
    assert results[0]["beside"] == (fmu.parent / "fmi3" / fmu.name, True)

    def read(folder):
        return Path(folder, fmu.name).read_bytes()
    with pytest.raises(PermissionError):  # the worker cannot see the build folder: only the copy it was given
        run_sweep(read, [str(fmu.parent)], scheduler=cluster.address)

    def fail(item):  # a message names the item's paths, not the worker's
        raise HarnessError(f"{item}: broken on purpose (and {Path(item).parent / 'fmi3' / Path(item).name})")
    with pytest.raises(HarnessError) as error:
        run_sweep(fail, [str(fmu)], scheduler=cluster.address)
    assert str(error.value) == f"{fmu}: broken on purpose (and {fmu.parent / 'fmi3' / fmu.name})"
    with distributed.Client(cluster.address, timeout="10s") as client:
        assert sum(_deliveries(client).values()) == 1
