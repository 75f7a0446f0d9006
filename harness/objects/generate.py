"""An object file to the files the build compiles: physics.h, physics.c, modelDescription.xml (FMI
2.0), fmi3/modelDescription.xml (FMI 3.0) and the equations section of the documentation.

    python -m harness.objects.generate OBJECT.toml --out DIR    writes DIR/<identifier>/...
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from harness.objects.c_code import generate_c
from harness.objects.derivation import GENERATION_SECONDS, Derivation, derive, time_limit
from harness.objects.documentation import equations_html
from harness.objects.model_description import model_description
from harness.objects.model_description_fmi3 import model_description_fmi3
from harness.objects.object_file import ObjectFileError, read_object_file


@dataclass
class GeneratedObject:
    identifier: str
    folder: Path
    derivation: Derivation


def _write(path: Path, text: str) -> None:
    # Always written, also when unchanged: make compares each output with the object file and the
    # generator, and an output left older than them would be regenerated in every target that uses it.
    path.write_text(text)


def no_progress(stage: str) -> None:
    pass


def generate(object_file: str | Path, out: str | Path,
             progress: Callable[[str], None] = no_progress) -> GeneratedObject:
    """`progress` is told each stage as it begins."""
    spec = read_object_file(object_file)
    with time_limit(GENERATION_SECONDS, f"{spec.path}: deriving and generating the equations took over "
                                        f"{GENERATION_SECONDS:.0f} s; an expression expands into too many terms "
                                        "(a high power of a sum, say): write the energies more simply"):
        return _generate(spec, out, progress)


def _generate(spec, out: str | Path, progress: Callable[[str], None]) -> GeneratedObject:
    progress("deriving Lagrange's equations")
    derivation = derive(spec)
    progress("generating the C code")
    code = generate_c(derivation)
    xml = model_description(derivation)
    folder = Path(out) / spec.identifier
    folder.mkdir(parents=True, exist_ok=True)
    _write(folder / "physics.h", code.header)
    _write(folder / "physics.c", code.source)
    _write(folder / "modelDescription.xml", xml)
    (folder / "fmi3").mkdir(exist_ok=True)
    _write(folder / "fmi3" / "modelDescription.xml", model_description_fmi3(derivation, xml))
    progress("simplifying the equations for the documentation (at most a minute)")
    _write(folder / "equations.html", equations_html(derivation))
    return GeneratedObject(spec.identifier, folder, derivation)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Generate an object's C physics and model description.")
    parser.add_argument("objects", nargs="+", type=Path)
    parser.add_argument("--out", required=True, type=Path)
    parser.add_argument("--identifier-is-file-name", action="store_true",
                        help="refuse an object whose identifier differs from its file name (the registry's rule)")
    args = parser.parse_args(argv)
    try:
        for path in args.objects:
            if args.identifier_is_file_name:
                spec = read_object_file(path)
                if spec.identifier != path.stem:
                    raise ObjectFileError(f"{path}: identifier: {spec.identifier!r} must equal the file name "
                                          f"{path.stem!r} in the objects folder")
            generate(path, args.out)
    except ObjectFileError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
