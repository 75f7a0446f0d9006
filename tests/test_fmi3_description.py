"""The FMI 3.0 model description of every object: valid against the standard's schema, the same
variables as the FMI 2.0 FMU (names, value references, causality, ranges, units), and dependencies
that the FMI 2.0 binary confirms: every output or derivative that moves when one known (a state, an
input, time) is nudged lists that known."""
from __future__ import annotations

import ctypes
import os
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Model
from lxml import etree

from harness.objects.derivation import derive
from harness.objects.model_description_fmi3 import model_description_fmi3
from harness.objects.object_file import read_object_file
from harness.objects.registry import object_file, object_names

SCHEMA = Path(os.path.dirname(fmpy.__file__)) / "schema" / "fmi3" / "fmi3ModelDescription.xsd"


@pytest.fixture(scope="module")
def descriptions(tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("fmi3")
    paths = {}
    for name in object_names():
        path = folder / f"{name}.xml"
        path.write_text(model_description_fmi3(derive(read_object_file(object_file(name)))))
        paths[name] = path
    return paths


@pytest.mark.parametrize("name", object_names())
def test_valid_against_the_fmi3_schema(descriptions, name):
    schema = etree.XMLSchema(file=str(SCHEMA))
    document = etree.parse(str(descriptions[name]))
    assert schema.validate(document), schema.error_log


@pytest.mark.parametrize("name", object_names())
def test_the_same_variables_as_fmi2(descriptions, fmu_paths, name):
    fmi2 = {v.name: v for v in read_model_description(str(fmu_paths[name])).modelVariables}
    fmi3 = {v.name: v for v in read_model_description(str(descriptions[name])).modelVariables}
    assert fmi3.pop("time").causality == "independent"
    assert set(fmi3) == set(fmi2)
    for variable_name, new in fmi3.items():
        old = fmi2[variable_name]
        assert (new.valueReference, new.causality, new.variability) == \
            (old.valueReference, old.causality, old.variability), variable_name
        assert (new.unit, new.min, new.max) == (old.unit, old.min, old.max), variable_name
        assert (new.start is None) == (old.start is None), variable_name
        if old.start is not None and old.type == "Real":
            assert float(new.start) == float(old.start), variable_name
        # the Integer outputs (the counters) count, the Integer parameter (taylor_order) is an Int64 as the
        # enumerations are
        integer = "UInt64" if old.causality == "output" else "Int64"
        expected = {"Real": "Float64", "Integer": integer, "Enumeration": "Enumeration"}[old.type]
        assert new.type == expected, variable_name


def pointer(array: np.ndarray):
    return array.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def dependency_lists(path: Path) -> dict[int, set[int]]:
    root = etree.parse(str(path)).getroot()
    found = {}
    for element in root.find("ModelStructure"):
        if element.tag in ("Output", "ContinuousStateDerivative") and element.get("dependencies") is not None:
            found[int(element.get("valueReference"))] = {int(r) for r in element.get("dependencies").split()}
    return found


@pytest.mark.parametrize("name", object_names())
def test_the_dependencies_cover_what_the_binary_shows(descriptions, fmu_paths, unzipped, name):
    """Model Exchange at a generic point (states, inputs and time away from special values): nudging
    one known at a time, each unknown that changes must list it."""
    md = read_model_description(str(fmu_paths[name]))
    listed = dependency_lists(descriptions[name])
    variables = {v.valueReference: v for v in md.modelVariables}
    n = md.numberOfContinuousStates
    states = [md.derivatives[k].variable.derivative.valueReference for k in range(n)]
    derivatives = [md.derivatives[k].variable.valueReference for k in range(n)]
    inputs = [vr for vr, v in variables.items() if v.causality == "input"]
    reals = [vr for vr, v in variables.items() if v.causality == "output" and v.type == "Real"]
    time_vr = max(variables) + 1
    model = FMU2Model(guid=md.guid, unzipDirectory=unzipped[name], modelIdentifier=md.modelExchange.modelIdentifier,
                      instanceName="deps")
    model.instantiate()
    try:
        model.setupExperiment(startTime=0.3)
        model.enterInitializationMode()
        model.exitInitializationMode()
        model.enterContinuousTimeMode()
        rng = np.random.default_rng(3)
        buffer, rates = np.zeros(n), np.zeros(n)
        model.getContinuousStates(pointer(buffer), n)
        x0 = buffer + rng.uniform(0.1, 0.3, n)
        u0 = rng.uniform(0.5, 1.5, len(inputs))

        def evaluate(x, u, t) -> dict[int, float]:
            model.setTime(t)
            buffer[:] = x
            model.setContinuousStates(pointer(buffer), n)
            if inputs:
                model.setReal(inputs, list(u))
            model.getDerivatives(pointer(rates), n)
            values = dict(zip(derivatives, rates.tolist()))
            values.update(zip(reals, model.getReal(reals)))
            return values
        base = evaluate(x0, u0, 0.3)
        nudges = [(vr, k, None) for k, vr in enumerate(states)] + [(vr, None, k) for k, vr in enumerate(inputs)]
        nudges.append((time_vr, None, None))
        observed = 0
        for known, state_k, input_k in nudges:
            x, u, t = x0.copy(), u0.copy(), 0.3
            if state_k is not None:
                x[state_k] += 1e-4
            elif input_k is not None:
                u[input_k] += 1e-2
            else:
                t += 1e-4
            moved = evaluate(x, u, t)
            for unknown, value in moved.items():
                if unknown in listed and abs(value - base[unknown]) > 1e-12 * max(1.0, abs(base[unknown])):
                    observed += 1
                    assert known in listed[unknown], (variables[unknown].name, "moves with",
                                                      variables.get(known).name if known in variables else "time")
        assert observed >= len(states)  # the nudges reached the model at all
    finally:
        model.terminate()
        model.freeInstance()
