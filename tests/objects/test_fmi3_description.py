"""The FMI 3.0 model description of every object: valid against the standard's schema and the same
variables as the FMI 2.0 FMU (names, value references, causality, ranges, units). Its dependency
lists are measured against the binaries in tests/objects/test_dependencies.py."""
from __future__ import annotations

import os
from pathlib import Path

import fmpy
import pytest
from fmpy import read_model_description
from lxml import etree

from harness.objects.model_description_fmi3 import model_description_fmi3
from harness.objects.registry import object_names

SCHEMA = Path(os.path.dirname(fmpy.__file__)) / "schema" / "fmi3" / "fmi3ModelDescription.xsd"


@pytest.fixture(scope="module")
def descriptions(tmp_path_factory, derivation) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("fmi3")
    paths = {}
    for name in object_names():
        path = folder / f"{name}.xml"
        path.write_text(model_description_fmi3(derivation(name)))
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
