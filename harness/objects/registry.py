"""The registry of objects: every modelDescription/<id>.toml is an object (derived from its
energies), every modelDescription/<id>.xml a hand-written model (the massless Spring). The CMake
build globs the same folder, so a file dropped there is built and known everywhere."""
from __future__ import annotations

import tomllib
from pathlib import Path

PROJECT_ROOT = Path(__file__).resolve().parents[2]
OBJECTS_FOLDER = PROJECT_ROOT / "modelDescription"


def object_files(folder: Path = OBJECTS_FOLDER) -> list[Path]:
    return sorted(folder.glob("*.toml"))


def object_names(folder: Path = OBJECTS_FOLDER) -> tuple[str, ...]:
    return tuple(path.stem for path in object_files(folder))


def handwritten_names(folder: Path = OBJECTS_FOLDER) -> tuple[str, ...]:
    return tuple(sorted(path.stem for path in folder.glob("*.xml")))


def object_file(name: str, folder: Path = OBJECTS_FOLDER) -> Path:
    return folder / f"{name}.toml"


def constrained_names(folder: Path = OBJECTS_FOLDER) -> tuple[str, ...]:
    """The objects with a [constraints] table: they have events, and no partial derivatives, Taylor
    method or Stormer-Verlet yet."""
    return tuple(path.stem for path in object_files(folder) if _constraints(path))


def compliant_names(folder: Path = OBJECTS_FOLDER) -> tuple[str, ...]:
    """The objects with a compliant constraint (one with a stiffness)."""
    return tuple(path.stem for path in object_files(folder)
                 if any(isinstance(c, dict) and "stiffness" in c for c in _constraints(path).values()))


def _constraints(path: Path) -> dict:
    constraints = tomllib.loads(path.read_text()).get("constraints", {})
    return constraints if isinstance(constraints, dict) else {}
