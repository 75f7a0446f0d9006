#!/usr/bin/env python3
"""From object file to proven FMU: seconds to derive and build each object (`harness derive`, the
same compiler flags as the CMake build) and to validate it (`harness validate`), with the largest
deviation of its accelerations from the independent numeric route. One object after another in
this process, so the figures share the machine's state."""
from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from harness.fmi.validation import validate  # noqa: E402
from harness.objects.build import derive_fmu  # noqa: E402
from harness.objects.object_file import read_object_file  # noqa: E402
from harness.objects.registry import object_files  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--objects", nargs="+", metavar="NAME", help="only these objects (default: every one)")
    args = parser.parse_args()
    paths = [p for p in object_files() if args.objects is None or p.stem in args.objects]
    if args.objects and len(paths) != len(set(args.objects)):
        parser.error(f"unknown objects: {sorted(set(args.objects) - {p.stem for p in paths})}")
    print(f"{'object':22s} {'coords':>6s} {'derive+build s':>15s} {'validate s':>11s} {'checks':>8s} "
          f"{'numeric route':>14s}")
    with tempfile.TemporaryDirectory(prefix="derive-times-") as scratch:
        for path in paths:
            start = time.perf_counter()
            fmu = derive_fmu(path, scratch).path
            built = time.perf_counter()
            checks = validate(fmu)
            validated = time.perf_counter()
            route = next((c.detail for c in checks if "numeric route" in c.name), "")
            deviation = re.search(r"accelerations ([0-9.e+-]+)", route)
            passed = sum(c.passed for c in checks)
            print(f"{path.stem:22s} {len(read_object_file(path).coordinates):6d} {built - start:15.1f} "
                  f"{validated - built:11.1f} {passed:4d}/{len(checks):<3d} "
                  f"{deviation.group(1) if deviation else '-':>14s}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
