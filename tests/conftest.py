from __future__ import annotations

from pathlib import Path

import pytest
from fmpy import extract

from harness.fmi.fmu_instance import FmuInstance
from harness.fmi.fmus import FMU_NAMES, build_dir, build_fmus

PENDULUMS = ("SimplePendulum", "DoublePendulum", "SpringPendulum")


@pytest.fixture(scope="session")
def fmu_paths() -> dict[str, Path]:
    build_fmus()
    return {name: build_dir() / "fmus" / f"{name}.fmu" for name in FMU_NAMES}


@pytest.fixture(scope="session")
def unzipped(fmu_paths, tmp_path_factory) -> dict[str, str]:
    """Each FMU extracted once per session."""
    return {name: extract(str(path), str(tmp_path_factory.mktemp(name))) for name, path in fmu_paths.items()}


@pytest.fixture
def open_fmu(fmu_paths, unzipped):
    """open_fmu(name, kind="CS") -> FmuInstance, freed after the test."""
    instances = []

    def factory(name: str, kind: str = "CS", **kwargs) -> FmuInstance:
        instance = FmuInstance(fmu_paths[name], kind=kind, unzipdir=unzipped[name], name=f"{name}{len(instances)}",
                               **kwargs)
        instances.append(instance)
        return instance

    yield factory
    for instance in instances:
        instance.free()
