"""Which modules the given modules of this source tree need but this Python cannot import.

    python tools/generator_imports.py harness.objects.generate harness.objects.model_description_fmi3

Imports the modules from the source tree (not an installed copy) and prints the top-level name of
every module that is missing, one a line; exit status 1 when any is, 0 when none. CMake runs it at
configure time with the Python that will derive the objects, so that the check follows the
generator's own imports instead of a list kept beside them. A missing module is replaced by a stand-in
and the import tried again, so that all missing modules are named at once, not only the first.
Standard library only: it has to run in a Python that lacks the rest.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import signal
import subprocess
import sys
from pathlib import Path

SOURCE_ROOT = Path(__file__).resolve().parent.parent
MARK = "missing module: "  # how the child reports a name: what an imported module prints is no name


class _StandIn:
    """Whatever a module body does with a missing module's names at import time: call, index, iterate,
    subclass, decorate."""

    def __init__(self, *args, **kwargs):
        pass

    def __call__(self, *args, **kwargs):
        return _StandIn()

    def __getattr__(self, name):
        # no private or protocol names: ctypes asks an argument for `_as_parameter_` and, given a stand-in,
        # asks that one again, until the process dies of the recursion
        if name.startswith("_"):
            raise AttributeError(name)
        return _StandIn()

    def __getitem__(self, key):
        return _StandIn()

    def __iter__(self):
        return iter(())

    def __mro_entries__(self, bases):
        return (object,)


class _StandInModule(type(sys)):
    def __getattr__(self, name):
        if name.startswith("__") and name.endswith("__"):
            raise AttributeError(name)
        return _StandIn()


class _StandInFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Supplies a stand-in for the named top-level modules and everything under them."""

    def __init__(self):
        self.names: set[str] = set()

    def find_spec(self, fullname, path=None, target=None):
        if fullname.partition(".")[0] in self.names:
            return importlib.machinery.ModuleSpec(fullname, self, is_package=True)
        return None

    def create_module(self, spec):
        module = _StandInModule(spec.name)
        module.__path__ = []
        return module

    def exec_module(self, module):
        pass


def missing_modules(modules: list[str], found=lambda name: None) -> list[str]:
    """The missing top-level names; `found` is called with each as it is found."""
    sys.path.insert(0, str(SOURCE_ROOT))
    finder = _StandInFinder()
    sys.meta_path.insert(0, finder)
    while True:
        try:
            for module in modules:
                importlib.import_module(module)
            return sorted(finder.names)
        except ModuleNotFoundError as error:
            name = (error.name or "").partition(".")[0]
            if not name or name in finder.names:
                raise
            finder.names.add(name)
            found(name)
            for loaded in [m for m in sys.modules if m.partition(".")[0] in {"harness", name}]:
                del sys.modules[loaded]
        except Exception:  # a stand-in used in a way it cannot mimic: the names found so far are the answer
            if finder.names:
                return sorted(finder.names)
            raise


def check(modules: list[str]) -> int:
    """The check itself: prints each missing name as it is found, so that a crash keeps them."""
    names: list[str] = []

    def found(name: str) -> None:
        names.append(name)
        print(f"{MARK}{name}", flush=True)

    try:
        missing_modules(modules, found)
    except Exception as error:  # noqa: BLE001 (a broken installation raises anything; CMake shows this line)
        if names:
            return 1
        print(f"importing {', '.join(modules)} failed: {type(error).__name__}: {error}")
        return 2
    return 1 if names else 0


def main(argv: list[str]) -> int:
    """Runs the check in a child process: an extension module that crashes on a stand-in (a C library handed
    one) ends the child, and the names it found before are the answer all the same."""
    if not argv:
        print("usage: generator_imports.py MODULE...", file=sys.stderr)
        return 2
    if argv[0] == "--child":
        return check(argv[1:])
    child = subprocess.run([sys.executable, __file__, "--child", *argv], stdout=subprocess.PIPE, text=True)
    if child.returncode == 2:
        sys.stdout.write(child.stdout)
        return 2
    names = sorted(line[len(MARK):] for line in child.stdout.split("\n") if line.startswith(MARK))
    if names:
        print("\n".join(names))
        return 1
    if child.returncode == 0:
        return 0
    print(f"importing {', '.join(argv)} ended the process ({signal_name(-child.returncode)})")
    return 2


def signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return f"status {-number}"


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
