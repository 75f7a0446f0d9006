"""The harness runs FMI 3.0 FMUs as it runs FMI 2.0 ones, and mixes both in one system.

The FMI 3.0 and 2.0 FMUs of an object share their C core, so every comparison here is exact: any
difference is the harness calling one version differently from the other."""
from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from harness.cosim.algorithm_registry import NAMES as ALGORITHM_NAMES
from harness.cosim.master import Master, MasterOptions
from harness.cosim.structure import Component, System
from harness.cosim.system import load_system
from harness.errors import HarnessError
from harness.fmi.fmu_instance import FmuInstance
from harness.fmi.methods import COUNTER_NAMES, METHODS
from harness.fmi.fmus import FMU_NAMES, PROJECT_ROOT, build_dir, locate_fmu
from harness.fmi.simulation import simulate

from conftest import ELEMENT_MOTION

SCENE = PROJECT_ROOT / "scenes" / "coupled_pendulums.json"


def fmi3(name: str) -> Path:
    return build_dir() / "fmus" / "fmi3" / f"{name}.fmu"


@pytest.mark.parametrize("name", FMU_NAMES)
def test_simulate_gives_the_fmi2_table_bit_for_bit(fmu_paths, name):
    start = ELEMENT_MOTION.get(name, {"solver": "rkf45"})  # adaptive: the counters differ by object
    two = simulate(fmu_paths[name], 1.0, 0.01, start_values=start)
    three = simulate(fmi3(name), 1.0, 0.01, start_values=start)
    assert three.columns == two.columns
    assert np.array_equal(three.values, two.values)


def test_a_discard_reports_the_same_time_and_message(fmu_paths):
    start = {"h": 0.001, "psi_dot": 0.0}  # the plane swing reaches the pole, where psi is undefined
    two = simulate(fmu_paths["SphericalPendulum"], 5.0, 0.01, start_values=start)
    three = simulate(fmi3("SphericalPendulum"), 5.0, 0.01, start_values=start)
    assert two.discarded_at is not None and three.discarded_at == two.discarded_at
    assert np.array_equal(three.values, two.values)
    assert three.messages[-1] == two.messages[-1].replace("fmi2DoStep", "fmi3DoStep")
    assert three.messages[-1].startswith("[Discard] fmi3DoStep:") and "singular" in three.messages[-1]


def test_fmu_state_serialized_and_restored_continues_the_run(fmu_paths):
    with FmuInstance(fmi3("DoublePendulum")) as instance:
        instance.initialize(0.0, solver="ab4")
        for k in range(10):
            assert instance.do_step(0.01 * k, 0.01) == 0
        data = instance.serialize(instance.get_state())
        for k in range(10, 20):
            instance.do_step(0.01 * k, 0.01)
        ahead = instance.get("phi1", "omega2", "n_rhs")
        state = instance.deserialize(data)
        instance.set_state(state)
        instance.free_state(state)
        for k in range(10, 20):
            instance.do_step(0.01 * k, 0.01)
        assert instance.get("phi1", "omega2", "n_rhs") == ahead
        assert isinstance(ahead[2], int) and ahead[2] > 0  # a UInt64 counter read as an integer


def test_values_are_checked_against_the_fmi3_types(fmu_paths):
    with FmuInstance(fmi3("SimplePendulum")) as instance:
        with pytest.raises(HarnessError, match=r"solver = 1.5 is not an integer \(Enumeration\)"):
            instance.set(solver=1.5)
        with pytest.raises(HarnessError, match="solver = 'rk5' is not one of euler, "):
            instance.set(solver="rk5")
        solver = instance.variables["solver"].declaredType
        ab6 = next(int(item.value) for item in solver.items if item.name == "ab6")
        instance.initialize(0.0, solver="ab6", h=0.004)
        assert instance.get("solver", "h") == [ab6, 0.004]
        with pytest.raises(HarnessError, match="has no variable 'nope'"):
            instance.get("nope")


def scene_with(system: System, versions: dict[str, str]) -> System:
    """The system with the named components' FMUs swapped for their FMI 3.0 builds."""
    return dataclasses.replace(system, components=[
        dataclasses.replace(c, fmu=fmi3(Path(c.fmu).stem)) if versions.get(c.name) == "3.0" else c
        for c in system.components])


@pytest.fixture(scope="module")
def coupled(fmu_paths):
    with load_system(SCENE) as system:
        yield system


@pytest.mark.parametrize("algorithm", ALGORITHM_NAMES)
@pytest.mark.parametrize("native", [True, False])
@pytest.mark.parametrize("mix", [{"left": "3.0", "right": "3.0"}, {"spring": "3.0"},
                                 {"spring": "3.0", "left": "3.0", "right": "3.0"}])
@pytest.mark.parametrize("extrapolation", ["hold", "linear"])
def test_a_mixed_system_runs_as_the_fmi2_system(coupled, algorithm, native, mix, extrapolation):
    """Held inputs give the FMI 2.0 numbers bit for bit. Linear ones reach an FMI 3.0 receiver as the values at
    the step's end it asks for (FMI 2.0: the derivative), whose slope may differ from FMI 2.0's in the last bit."""
    options = MasterOptions(stop=1.0, step=0.01, algorithm=algorithm, extrapolation=extrapolation)
    results = []
    for system in (coupled, scene_with(coupled, mix)):
        with Master(system, options) as master:
            master.use_native = native
            results.append(master.run())
    assert results[1].columns == results[0].columns and results[1].extrapolation == extrapolation
    if extrapolation == "hold":
        assert np.array_equal(results[1].values, results[0].values)
        assert np.array_equal(results[1].energy, results[0].energy)
    else:
        assert np.allclose(results[1].values, results[0].values, rtol=0, atol=1e-12)
        assert np.allclose(results[1].energy, results[0].energy, rtol=0, atol=1e-12)


def test_rollback_through_fmi3_states_matches_fmi2(fmu_paths, coupled):
    """Retry after a discard and step doubling save and restore every component's FMU state."""
    spherical = System("pole", [Component("bob", fmu_paths["SphericalPendulum"], {"h": 0.001, "psi_dot": 0.0})], [])
    cases = [(spherical, {"bob": "3.0"}, MasterOptions(stop=1.0, step=0.05, on_discard="retry", max_halvings=3)),
             (coupled, {"spring": "3.0", "left": "3.0", "right": "3.0"},
              MasterOptions(stop=1.0, step=0.1, extrapolation="hold", tolerance=1e-3))]
    for system, mix, options in cases:
        runs = []
        for version in (system, scene_with(system, mix)):
            with Master(version, options) as master:
                runs.append(master.run())
        assert runs[0].retries > 0 and runs[1].retries == runs[0].retries
        assert runs[1].stopped_at == runs[0].stopped_at and runs[1].macro_steps == runs[0].macro_steps
        assert np.array_equal(runs[1].values, runs[0].values)


def test_an_fmi3_spring_measures_its_bonds_as_the_fmi2_one(coupled):
    """The bonds' measure asks a spring for its directional derivatives (fmi3GetDirectionalDerivative)."""
    runs = []
    for system in (coupled, scene_with(coupled, {"spring": "3.0"})):
        with Master(system, MasterOptions(stop=1.0, step=0.01, extrapolation="hold", energy_correction=True)) as master:
            runs.append(master.run())
    assert abs(sum(runs[0].bond_energy.values())) > 1e-6
    assert runs[1].bond_energy == runs[0].bond_energy
    assert np.array_equal(runs[1].values, runs[0].values)


def test_an_fmi3_source_hands_over_its_output_derivatives(coupled):
    """Linear extrapolation needs input derivatives at the receiver only: a pendulum that only feeds
    the spring may be FMI 3.0 (fmi3GetOutputDerivatives gives the slopes)."""
    one_way = dataclasses.replace(coupled, connections=[c for c in coupled.connections if c.target != "left"])
    runs = []
    for native in (True, False):
        for system in (one_way, scene_with(one_way, {"left": "3.0"})):
            with Master(system, MasterOptions(stop=1.0, step=0.01)) as master:
                master.use_native = native
                runs.append(master.run())
    assert all(run.extrapolation == "linear" for run in runs)
    for run in runs[1:]:
        assert np.array_equal(run.values, runs[0].values)


@pytest.mark.parametrize("scene", ["coupled_pendulums", "spring_chain"])
def test_fmi3_receivers_take_linear_inputs_as_fmi2_ones(scene, fmu_paths):
    """FMI 3.0 has no input derivatives; its receivers ask for their inputs at each step's end (intermediate
    updates) instead. Linear extrapolation is then the default and couples as accurately as FMI 2.0's: over
    10 s the energy residual equals FMI 2.0's and is far below the held inputs' (coupled scene: 1.8e-3 J against
    1.08 J), in both loops; iterated steps, which interpolate the inputs the same way, run too."""
    with load_system(PROJECT_ROOT / "scenes" / f"{scene}.json") as system:
        everything = scene_with(system, {c.name: "3.0" for c in system.components})
        residual = {}
        for native in (True, False):
            for version, tried in (("2.0", system), ("3.0", everything)):
                for extrapolation in (None, "hold"):
                    with Master(tried, MasterOptions(stop=10.0, step=0.01, extrapolation=extrapolation)) as master:
                        master.use_native = native
                        run = master.run()
                    residual[native, version, run.extrapolation] = run.energy_residual
        for native in (True, False):
            two, three = residual[native, "2.0", "linear"], residual[native, "3.0", "linear"]
            assert abs(three - two) <= 1e-9 * two
            assert three < residual[native, "3.0", "hold"] / 50
        iterated = []
        for tried in (system, everything):
            with Master(tried, MasterOptions(stop=1.0, step=0.05, iterate_tol=1e-10)) as master:
                iterated.append(master.run())
        assert iterated[1].iterations == iterated[0].iterations > iterated[0].macro_steps
        assert np.allclose(iterated[1].values, iterated[0].values, rtol=0, atol=1e-11)


def test_an_fmi3_receiver_whose_inputs_are_not_asked_for_holds_them_and_refuses_linear(coupled, tmp_path):
    """An FMI 3.0 FMU whose inputs cannot be set in intermediate updates takes no line: held by default."""
    import re as regex
    text = zipfile_text(fmi3("Spring"))
    inputs = regex.findall(r'<Float64 name="[^"]+"[^>]*causality="input"[^>]*/>', text)
    assert inputs and all(' intermediateUpdate="true"' in v for v in inputs)
    plain = edited(tmp_path, "Spring", *[(v, v.replace(' intermediateUpdate="true"', "")) for v in inputs])
    system = dataclasses.replace(coupled, components=[dataclasses.replace(c, fmu=plain) if c.name == "spring" else c
                                                      for c in coupled.components])
    with Master(system, MasterOptions(stop=0.1, step=0.01)) as master:
        assert master.run().extrapolation == "hold"
    with pytest.raises(HarnessError, match=r"linear extrapolation hands over inputs on a line, which the FMI 3.0 "
                                           r"component\(s\) 'spring' cannot take \(their inputs are not set in "
                                           r"intermediate updates\)"):
        Master(system, MasterOptions(stop=0.1, step=0.01, extrapolation="linear"))
    with pytest.raises(HarnessError, match=r"iterated macro steps .* 'spring' cannot take"):
        Master(system, MasterOptions(stop=0.1, step=0.01, iterate_tol=1e-8))


def zipfile_text(path: Path) -> str:
    import zipfile
    with zipfile.ZipFile(path) as archive:
        return archive.read("modelDescription.xml").decode()


def harness(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "harness", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def test_the_command_line_names_fmi3_builds_and_mixes_them(fmu_paths, tmp_path):
    locate_fmu("fmi3/Spring")
    ran = harness("simulate", "fmi3/SimplePendulum", "--stop", "1", "--out", "three.csv", cwd=tmp_path)
    assert ran.returncode == 0, ran.stderr
    assert harness("simulate", "SimplePendulum", "--stop", "1", "--out", "two.csv", cwd=tmp_path).returncode == 0
    assert (tmp_path / "three.csv").read_text() == (tmp_path / "two.csv").read_text()
    wrong = harness("simulate", "fmi3/Pendulum", cwd=tmp_path)
    assert wrong.returncode == 2 and "unknown FMU 'fmi3/Pendulum'" in wrong.stderr and "fmi3/<name>" in wrong.stderr
    scene = SCENE.read_text().replace('"fmu": "Spring"', '"fmu": "fmi3/Spring"')
    (tmp_path / "mixed.json").write_text(scene)
    ran = harness("run", "mixed.json", "--stop", "1", "--out", "mixed.csv", cwd=tmp_path)
    assert ran.returncode == 0 and "linear extrapolation" in ran.stdout, ran.stderr
    two = harness("run", str(SCENE), "--stop", "1", "--out", "two.csv", cwd=tmp_path)
    assert two.returncode == 0
    mixed, plain = (np.loadtxt(tmp_path / name, delimiter=",", skiprows=1) for name in ("mixed.csv", "two.csv"))
    assert mixed.shape == plain.shape and np.allclose(mixed, plain, rtol=0, atol=1e-12)


def test_an_fmi3_fmu_without_this_platform_names_the_fmi3_folder(tmp_path):
    import zipfile
    source = fmi3("SimplePendulum")
    stripped = tmp_path / "stripped.fmu"
    with zipfile.ZipFile(source) as full, zipfile.ZipFile(stripped, "w") as out:
        for item in full.infolist():
            if not item.filename.startswith("binaries/x86_64-linux/"):
                out.writestr(item, full.read(item))
    with pytest.raises(HarnessError, match=r"no binary for this platform \(binaries/x86_64-linux/SimplePendulum.so "
                                           r"is missing\)"):
        FmuInstance(stripped)
    assert not list(Path(tmp_path).glob("fmu_*"))


def test_other_fmi_versions_are_refused_by_name(tmp_path):
    import zipfile
    fake = tmp_path / "old.fmu"
    with zipfile.ZipFile(fake, "w") as out:
        out.writestr("modelDescription.xml", '<fmiModelDescription fmiVersion="1.0" modelName="m" guid="g"/>')
    with pytest.raises(HarnessError, match="an FMI 1.0 FMU; this harness runs FMI 2.0 and 3.0 FMUs"):
        FmuInstance(fake)


@pytest.mark.parametrize("name", ["Spring", "SimplePendulum", "KapitzaPendulum"])
def test_validate_runs_every_check_on_fmi3_as_on_fmi2(fmu_paths, name):
    """The runtime checks, the object file's proofs and the physics checks, through FMI 3.0's calls."""
    from harness.fmi.validation import validate
    two, three = validate(fmu_paths[name]), validate(fmi3(name))
    assert [c.name for c in three] == [c.name for c in two] and len(three) > 5
    assert all(c.passed for c in three), [str(c) for c in three if not c.passed]


def test_an_ssp_may_carry_fmi3_fmus(fmu_paths, tmp_path):
    """The SSP form of the coupled scene with its pendulums' FMU swapped for the FMI 3.0 one: the
    parameter bindings reach the FMI 3.0 variables, and the run gives the FMI 2.0 numbers."""
    import shutil
    folder = tmp_path / "ssp"
    shutil.copytree(build_dir() / "scenes" / "coupled_pendulums", folder)
    options = MasterOptions(stop=1.0, step=0.01, extrapolation="hold")
    with load_system(folder) as system:
        with Master(system, options) as master:
            two = master.run()
    shutil.copy(fmi3("SimplePendulum"), folder / "resources" / "SimplePendulum.fmu")
    with load_system(folder) as system:
        with Master(system, options) as master:
            assert {unit.name: unit.instance.version for unit in master.units} == \
                {"spring": "2.0", "left": "3.0", "right": "3.0"}
            three = master.run()
    assert np.array_equal(three.values, two.values) and np.ptp(two["left.x"]) > 0.1


def edited(tmp_path: Path, name: str, *replacements: tuple[str, str], source: Path | None = None) -> Path:
    """A copy of the FMI 3.0 FMU `name` with its model description edited."""
    import zipfile
    target = tmp_path / f"{name}-{len(list(tmp_path.glob('*.fmu')))}.fmu"
    with zipfile.ZipFile(source or fmi3(name)) as original, zipfile.ZipFile(target, "w") as copy:
        for item in original.infolist():
            data = original.read(item)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                for old, new in replacements:
                    assert old in text, old
                    text = text.replace(old, new)
                data = text.encode()
            copy.writestr(item, data)
    return target


def one_line(ran: subprocess.CompletedProcess, *words: str) -> None:
    assert ran.returncode == 2, (ran.returncode, ran.stderr)
    assert ran.stderr.count("\n") == 1 and ran.stderr.startswith("harness: error: "), ran.stderr
    for word in words:
        assert word in ran.stderr, (word, ran.stderr)


def mixed_scene(tmp_path: Path, left: Path) -> Path:
    scene = json.loads(SCENE.read_text())
    scene["components"]["left"]["fmu"] = str(left)
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    return path


def test_outputs_of_types_the_harness_does_not_record_are_refused_by_name(fmu_paths, tmp_path):
    single = edited(tmp_path, "SimplePendulum", ('<Float64 name="E" ', '<Float32 name="E" '))
    one_line(harness("simulate", str(single), "--out", "x.csv", cwd=tmp_path),
             "output 'E' is a Float32; the harness records Float64 and integer outputs")
    flags = edited(tmp_path, "SimplePendulum", *[(f'<UInt64 name="{n}" ', f'<Boolean name="{n}" ')
                                                 for n in COUNTER_NAMES])
    for extra in ([], ["--on-discard", "retry"]):  # the C loop and the Python loop
        one_line(harness("run", str(mixed_scene(tmp_path, flags)), "--stop", "0.1", "--out", "y.csv", *extra,
                         cwd=tmp_path), "output 'n_rhs' is a Boolean")
    assert not (tmp_path / "x.csv").exists() and not (tmp_path / "y.csv").exists()


def test_each_value_goes_through_the_function_of_its_declared_type(fmu_paths, tmp_path):
    """A parameter declared Float32 is set with fmi3SetFloat32 (which this FMU, whose L is a Float64,
    refuses by name), never as 4 bytes handed to fmi3SetFloat64."""
    single = edited(tmp_path, "SimplePendulum", ('<Float64 name="L" ', '<Float32 name="L" '))
    one_line(harness("simulate", str(single), "--set", "L=2", "--out", "x.csv", cwd=tmp_path), "fmi3SetFloat32")


def test_integers_are_read_exactly_and_checked_against_their_type(fmu_paths):
    with FmuInstance(fmi3("SimplePendulum")) as instance:
        with pytest.raises(HarnessError, match=r"solver = '5.0000000000000001' is not an integer \(Enumeration\)"):
            instance.set(solver="5.0000000000000001")
        with pytest.raises(HarnessError, match=r"solver = '9223372036854775808' is outside the range of an FMI 3.0 "
                                               r"Enumeration \[-9223372036854775808, 9223372036854775807\]"):
            instance.set(solver="9223372036854775808")
        assert instance.set(solver="9223372036854775807") == 3  # in Int64's range: the FMU's own check refuses it
        assert instance.last_message().startswith("fmi3SetInt64: variable solver")
        assert f"out of its allowed range [1, {len(METHODS)}]" in instance.last_message()
        assert instance.set(solver="4e0") == 0
    with FmuInstance(fmu_paths["SimplePendulum"]) as instance:
        with pytest.raises(HarnessError, match=r"solver = 2147483648 is outside the range of an FMI 2.0 Enumeration"):
            instance.set(solver=2**31)
        # Integer and Enumeration travel through fmi2GetInteger alike: one reader for both
        instance.initialize(0.0, solver="ab4")
        reader = instance.integer_reader(["solver", "n_rhs"])
        values = np.zeros(2, dtype=reader.dtype)
        assert reader.read(values.ctypes.data) == 0 and reader.dtype == np.intc
        assert values[0] == instance.get("solver")[0] and values[1] == instance.get("n_rhs")[0]


def test_a_failed_integer_read_names_its_component_in_both_loops(fmu_paths, tmp_path):
    """The counters declared Int32 (they are UInt64 in the binary): the FMU refuses fmi3GetInt32 at the
    first row, and the C loop blames that component as the Python loop does."""
    wrong = edited(tmp_path, "SimplePendulum", *[(f'<UInt64 name="{n}" ', f'<Int32 name="{n}" ')
                                                 for n in COUNTER_NAMES])
    for extra in ([], ["--on-discard", "retry"]):
        one_line(harness("run", str(mixed_scene(tmp_path, wrong)), "--stop", "0.1", "--out", "y.csv", *extra,
                         cwd=tmp_path), "left: ", "fmi3GetInt32")


def test_rollback_needs_components_that_save_their_state(fmu_paths, tmp_path):
    stateless = edited(tmp_path, "SimplePendulum", ('canGetAndSetFMUState="true" canSerializeFMUState="true"\n',
                                                    'canGetAndSetFMUState="false" canSerializeFMUState="false"\n'))
    scene = mixed_scene(tmp_path, stateless)
    one_line(harness("run", str(scene), "--stop", "0.1", "--on-discard", "retry", "--out", "y.csv", cwd=tmp_path),
             "--on-discard retry roll back through FMU states, which left cannot save")
    assert harness("run", str(scene), "--stop", "0.1", "--out", "y.csv", cwd=tmp_path).returncode == 0


def test_names_that_only_look_like_project_fmus_are_refused(fmu_paths, tmp_path):
    for name in ("/SimplePendulum", "fmi3//SimplePendulum", "FMI3/SimplePendulum", "fmi3/"):
        one_line(harness("simulate", name, "--out", "x.csv", cwd=tmp_path), f"unknown FMU {name!r}")


def test_the_coupling_studies_plan_with_fmi3_receivers_as_with_fmi2_ones(fmu_paths, tmp_path):
    """The studies compare linear extrapolation, which FMI 3.0 receivers take through intermediate updates: the
    plan for the coupled scene with an FMI 3.0 spring is the FMI 2.0 scene's, figure for figure."""
    scene = SCENE.read_text().replace('"fmu": "Spring"', '"fmu": "fmi3/Spring"')
    (tmp_path / "mixed.json").write_text(scene)
    three = harness("plan", "mixed.json", "--tolerance", "1e-3", cwd=tmp_path)
    two = harness("plan", str(SCENE), "--tolerance", "1e-3", cwd=tmp_path)
    assert three.returncode == two.returncode == 0, three.stderr
    assert three.stdout == two.stdout and "total cost" in three.stdout
