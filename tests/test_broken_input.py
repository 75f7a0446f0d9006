"""The harness against broken input: one line on stderr, a non-zero exit code, no traceback, and
results written so far kept."""
from __future__ import annotations

import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

from harness.fmi.fmus import PROJECT_ROOT, build_dir


def harness(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "harness", *args], capture_output=True, text=True)


def one_line_error(result: subprocess.CompletedProcess, words: str, code: int = 2) -> None:
    lines = result.stderr.strip().splitlines()
    assert result.returncode == code, result.stderr
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in result.stderr, result.stderr


def rewrite_fmu(source: Path, target: Path, drop_prefix: str = "", replace: tuple[bytes, bytes] | None = None) -> Path:
    with zipfile.ZipFile(source) as original, zipfile.ZipFile(target, "w") as copy:
        for item in original.infolist():
            if drop_prefix and item.filename.startswith(drop_prefix):
                continue
            data = original.read(item)
            if replace and item.filename == "modelDescription.xml":
                data = data.replace(*replace)
            copy.writestr(item, data)
    return target


@pytest.fixture
def broken(fmu_paths, tmp_path) -> dict[str, Path]:
    simple = fmu_paths["SimplePendulum"]
    (tmp_path / "corrupt.fmu").write_bytes(b"PK\x03\x04 this is not a zip archive")
    return {
        "corrupt": tmp_path / "corrupt.fmu",
        "no binary": rewrite_fmu(simple, tmp_path / "nobinary.fmu", drop_prefix="binaries/"),
        "FMI 3.0": rewrite_fmu(simple, tmp_path / "fmi3.fmu", replace=(b'fmiVersion="2.0"', b'fmiVersion="3.0"')),
        "missing": tmp_path / "missing.fmu",
    }


@pytest.mark.parametrize("case,words", [("corrupt", "not a zip archive"),
                                        ("no binary", "no binary for this platform"),
                                        ("FMI 3.0", "Failed to validate modelDescription.xml: (line 5, column 0): Element "
                                                    "'fmiModelDescription', attribute 'guid': The attribute 'guid' "
                                                    "is not allowed; and "),
                                        ("missing", "no such FMU file")])
def test_broken_fmus(broken, tmp_path, case, words):
    one_line_error(harness("simulate", str(broken[case]), "--out", str(tmp_path / "x.csv")), words)
    if case != "missing":
        result = harness("validate", str(broken[case]))
        assert result.returncode == 1 and "FAIL" in result.stdout and "Traceback" not in result.stderr


def ssp_copy(tmp_path: Path) -> Path:
    folder = tmp_path / "ssp"
    shutil.copytree(build_dir() / "scenes" / "coupled_pendulums", folder)
    return folder


def ssd_edited(text: str, pattern: str, replacement: str) -> str:
    """`text` with every match of `pattern` replaced; the pattern must match, or the test would pass
    on an SSD it never edited. Patterns allow for the exporter's line breaks between elements."""
    text, count = re.subn(pattern, replacement, text)
    assert count, pattern
    return text


def test_malformed_ssd(fmu_paths, tmp_path):
    folder = ssp_copy(tmp_path)
    (folder / "SystemStructure.ssd").write_text("<ssd:SystemStructureDescription xmlns:ssd='x'><unclosed")
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "malformed SSD")


def test_an_ssd_against_its_schema_names_the_first_problem(fmu_paths, tmp_path):
    folder = ssp_copy(tmp_path)
    ssd = folder / "SystemStructure.ssd"
    text = ssd.read_text()
    line = text[:text.index("<ssd:System ")].count("\n") + 1  # where the edit lands, as the schema check counts
    ssd.write_text(text.replace("<ssd:System ", '<ssd:System bogus="1" ', 1))
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   f"Failed to validate SystemStructure.ssd: (line {line}, column 0): Element "
                   "'{http://ssp-standard.org/SSP1/SystemStructureDescription}System', attribute 'bogus': "
                   "The attribute 'bogus' is not allowed)")


def test_ssd_connection_to_a_missing_variable(fmu_paths, tmp_path):
    folder = ssp_copy(tmp_path)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd.read_text().replace('endElement="spring" endConnector="a_x"',
                                           'endElement="spring" endConnector="a_z"'))
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "spring has no input 'a_z'")


def test_ssd_component_without_its_fmu(fmu_paths, tmp_path):
    folder = ssp_copy(tmp_path)
    (folder / "resources" / "Spring.fmu").unlink()
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "source resources/Spring.fmu not found")


def test_connection_between_different_units(fmu_paths, tmp_path):
    scene = json.loads((PROJECT_ROOT / "scenes" / "coupled_pendulums.json").read_text())
    scene["connections"][0] = ["left.phi", "spring.a_x"]  # an angle into a position
    del scene["bonds"]  # whose position this connection was
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    one_line_error(harness("run", str(path), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")),
                   "units differ (rad to m)")


def test_a_stopped_run_keeps_its_rows(fmu_paths, tmp_path):
    scene = json.loads((PROJECT_ROOT / "scenes" / "coupled_pendulums.json").read_text())
    scene["components"]["spring"]["start"]["k"] = 4000.0
    for side in ("left", "right"):
        scene["components"][side]["start"].update(solver="euler", h=0.05)
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    out = tmp_path / "out.csv"
    result = harness("run", str(path), "--stop", "5", "--step", "0.05", "--out", str(out), "--quiet")
    assert result.returncode == 1 and "could not complete the step" in result.stderr
    rows = out.read_text().splitlines()
    assert rows[0].startswith("time,") and len(rows) > 5


# ---- writing results: checked paths, no loss on failure, interrupts keep rows ------------------

def test_a_full_disk_loses_nothing(fmu_paths, tmp_path, monkeypatch):
    """Writing fails (ENOSPC): one line naming the file, the earlier file as it was, no temporary file."""
    import errno
    from harness import output
    from harness.cli import main
    out = tmp_path / "result.csv"
    out.write_text("earlier result\n")

    class FullDisk(io.StringIO):
        def write(self, text):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def close(self):
            pass

    monkeypatch.setattr(output.os, "fdopen", lambda descriptor, *args, **kwargs: (os.close(descriptor), FullDisk())[1])
    code = main(["simulate", "SimplePendulum", "--stop", "0.1", "--out", str(out)])
    assert code == 2 and out.read_text() == "earlier result\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["result.csv"]


def test_an_unwritable_folder_is_one_line(fmu_paths, tmp_path, monkeypatch, capsys):
    """A folder the user may not write to (simulated: root may write anywhere)."""
    import errno
    from harness import output
    from harness.cli import main

    def refused(*args, **kwargs):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))

    monkeypatch.setattr(output.tempfile, "mkstemp", refused)
    code = main(["simulate", "SimplePendulum", "--stop", "0.1", "--out", str(tmp_path / "x.csv")])
    error = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(error) == 1 and "x.csv: cannot write here (Permission denied)" in error[0], error


def test_two_runs_writing_one_file_do_not_interleave(fmu_paths, tmp_path):
    out = tmp_path / "shared.csv"
    runs = [subprocess.Popen([sys.executable, "-m", "harness", "simulate", "SimplePendulum", "--stop", "20",
                              "--step", "0.001", "--set", f"phi={phi}", "--out", str(out)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) for phi in (0.5, 0.25)]
    assert [run.wait() for run in runs] == [0, 0]
    rows = out.read_text().splitlines()
    assert len(rows) == 20002 and float(rows[1].split(",")[1]) in (0.5, 0.25)
    phi0 = rows[1].split(",")[1]
    assert all(len(row.split(",")) == len(rows[0].split(",")) for row in rows)
    assert not [p for p in tmp_path.iterdir() if p.name != "shared.csv"]
    assert phi0 in ("0.5", "0.25")


@pytest.mark.parametrize("command,signal_number", [("simulate", signal.SIGINT), ("run", signal.SIGTERM)])
def test_an_interrupted_run_keeps_its_rows_and_removes_its_temporary_folders(fmu_paths, tmp_path, command,
                                                                             signal_number):
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    out = tmp_path / "long.csv"
    args = (["simulate", "SimplePendulum", "--stop", "2000", "--step", "0.001", "--h", "1e-5"] if command == "simulate"
            else ["run", str(build_dir() / "scenes" / "coupled_pendulums.ssp"), "--stop", "2000", "--step", "0.001",
                  "--quiet"])
    process = subprocess.Popen([sys.executable, "-m", "harness", *args, "--out", str(out)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               env={**os.environ, "TMPDIR": str(scratch)},
                               # a shell running the tests in the background ignores SIGINT, and children inherit that
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 60
    while not list(scratch.iterdir()) and time.monotonic() < deadline:  # its FMUs are extracted: it runs
        time.sleep(0.05)
    time.sleep(2.0)
    process.send_signal(signal_number)
    stdout, stderr = process.communicate(timeout=60)
    assert process.returncode == 130 and stderr.strip() == "harness: interrupted", stderr
    rows = out.read_text().splitlines()
    assert len(rows) > 10 and all(len(r.split(",")) == len(rows[0].split(",")) for r in rows)
    assert list(scratch.iterdir()) == []
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".part")] == []


def handlers_installed(pid: int) -> bool:
    """Whether the harness in process pid has installed its signal handlers (it catches SIGTERM): from
    then on its own code runs, before that only the interpreter's start."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("SigCgt:"):
                return bool(int(line.split()[1], 16) >> (signal.SIGTERM - 1) & 1)
    except OSError:
        pass
    return False


def test_an_interrupt_at_any_moment_of_a_rolled_back_run_ends_it_cleanly(fmu_paths, tmp_path):
    """`run --tolerance` on the coupled scene (the Python loop: every macro step saves, restores and
    releases FMU states, and the FMUs call back into the harness) interrupted at 25 seeded random
    moments from the harness's start to past the run's end (loading, extracting and instantiating the
    FMUs, the loop, writing, freeing): each ends with exit code 130 and the one line "harness:
    interrupted" (0 and no line where it had finished), leaves nothing in its temporary folder and no
    .part file, and keeps its rows so far: lines of the uninterrupted run's file, in their order. Before
    the fix an interrupt inside the FMU's memory callbacks (Python, then) corrupted the heap (SIGABRT,
    SIGSEGV) or was swallowed, the run going on to its end deaf to Ctrl-C."""
    import random
    scene = PROJECT_ROOT / "scenes" / "coupled_pendulums.json"
    args = ["run", str(scene), "--tolerance", "1e-3", "--stop", "4", "--quiet"]

    def interrupted(name: str, delay: float | None) -> tuple[subprocess.Popen, str, Path, Path, float]:
        """The run, sent SIGINT `delay` seconds after its handlers are installed; also how long it went on."""
        scratch, out = tmp_path / name / "scratch", tmp_path / name / "out" / "coupled.csv"
        scratch.mkdir(parents=True)
        out.parent.mkdir()
        process = started([*args, "--out", str(out)], scratch)
        deadline = time.monotonic() + 30
        while not handlers_installed(process.pid) and process.poll() is None and time.monotonic() < deadline:
            time.sleep(0.001)
        if delay is not None:
            time.sleep(delay)
            process.send_signal(signal.SIGINT)
        signalled = time.monotonic()
        try:
            _, stderr = process.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
            pytest.fail(f"the run interrupted {delay} s after its start did not end within 60 s")
        return process, stderr, scratch, out, time.monotonic() - signalled

    process, stderr, scratch, out, duration = interrupted("whole", None)
    assert process.returncode == 0 and stderr == "", stderr
    whole = out.read_text().splitlines()
    assert len(whole) == 402 and whole[0].startswith("time,") and list(scratch.iterdir()) == []

    rng = random.Random(20240611)
    outcomes = []
    for k, delay in enumerate(sorted(rng.uniform(0.0, 1.15 * duration) for _ in range(25))):
        process, stderr, scratch, out, went_on = interrupted(f"run{k}", delay)
        where = f"interrupted {delay:.3f} s after its start (the whole run: {duration:.2f} s)"
        lines = stderr.strip().splitlines()
        if process.returncode == 0:  # it was ending: not an interrupt lost, the run going on to its end
            assert stderr == "" and went_on < 1.0, f"{where}: went on for {went_on:.2f} s, stderr {stderr!r}"
        else:
            assert process.returncode == 130 and lines == ["harness: interrupted"], \
                f"{where}: exit code {process.returncode}, stderr {stderr!r}"
        assert list(scratch.rglob("*")) == [], f"{where}: left {sorted(scratch.rglob('*'))}"
        assert [p.name for p in out.parent.iterdir() if p.name != out.name] == [], where
        rows = out.read_text().splitlines() if out.exists() else []
        assert rows == whole[:len(rows)] and len(rows) != 1, f"{where}: {len(rows)} lines, not the run's first ones"
        assert process.returncode == 130 or len(rows) == len(whole), where
        outcomes.append(process.returncode)
    assert outcomes.count(130) >= 10, outcomes  # most moments fall inside the run


def test_no_fmu_state_outlives_its_use_over_a_long_iterated_run(fmu_paths, monkeypatch):
    """100 macro steps, each iterated to 1e-10 (a state saved and restored per pass) under step
    doubling and retry on discard: at every recorded row each component holds exactly what it held
    before the first step (counted through the FMU's memory callbacks), so every state the parts
    saved was released once it had served, and nothing after close."""
    from harness.cosim.master import Master, MasterOptions
    from harness.cosim.system import load_system
    from harness.fmi.fmu_instance import LogCollector
    monkeypatch.setattr(LogCollector, "counting", True)
    with load_system(PROJECT_ROOT / "scenes" / "coupled_pendulums.json") as system:
        master = Master(system, MasterOptions(stop=10.0, step=0.1, iterate_tol=1e-10, tolerance=1e-4,
                                              on_discard="retry"))
        held: list[list[int]] = []
        with master:
            before = [u.instance.log.live_blocks for u in master.units]
            result = master.run(on_row=lambda row: held.append([u.instance.log.live_blocks for u in master.units]))
            assert result.stopped_at is None and len(held) == 101 and result.iterations > 100
            assert result.retries > 0  # step doubling rejected steps: states were restored, not only taken
            assert held == [before] * 101
            assert [u.live_states for u in master.units] == [0] * len(master.units)
        assert [unit.instance.log.live_blocks for unit in master.units] == [0] * len(master.units)


def test_a_discard_inside_an_iterated_step_releases_its_states(fmu_paths, monkeypatch):
    """A step that fails deep inside retry and iteration (every halving discards) leaves no state
    behind: the run stops with its message and the components hold what they held before it."""
    from harness.cosim.master import Master, MasterOptions
    from harness.cosim.system import load_system
    from harness.fmi.fmu_instance import LogCollector
    monkeypatch.setattr(LogCollector, "counting", True)
    with load_system(PROJECT_ROOT / "scenes" / "coupled_pendulums.json") as system:
        # the spring's rest length 0 with both ends at one point is fine; a huge stiffness blows up
        system.components[0].start.update(k=1e9)
        master = Master(system, MasterOptions(stop=1.0, step=0.1, iterate_tol=1e-10, on_discard="retry",
                                              max_halvings=3))
        with master:
            before = [u.instance.log.live_blocks for u in master.units]
            result = master.run()
            assert result.stopped_at is not None and "could not complete" in result.message
            assert [u.live_states for u in master.units] == [0] * len(master.units)
            assert [u.instance.log.live_blocks for u in master.units] == before


def started(args: list[str], scratch: Path, env: dict | None = None) -> subprocess.Popen:
    """The harness in a process of its own, with its temporary files in `scratch`."""
    return subprocess.Popen([sys.executable, "-m", "harness", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "TMPDIR": str(scratch), **(env or {})},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def wait_for(condition, seconds: float = 120) -> None:
    deadline = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < deadline, "the run never reached the point to interrupt"
        time.sleep(0.05)


def processes_naming(text: str) -> list[str]:
    """Command lines of the running processes that mention text (a folder only our run uses)."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            line = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if entry.name.isdigit() and text in line:
            found.append(line)
    return found


def ended_cleanly(process: subprocess.Popen, scratch: Path) -> None:
    stdout, stderr = process.communicate(timeout=60)  # ends in seconds, though items or tools were mid-way
    assert process.returncode == 130 and stderr.strip().splitlines()[-1] == "harness: interrupted", stderr
    time.sleep(0.5)
    assert processes_naming(str(scratch)) == []
    assert list(scratch.iterdir()) == []


def test_an_interrupted_plan_ends_its_workers_and_their_files(fmu_paths, tmp_path):
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    process = started(["plan", str(PROJECT_ROOT / "scenes" / "thesis_scene.json"), "--workers", "2"], scratch)
    wait_for(lambda: any(p.name.startswith("sweep-") and any(p.iterdir()) for p in scratch.iterdir()))
    time.sleep(1.0)
    process.send_signal(signal.SIGINT)
    ended_cleanly(process, scratch)


def test_an_interrupted_derive_ends_the_compiler(tmp_path):
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    process = started(["derive", str(PROJECT_ROOT / "modelDescription" / "DoublePendulum.toml"), "--out",
                       str(tmp_path / "out")], scratch)
    wait_for(lambda: processes_naming(f"{scratch}/program-") and any("cc1" in p for p in processes_naming(str(scratch))))
    process.send_signal(signal.SIGTERM)
    ended_cleanly(process, scratch)
    assert not list((tmp_path / "out").glob("*.fmu"))


def test_an_interrupted_build_ends_make(tmp_path):
    """The FMUs built on demand into an empty build folder: an interrupt ends cmake and what it started
    (the first program cmake runs, the generator of the objects' C, or a compiler)."""
    scratch, build = tmp_path / "scratch", tmp_path / "build"
    scratch.mkdir()
    process = started(["simulate", "SimplePendulum", "--out", str(tmp_path / "x.csv")], scratch,
                      {"PENDULUM_BUILD_DIR": str(build), "PENDULUM_SKIP_BUILD": "0"})
    wait_for(lambda: any(not p.split()[0].endswith("cmake") for p in processes_naming(str(build))))
    process.send_signal(signal.SIGTERM)
    ended_cleanly(process, scratch)
    assert processes_naming(str(build)) == []


def test_a_second_interrupt_does_not_cut_the_clean_up_short(fmu_paths, tmp_path):
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    out = tmp_path / "long.csv"
    process = started(["simulate", "SimplePendulum", "--stop", "2000", "--step", "0.001", "--h", "1e-5", "--quiet",
                       "--out", str(out)], scratch)
    wait_for(lambda: list(scratch.iterdir()))
    time.sleep(1.0)
    for _ in range(3):
        process.send_signal(signal.SIGTERM)
    ended_cleanly(process, scratch)
    assert len(out.read_text().splitlines()) > 10


@pytest.mark.parametrize("case", ["start", "unit", "implementation"])
def test_ssd_features_the_master_does_not_carry_out_are_refused(fmu_paths, tmp_path, case):
    """A start time other than 0, a value in another unit than its variable's, a component asking
    for Model Exchange: one line naming it, never a run that ignores it."""
    folder = ssp_copy(tmp_path)
    ssd = folder / "SystemStructure.ssd"
    edits = {"start": ('startTime="0" stopTime="10.0"', 'startTime="5" stopTime="5.05"'),
             "unit": (r'(<ssv:Parameter name="l0">\s*<ssv:Real) value="1.5"', r'\1 value="1500" unit="mm"'),
             "implementation": ('<ssd:Component name="left" ',
                                '<ssd:Component name="left" implementation="ModelExchange" ')}
    ssd.write_text(ssd_edited(ssd.read_text(), *edits[case]))
    words = {"start": "startTime = 5", "unit": "parameter 'l0' is given in 'mm'",
             "implementation": "'ModelExchange'"}[case]
    one_line_error(harness("run", str(folder), "--stop", "1", "--step", "0.1", "--out", str(tmp_path / "x.csv")), words)
    assert not (tmp_path / "x.csv").exists()


def test_an_ssv_enumeration_names_its_item(fmu_paths, tmp_path):
    """SSP gives an enumeration's value as its item's name: euler runs as euler (its work counts show it)."""
    folder = ssp_copy(tmp_path)
    ssd = folder / "SystemStructure.ssd"
    ssd.write_text(ssd_edited(ssd.read_text(), r'(<ssv:Parameter name="solver">\s*)<ssv:Integer value="5" ?/>',
                              r'\1<ssv:Enumeration value="euler"/>'))
    result = harness("run", str(folder), "--stop", "0.1", "--step", "0.1", "--out", str(tmp_path / "x.csv"))
    assert result.returncode == 0, result.stderr
    header, *rows = (tmp_path / "x.csv").read_text().splitlines()
    column = header.split(",").index("left.n_rhs")
    assert float(rows[-1].split(",")[column]) == 100  # euler: one evaluation per substep of h = 0.001
