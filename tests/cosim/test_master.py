"""The master against an independent monolithic reference of the coupled pendulums: the two
pendulums' and the spring's equations combined by hand and integrated by scipy at tight tolerance
(tests/pair_reference.py)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description

from harness.cosim.algorithm_registry import NAMES as ALGORITHM_NAMES
from harness.cosim.master import MasterOptions, run_system
from harness.cosim.system import load_system
from harness.fmi.fmus import PROJECT_ROOT, build_dir
from harness.objects.thesis.reference import slope
from pair_reference import CoupledPair

SCENE = PROJECT_ROOT / "scenes" / "coupled_pendulums.json"
G, L, M, K, L0, GAP = 9.81, 1.0, 1.0, 10.0, 1.5, 1.5
T = 3.0


def monolithic(t_eval: np.ndarray, c: float = 0.0) -> dict[str, np.ndarray]:
    """The hand-coded monolithic reference, spring damping c."""
    system = load_system(SCENE)
    spring = next(x for x in system.components if x.name == "spring")
    damped = dataclasses.replace(system, components=[dataclasses.replace(spring, start={**spring.start, "c": c})
                                                     if x is spring else x for x in system.components])
    left, right = CoupledPair.from_system(damped).reference(t_eval)
    return {"left.x": left[:, 0], "left.y": left[:, 1], "right.x": right[:, 0], "right.y": right[:, 1]}


def position_error(result) -> float:
    reference = monolithic(result.time)
    return float(max(np.max(np.hypot(result["left.x"] - reference["left.x"], result["left.y"] - reference["left.y"])),
                     np.max(np.hypot(result["right.x"] - reference["right.x"],
                                     result["right.y"] - reference["right.y"]))))


@pytest.fixture(scope="module")
def system(fmu_paths):
    return load_system(SCENE)


STEPS = [0.04, 0.02, 0.01, 0.005]


@pytest.fixture(scope="module")
def errors(system) -> dict[tuple[str, str], list[float]]:
    table = {}
    for algorithm in ALGORITHM_NAMES:
        for extrapolation in ("hold", "linear"):
            table[algorithm, extrapolation] = [
                position_error(run_system(system, MasterOptions(stop=T, step=H, algorithm=algorithm,
                                                                extrapolation=extrapolation)))
                for H in STEPS]
    return table


@pytest.mark.parametrize("algorithm", ALGORITHM_NAMES)
def test_held_inputs_converge_at_first_order(errors, algorithm):
    measured = slope(STEPS, errors[algorithm, "hold"])
    assert 0.8 <= measured <= 1.3, errors[algorithm, "hold"]


@pytest.mark.parametrize("algorithm", ALGORITHM_NAMES)
def test_linear_extrapolation_converges_at_second_order(errors, algorithm):
    measured = slope(STEPS, errors[algorithm, "linear"])
    assert 1.7 <= measured <= 2.4, errors[algorithm, "linear"]


@pytest.mark.parametrize("extrapolation", ["hold", "linear"])
def test_gauss_seidel_no_worse_than_jacobi(errors, extrapolation):
    for gs, jacobi in zip(errors["gauss-seidel", extrapolation], errors["jacobi", extrapolation]):
        assert gs <= jacobi * 1.05


def test_energy_residual_tends_to_zero(system):
    residuals = [run_system(system, MasterOptions(stop=T, step=H)).energy_residual for H in STEPS]
    assert all(a > b for a, b in zip(residuals, residuals[1:]))
    assert slope(STEPS, residuals) >= 1.5 and residuals[-1] < 1e-3


def test_result_table_and_consistent_start(system):
    result = run_system(system, MasterOptions(stop=0.5, step=0.1))
    assert result.columns[0] == "time" and len(result.values) == 6
    assert np.allclose(result.time, [0, 0.1, 0.2, 0.3, 0.4, 0.5])
    # every output of every component, as its model description lists them
    outputs = {c.name: sum(1 for v in read_model_description(c.fmu).modelVariables if v.causality == "output")
               for c in system.components}
    assert outputs == {"left": 15, "spring": 5, "right": 15}
    assert len(result.columns) == 1 + sum(outputs.values())
    # At t = 0 the spring already sees the bobs' start positions (initialization iterates the loop).
    pa = np.array([np.sin(0.5), -np.cos(0.5)])
    pb = np.array([GAP, -1.0])
    d = pb - pa
    force = K * (np.hypot(*d) - L0) * d / np.hypot(*d)
    assert np.allclose([result["spring.Fa_x"][0], result["spring.Fa_y"][0]], force, rtol=1e-12)


def test_ssp_forms_give_the_same_result(system):
    options = MasterOptions(stop=1.0, step=0.01)
    expected = run_system(system, options).values
    for path in (build_dir() / "scenes" / "coupled_pendulums.ssp", build_dir() / "scenes" / "coupled_pendulums",
                 build_dir() / "scenes" / "coupled_pendulums" / "SystemStructure.ssd"):
        assert np.array_equal(run_system(load_system(path), options).values, expected), path


def test_discard_stops_with_a_message_or_retries_with_smaller_steps(system):
    changes = {"spring": {"k": 4000.0}, "left": {"solver": "euler", "h": 0.05}, "right": {"solver": "euler", "h": 0.05}}
    stiff = dataclasses.replace(system, components=[dataclasses.replace(c, start={**c.start, **changes[c.name]})
                                                    for c in system.components])
    stopped = run_system(stiff, MasterOptions(stop=2.0, step=0.05, on_discard="stop"))
    assert stopped.stopped_at is not None and "could not complete the step" in stopped.message
    assert np.all(np.isfinite(stopped.values))
    retried = run_system(stiff, MasterOptions(stop=2.0, step=0.05, on_discard="retry", max_halvings=3))
    assert retried.retries > 0
    assert retried.stopped_at is None or retried.stopped_at >= stopped.stopped_at


def test_iteration_converges_and_improves_on_a_single_pass(system):
    single = run_system(system, MasterOptions(stop=T, step=0.04))
    iterated = run_system(system, MasterOptions(stop=T, step=0.04, iterate_tol=1e-10))
    assert iterated.unconverged == 0 and iterated.iterations > 2 * iterated.macro_steps
    assert position_error(iterated) < position_error(single)
    # Converged passes agree with each other: a looser tolerance gives nearly the same answer.
    loose = run_system(system, MasterOptions(stop=T, step=0.04, iterate_tol=1e-6))
    assert np.max(np.abs(loose.values[:, 1:] - iterated.values[:, 1:])) < 1e-4


@pytest.mark.parametrize("extrapolation,tolerances", [("linear", [1e-3, 1e-4, 1e-5]), ("hold", [1e-2])])
def test_step_doubling_meets_the_requested_accuracy(system, extrapolation, tolerances):
    for tolerance in tolerances:
        result = run_system(system, MasterOptions(stop=T, step=0.1, tolerance=tolerance, extrapolation=extrapolation))
        assert result.stopped_at is None
        assert position_error(result) <= tolerance, (extrapolation, tolerance)
        assert np.allclose(result.time, np.arange(0, T + 1e-9, 0.1))  # rows stay on the output grid


def test_bad_master_options_are_refused():
    from harness.errors import HarnessError
    for kwargs in ({"algorithm": "newton"}, {"extrapolation": "cubic"}, {"tolerance": -1.0}, {"iterate_tol": 0.0}):
        with pytest.raises(HarnessError):
            MasterOptions(stop=1.0, step=0.1, **kwargs)


@pytest.mark.parametrize("algorithm", ALGORITHM_NAMES)
@pytest.mark.parametrize("extrapolation", ["hold", "linear"])
def test_native_loop_is_bit_identical_to_the_python_loop(system, algorithm, extrapolation):
    from harness.cosim.master import Master
    results = []
    for native in (True, False):
        with Master(system, MasterOptions(stop=1.0, step=0.01, algorithm=algorithm,
                                          extrapolation=extrapolation)) as master:
            master.use_native = native
            results.append(master.run())
    assert np.array_equal(results[0].values, results[1].values)
    assert np.array_equal(results[0].energy, results[1].energy)


def test_native_loop_reports_a_discard_like_the_python_loop(system):
    from harness.cosim.master import Master
    changes = {"spring": {"k": 4000.0}, "left": {"solver": "euler", "h": 0.05}, "right": {"solver": "euler", "h": 0.05}}
    stiff = dataclasses.replace(system, components=[dataclasses.replace(c, start={**c.start, **changes[c.name]})
                                                    for c in system.components])
    outcomes = []
    for native in (True, False):
        with Master(stiff, MasterOptions(stop=2.0, step=0.05)) as master:
            master.use_native = native
            result = master.run()
            outcomes.append((result.stopped_at, result.message, result.values.shape, result.macro_steps))
    assert outcomes[0] == outcomes[1] and outcomes[0][0] is not None


def test_ssp_parameter_values_from_an_ssv_file(fmu_paths, tmp_path):
    """A binding that references an .ssv file (SSP 1.0 ParameterBinding source) sets start values."""
    import shutil
    folder = tmp_path / "ssp"
    shutil.copytree(build_dir() / "scenes" / "coupled_pendulums", folder)
    ssd = (folder / "SystemStructure.ssd").read_text()
    start = ssd.index('<ssd:Component name="spring"')
    block_start = ssd.index("<ssd:ParameterBindings>", start)
    block_end = ssd.index("</ssd:ParameterBindings>", start) + len("</ssd:ParameterBindings>")
    ssd = ssd[:block_start] + ('<ssd:ParameterBindings><ssd:ParameterBinding source="resources/spring.ssv"/>'
                               '</ssd:ParameterBindings>') + ssd[block_end:]
    (folder / "SystemStructure.ssd").write_text(ssd)
    (folder / "resources" / "spring.ssv").write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" '
        'version="1.0" name="spring"><ssv:Parameters>'
        '<ssv:Parameter name="k"><ssv:Real value="25"/></ssv:Parameter>'
        '<ssv:Parameter name="l0"><ssv:Real value="1.5"/></ssv:Parameter>'
        '</ssv:Parameters></ssv:ParameterSet>\n')
    system = load_system(folder)
    assert system.component("spring").start == {"k": 25.0, "l0": 1.5}
    result = run_system(system, MasterOptions(stop=0.1, step=0.05))
    assert result.stopped_at is None


def test_instances_of_one_fmu_share_one_extraction_and_one_library(fmu_paths, tmp_path, monkeypatch):
    """A chain of 20 pendulums and 19 springs: while it runs, the process maps each FMU's library once
    and the master has extracted each FMU once; after it, the extractions are gone."""
    import json
    import tempfile

    from harness.cosim.master import Master
    from harness.scene.spring_scenes import pendulum_chain
    scene = tmp_path / "chain.json"
    scene.write_text(json.dumps(pendulum_chain(20)))
    system = load_system(scene)
    scratch = tmp_path / "scratch"  # this process's temporary files: other runs use the system's folder
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    with Master(system, MasterOptions(stop=0.1, step=0.01)) as master:
        extracted = set(scratch.glob("fmu_*"))
        assert len(extracted) == 2  # SimplePendulum and Spring
        mapped = {line.split()[-1] for line in Path("/proc/self/maps").read_text().splitlines()
                  if any(line.endswith(str(folder / "binaries" / "linux64" / library)) for folder in extracted
                         for library in ("SimplePendulum.so", "Spring.so"))}
        assert sorted(Path(path).name for path in mapped) == ["SimplePendulum.so", "Spring.so"]  # once each
        result = master.run()
        assert result.stopped_at is None and len(master.units) == 39
    assert not any(path.exists() for path in extracted)


def test_runs_that_share_the_fmus_give_a_fresh_runs_numbers_and_unload_the_library_at_the_end(fmu_paths):
    """A planner runs a scene a thousand times: the runs share one extraction and one loaded library of
    each FMU (`SharedFmus`), which stays loaded between the runs and is unloaded when the share closes."""
    from harness.fmi.fmu_instance import SharedFmus
    system = load_system(PROJECT_ROOT / "scenes" / "coupled_pendulums.json")
    options = MasterOptions(stop=1.0, step=0.01, algorithm="gauss-seidel", extrapolation="linear")
    fresh = run_system(system, options)

    def mapped() -> set[str]:  # a library still mapped after its folder was removed is "... (deleted)"
        return {line.split()[5] for line in Path("/proc/self/maps").read_text().splitlines()
                if ("/SimplePendulum.so" in line or "/Spring.so" in line) and "/binaries/" in line}
    before = mapped()
    with SharedFmus() as fmus:
        for _ in range(4):  # two instances of SimplePendulum and one of Spring each time
            shared = run_system(system, options, fmus)
            for name in ("left.x", "right.x", "spring.Fa_x"):
                assert np.array_equal(shared[name], fresh[name]), name
            assert len(mapped() - before) == 2  # loaded between the runs, once each
    assert mapped() == before
