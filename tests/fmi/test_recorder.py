"""The recorder's native loop (harness/fmi/native/record_loop.c) against its Python loop: the same
table bit for bit, the same stop at a discarded step, the same messages, in both FMI versions."""
from __future__ import annotations

import numpy as np
import pytest

from harness.fmi.fmu_instance import FmuInstance
from harness.fmi.fmus import build_dir
from harness.fmi.simulation import Recorder, communication_grid

CASES = [
    ("SimplePendulum", {"solver": "ab6", "h": 0.004}),
    ("DoublePendulum", {"solver": "gauss_legendre4", "h": 0.01, "phi1": 1.5}),
    ("SpringPendulum", {"solver": "rkf45", "tol": 1e-9}),
    ("CartPendulum", {"solver": "rk4", "h": 0.005}),
]


def fmu_path(name: str, version: str):
    return build_dir() / "fmus" / ("fmi3" if version == "3.0" else "") / f"{name}.fmu"


def record(name: str, version: str, start: dict, stop: float, step: float, native: bool, outputs=None):
    with FmuInstance(fmu_path(name, version), name=name) as instance:
        names = outputs or [v.name for v in instance.model_description.modelVariables if v.causality == "output"]
        recorder = Recorder(instance, communication_grid(0.0, stop, step), names, native=native)
        assert recorder.native == native
        results = []
        for _ in range(2):  # prepared once, run twice: the second run starts from a reset
            instance.reset()
            instance.initialize(0.0, **start)
            results.append(recorder.run())
        assert np.array_equal(results[0].values, results[1].values)
        return results[0]


@pytest.mark.parametrize("version", ["2.0", "3.0"])
@pytest.mark.parametrize("name,start", CASES)
def test_native_and_python_loops_give_the_same_table(fmu_paths, name, start, version):
    native = record(name, version, start, 10.0, 0.01, True)
    python = record(name, version, start, 10.0, 0.01, False)
    assert native.columns == python.columns and "n_rhs" in native.columns
    assert native.values.shape == (1001, len(native.columns))
    assert np.array_equal(native.values, python.values)
    assert native.discarded_at is None and native.messages == python.messages


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_a_discarded_step_stops_both_loops_at_the_same_row(fmu_paths, version):
    """The spherical pendulum through its pole: the step is discarded, the state it reached is the last
    row (at the last successful time), and the message is kept."""
    start = {"h": 0.001, "psi_dot": 0.0}  # the plane swing reaches the pole, where psi is undefined
    native = record("SphericalPendulum", version, start, 5.0, 0.01, True)
    python = record("SphericalPendulum", version, start, 5.0, 0.01, False)
    assert native.discarded_at is not None and native.discarded_at == python.discarded_at
    assert np.array_equal(native.values, python.values)
    assert native.values[-1, 0] == native.discarded_at
    assert native.messages == python.messages and "DoStep" in native.messages[-1]


def test_only_the_requested_outputs_in_their_order(fmu_paths):
    native = record("SimplePendulum", "2.0", {}, 1.0, 0.1, True, outputs=["n_steps", "y", "x"])
    python = record("SimplePendulum", "2.0", {}, 1.0, 0.1, False, outputs=["n_steps", "y", "x"])
    assert native.columns == ["time", "y", "x", "n_steps"]  # floats first, then integers
    assert np.array_equal(native.values, python.values)
    assert native.values[-1, 3] == 130  # h = 0.008: ceil(0.1 / 0.008) = 13 steps per 0.1 s


def test_many_rows_cross_many_native_calls(fmu_paths):
    """More rows than one call takes: the calls join without a gap or a repeated step."""
    with FmuInstance(fmu_path("SimplePendulum", "2.0")) as instance:
        recorder = Recorder(instance, communication_grid(0.0, 50.0, 0.001), ["phi", "n_steps"])
        recorder.CHUNK_SECONDS = 1e-5  # calls of a few rows each
        instance.initialize(0.0, solver="rk4", h=0.001)
        result = recorder.run()
    assert result.values.shape == (50001, 3)
    assert np.array_equal(result.values[:, 2], np.arange(50001))  # one internal step per row, none repeated


def test_an_interrupt_keeps_every_row_the_fmu_stepped_to(fmu_paths):
    """Ctrl-C during a long native call: the call finishes its rows (calls grow from one row to about
    0.1 s), and every row it wrote is kept: the last row is where the FMU is."""
    import signal
    with FmuInstance(fmu_path("SimplePendulum", "2.0")) as instance:
        recorder = Recorder(instance, communication_grid(0.0, 100.0, 0.01), ["phi", "n_steps"])
        instance.initialize(0.0, solver="rk4", h=2e-6)  # about 5,000 substeps per row
        previous = signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.setitimer(signal.ITIMER_REAL, 0.3)
        alarm = signal.signal(signal.SIGALRM, lambda *_: signal.raise_signal(signal.SIGINT))
        try:
            result = recorder.run(keep_interrupted=True)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, alarm)
            signal.signal(signal.SIGINT, previous)
        assert result.interrupted and 2 <= len(result.values) < 10001
        assert result.values[-1, 0] == pytest.approx(instance.last_successful_time(), abs=1e-12)
        assert result.values[-1, 2] == instance.get("n_steps")[0]
