"""The reference result of every FMU, and the importers on this machine that run the x86_64 Linux
binaries of both FMI versions against it: the harness itself and fmpy (Co-Simulation, and Model
Exchange under CVode). Each test is a row of docs/compatibility.md (tests/compatibility_record.py);
the other rows come from the tests of the other importers (platforms, peers, checkers)."""
from __future__ import annotations

import fmpy
import numpy as np
import pytest

from compatibility_record import Reference
from harness.fmi.calls import is_float
from harness.fmi.fmu_instance import read_description
from harness.fmi.fmus import FMU_NAMES, build_dir
from harness.fmi.results import rows_on_grid
from harness.fmi.simulation import simulate

from conftest import ELEMENT_MOTION, ELEMENTS

STOP, STEP = 10.0, 0.05
ME_STOP, ME_RTOL, ME_BOUND = 1.0, 1e-9, 1e-6
# A coupling element alone with its default inputs rests: its ends move.
START = ELEMENT_MOTION
HARNESS = "harness (this project, on fmpy's loader)"


def fmu(name: str, version: str):
    return build_dir() / "fmus" / (f"{name}.fmu" if version == "2.0" else f"fmi3/{name}.fmu")


def float_outputs(name: str) -> list[str]:
    return [v.name for v in read_description(fmu(name, "2.0")).modelVariables
            if v.causality == "output" and is_float(v)]


def command(name: str) -> str:
    settings = "".join(f" --set {k}={v}" for k, v in START.get(name, {}).items())
    return f"python -m harness simulate {name} --stop {STOP:g} --step {STEP:g}{settings} --out {name}_ref.csv"


@pytest.fixture(scope="module")
def references(fmu_paths, compatibility_record, tmp_path_factory) -> dict[str, dict[str, np.ndarray]]:
    """Each FMU's reference: the FMI 2.0 binary through the harness, written as `simulate` writes it."""
    folder = tmp_path_factory.mktemp("references")
    tables = {}
    for name in FMU_NAMES:
        result = simulate(fmu(name, "2.0"), STOP, STEP, start_values=START.get(name, {}))
        result.write_csv(folder / f"{name}_ref.csv")
        options = f"StartTime, 0.0\nStopTime, {STOP}\nStepSize, {STEP}\nRelTol, {ME_RTOL}\n"
        compatibility_record.references[name] = Reference(command(name), (folder / f"{name}_ref.csv").read_text(),
                                                          options)
        tables[name] = {column: np.asarray(result[column]) for column in ["time", *float_outputs(name)]}
    return tables


def deviation(reference: dict[str, np.ndarray], columns, rows: slice = slice(None)) -> float:
    """The largest |a - b| / max(1, |a|) over the reference's float outputs."""
    worst = 0.0
    for name, expected in reference.items():
        got = np.asarray(columns(name), dtype=float)
        assert got.shape == expected[rows].shape, name
        worst = max(worst, float(np.max(np.abs(got - expected[rows]) / np.maximum(1.0, np.abs(expected[rows])))))
    return worst


def test_every_reference_moves_and_holds_every_output(references):
    for name, table in references.items():
        assert len(table["time"]) == round(STOP / STEP) + 1
        moving = [column for column, values in table.items() if column != "time" and np.ptp(values) > 1e-3]
        assert len(moving) >= 3, name
        assert all(np.all(np.isfinite(values)) for values in table.values())


@pytest.mark.compatibility(importer=HARNESS, version="{version}", interface="CS", platform="x86_64 Linux",
                           criterion="the reference, bit for bit")
@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_the_harness_runs_both_versions_to_the_reference(references, compatibility, version):
    for name, reference in references.items():
        result = simulate(fmu(name, version), STOP, STEP, start_values=START.get(name, {}))
        difference = deviation(reference, lambda column: result[column])
        assert difference == 0.0, name
        compatibility.agrees(name, difference)


@pytest.mark.compatibility(importer=f"fmpy {fmpy.__version__} simulate_fmu", version="{version}", interface="CS",
                           platform="x86_64 Linux", criterion="the reference, bit for bit")
@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_fmpy_co_simulation_gives_the_reference(references, compatibility, version):
    for name, reference in references.items():
        result = fmpy.simulate_fmu(str(fmu(name, version)), stop_time=STOP, output_interval=STEP,
                                   start_values=START.get(name, {}), fmi_type="CoSimulation")
        difference = deviation(reference, lambda column: result[column])
        assert difference == 0.0, name
        compatibility.agrees(name, difference)


@pytest.mark.compatibility(importer=f"fmpy {fmpy.__version__} simulate_fmu, CVode (rtol {ME_RTOL:g})",
                           version="{version}", interface="ME", platform="x86_64 Linux",
                           criterion=f"the FMU's rkf45 at tol 1e-12 (CS) over {ME_STOP:g} s, within {ME_BOUND:g}")
@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_fmpy_model_exchange_follows_a_tight_co_simulation(fmu_paths, compatibility, version):
    """Another integrator on the FMU's equations: CVode in Model Exchange against the FMU's own
    rkf45 at a tight tolerance, over a second (before the chaotic objects amplify the difference).
    Not the coupling elements: they have no states, and in Model Exchange their ends stay where the inputs put them
    (in Co-Simulation it moves them by their velocities over a step)."""
    for name in (n for n in FMU_NAMES if n not in ELEMENTS):
        tight = simulate(fmu(name, "2.0"), ME_STOP, STEP, start_values={"solver": "rkf45", "tol": 1e-12})
        reference = {column: np.asarray(tight[column]) for column in float_outputs(name)}
        result = fmpy.simulate_fmu(str(fmu(name, version)), stop_time=ME_STOP, output_interval=STEP,
                                   fmi_type="ModelExchange", solver="CVode", relative_tolerance=ME_RTOL)
        result = result[rows_on_grid(result["time"], np.asarray(tight["time"]))]  # not the rows fmpy adds at events
        difference = deviation(reference, lambda column: result[column])
        assert difference < ME_BOUND, (name, difference)
        compatibility.agrees(name, difference)


def test_the_record_renders_every_outcome():
    """The table counts and words what it holds: an agreeing row, a skipped one, a failing one."""
    from compatibility_record import Record, Row, render
    record = Record()
    good = record.rows.setdefault(("a", "2.0", "CS", "p"), Row("a", "2.0", "CS", "p", "ref"))
    good.agrees("X", 0.0)
    good.agrees("Y", 3e-13)
    skipped = record.rows.setdefault(("b", "3.0", "CS", "p"), Row("b", "3.0", "CS", "p", "ref"))
    skipped.worsen("not run", "wine is not installed")
    failed = record.rows.setdefault(("c", "3.0", "ME", "p"), Row("c", "3.0", "ME", "p", "ref"))
    failed.agrees("X", 0.5)
    failed.worsen("fails", "test_c failed")
    text = render(record)
    assert "3 rows: 1 agree, 1 not run here (each with its reason), 1 fail." in text
    assert "| a | 2.0 | CS | p | ref | agrees | 2 | 3.0e-13 (Y) |" in text
    assert "| b | 3.0 | CS | p | ref | not run: wine is not installed | 0 | - |" in text
    assert "| c | 3.0 | ME | p | ref | fails: test_c failed | 1 | 5.0e-01 (X) |" in text
