"""Programs the harness runs (the C compiler, CMake): each in a process group of its own with a
temporary folder of its own, so that an interrupt ends the whole tree it started (make, the compiler
driver, cc1, as) and nothing they wrote to the temporary folder is left behind."""
from __future__ import annotations

import os
import signal
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

GRACE_SECONDS = 5.0  # after SIGTERM, before SIGKILL


def run_program(command: Sequence[str], stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd: Path | None = None,
                environment: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """Runs command to its end (in cwd, with environment or this process's) and returns what it printed
    (text). When the caller is interrupted (Ctrl-C, SIGTERM, a test's time-out, any exception) the program's
    whole process group is ended before the interrupt goes on."""
    with tempfile.TemporaryDirectory(prefix="program-") as scratch:
        process = _start(command, scratch, stdout, stderr, cwd, environment)
        try:
            out, err = process.communicate()
        except BaseException:
            _end_group(process)
            raise
        return subprocess.CompletedProcess(list(command), process.returncode, out, err)


def _start(command: Sequence[str], scratch: str, stdout, stderr, cwd: Path | None = None,
           environment: dict[str, str] | None = None) -> subprocess.Popen:
    """The program in a process group of its own, its temporary files in scratch (gcc's cc*.s, cc*.o)."""
    return subprocess.Popen(list(command), stdout=stdout, stderr=stderr, text=True, cwd=cwd,
                            env=dict(os.environ if environment is None else environment, TMPDIR=scratch),
                            start_new_session=True)


def _end_group(process: subprocess.Popen) -> None:
    try:
        os.killpg(process.pid, signal.SIGTERM)
        process.wait(timeout=GRACE_SECONDS)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        pass
    try:  # members that outlived the leader or ignored SIGTERM
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    process.wait()


def run_programs(commands: Sequence[Sequence[str]], parallel: int = 4) -> list[subprocess.CompletedProcess]:
    """Runs the commands, at most `parallel` at a time, each as run_program does (what it printed
    goes to files in its temporary folder, so that no pipe fills up); returns their results in order.
    An interrupt ends every running program's group before it goes on."""
    results: list[subprocess.CompletedProcess | None] = [None] * len(commands)
    waiting = list(enumerate(commands))
    running: list[tuple[int, subprocess.Popen, tempfile.TemporaryDirectory]] = []
    try:
        while waiting or running:
            while waiting and len(running) < parallel:
                index, command = waiting.pop(0)
                scratch = tempfile.TemporaryDirectory(prefix="program-")
                try:
                    with open(os.path.join(scratch.name, ".stdout"), "w") as out, \
                            open(os.path.join(scratch.name, ".stderr"), "w") as err:
                        process = _start(command, scratch.name, out, err)
                except BaseException:
                    scratch.cleanup()
                    raise
                running.append((index, process, scratch))
            for entry in list(running):
                index, process, scratch = entry
                try:
                    process.wait(timeout=0.02)
                except subprocess.TimeoutExpired:
                    continue
                running.remove(entry)
                with scratch:
                    printed = [Path(scratch.name, name).read_text(errors="replace") for name in (".stdout", ".stderr")]
                results[index] = subprocess.CompletedProcess(list(commands[index]), process.returncode, *printed)
    except BaseException:
        for _, process, scratch in running:
            _end_group(process)
            scratch.cleanup()
        raise
    return results  # type: ignore[return-value]
