"""Loading a coupled system from its file: the harness's own scene file (harness/cosim/scene_file.py,
JSON) or SSP 1.0 (harness/cosim/ssp_file.py: an `.ssp` archive, a folder holding
`SystemStructure.ssd`, or an `.ssd` file next to its resources). The system itself is
harness/cosim/structure.py."""
from __future__ import annotations

from pathlib import Path

from harness.cosim.scene_file import load_scene_file
from harness.cosim.ssp_file import load_ssp
from harness.cosim.structure import Component, Connection, System, component_name_problem
from harness.errors import HarnessError

__all__ = ["Component", "Connection", "System", "component_files", "component_name_problem", "load_system",
           "system_inputs"]


def load_system(path: str | Path) -> System:
    """A scene file (.json) or an SSP (.ssp archive, .ssd file, folder with SystemStructure.ssd).
    Use it as a context manager (or call close()) to remove what an .ssp archive put on disk."""
    path = Path(path)
    if not path.exists():
        raise HarnessError(f"{path}: no such file or folder")
    if not (path.is_file() or path.is_dir()):  # reading a pipe or a device could block or never end
        raise HarnessError(f"{path}: is not a regular file or a folder")
    system = load_scene_file(path) if path.suffix == ".json" else load_ssp(path)
    try:  # checked as the file is read: a run or an export refuses the bonds the energy coupling would
        system.check_bonds()
    except BaseException:
        system.close()
        raise
    return system


def system_inputs(system: str | Path) -> tuple[str | Path, ...]:
    """What a system's command reads: the file or folder, and for an .ssd file the folder of its
    parameter files and FMUs."""
    path = Path(system)
    return (system, path.parent) if path.suffix.lower() == ".ssd" else (system,)


def component_files(system_file: str | Path, system: System) -> tuple[str | Path, ...]:
    """What a loaded system reads: its own inputs and the FMU of every component, which an output
    must not replace either."""
    return (*system_inputs(system_file), *(component.fmu for component in system.components))
