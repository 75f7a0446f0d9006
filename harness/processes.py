"""Programs the harness runs (the C compiler, CMake): each in a process group of its own with a
temporary folder of its own, so that an interrupt ends the whole tree it started (make, the compiler
driver, cc1, as) and nothing they wrote to the temporary folder is left behind."""
from __future__ import annotations

import os
import signal
import subprocess
import tempfile
from collections.abc import Sequence

GRACE_SECONDS = 5.0  # after SIGTERM, before SIGKILL


def run_program(command: Sequence[str], stdout=subprocess.PIPE, stderr=subprocess.PIPE) -> subprocess.CompletedProcess:
    """Runs command to its end and returns what it printed (text). When the caller is interrupted
    (Ctrl-C, SIGTERM, any exception) the program's whole process group is ended before the
    interrupt goes on."""
    with tempfile.TemporaryDirectory(prefix="program-") as scratch:
        environment = dict(os.environ, TMPDIR=scratch)  # gcc's cc*.s and cc*.o go here
        process = subprocess.Popen(list(command), stdout=stdout, stderr=stderr, text=True, env=environment,
                                   start_new_session=True)
        try:
            out, err = process.communicate()
        except BaseException:
            _end_group(process)
            raise
        return subprocess.CompletedProcess(list(command), process.returncode, out, err)


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
