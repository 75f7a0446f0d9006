"""The FMUs of a Dask sweep travel with it: a worker needs no view of the project's files.

Before the items go out, every FMU file an item names (a str or Path ending in .fmu that names a
file, anywhere in the item's tuples, lists, dicts, sets and dataclasses) is read, together with its
FMI 3.0 build beside it (fmi3/<name>.fmu) when there is one, and handed to the scheduler as a
worker plugin named after the files' content (`FmuBundle`). The scheduler gives each such plugin
to every worker once, to the workers there are and to any that join later, and the worker writes
the files into its own local directory (harness-fmus/<key>/), which goes when the worker closes.
The scheduler holds the plugins, so a second sweep with the same FMUs sends nothing to the workers,
and a rebuilt FMU (other content) is a new plugin. The scheduler keeps each version it was given
(an FMU is under a megabyte) for the workers that join later, as it keeps Dask's uploaded files.

In the items each FMU path becomes a `ShippedFmu` (the bundle's key, the file's name and the path
it stands for). On the worker, `LocalFmus` gives the item function the path of the local copy, of
the type the item had (str or Path), and gives back the path it stood for in the result and in a
HarnessError's message, so that results and messages read as in a local sweep.
"""
from __future__ import annotations

import contextlib
import copy
import dataclasses
import hashlib
import os
import shutil
import tempfile
from pathlib import Path, PurePath
from typing import Any, Callable

from distributed.diagnostics.plugin import WorkerPlugin

from harness.errors import HarnessError

FOLDER = "harness-fmus"  # in a worker's local directory: one folder per bundle
TOPIC = "harness-fmus"  # the scheduler's event log: one event per bundle a worker was given
_ATOMS = (str, bytes, int, float, complex, bool, type(None))


@dataclasses.dataclass(frozen=True)
class ShippedFmu:
    """An FMU file of an item on its way to a worker."""
    key: str  # the bundle: <name>-<16 hex digits of the content's SHA-256>
    name: str  # the file's name in the bundle
    original: str  # the path in the item (for results and messages)
    as_path: bool  # it was a Path (else a str)


class FmuBundle(WorkerPlugin):
    """An FMU file (and its FMI 3.0 build) for the workers' local directories; registered under
    its content's name, a second registration is a no-op (`idempotent`)."""
    idempotent = True

    def __init__(self, key: str, files: dict[str, bytes]):
        self.key, self.files = key, files
        self.sizes = {name: len(data) for name, data in files.items()}

    def setup(self, worker) -> None:
        folder = Path(worker.local_directory) / FOLDER
        target = folder / self.key
        stored = not target.is_dir()
        if stored:
            folder.mkdir(exist_ok=True)
            # written aside and renamed: a task never sees half a file
            partial = Path(tempfile.mkdtemp(prefix=f".{self.key}.", dir=folder))
            try:
                for name, data in self.files.items():
                    (partial / name).parent.mkdir(parents=True, exist_ok=True)
                    (partial / name).write_bytes(data)
                try:
                    os.rename(partial, target)
                except OSError:
                    if not target.is_dir():  # else another registration of it got there first
                        raise
            finally:
                shutil.rmtree(partial, ignore_errors=True)
        self.files = {}  # the copy on disk is what the tasks read
        worker.log_event(TOPIC, {"worker": worker.address, "key": self.key, "files": self.sizes, "stored": stored})


def plugin_name(key: str) -> str:
    return f"harness-fmu-{key}"


def ship(client, items: list, scheduler: str) -> list:
    """The items with their FMU files as ShippedFmu, once the scheduler holds every bundle."""
    bundles: dict[str, tuple[str, dict[str, bytes]]] = {}  # path -> (key, files)

    def mark(value):
        if isinstance(value, (str, PurePath)) and str(value)[-4:].lower() == ".fmu" and os.path.isfile(value):
            path = os.fspath(value)
            if path not in bundles:
                bundles[path] = _bundle(Path(path))
            return ShippedFmu(bundles[path][0], Path(path).name, path, isinstance(value, PurePath))
        return value
    shipped = [transform(item, mark) for item in items]
    for key, files in dict(bundles.values()).items():
        try:
            client.register_plugin(FmuBundle(key, files), name=plugin_name(key))
        except Exception as error:  # a worker that cannot write its local directory, or lacks the harness
            with contextlib.suppress(Exception):  # not kept as given: the next sweep tries again
                client.unregister_worker_plugin(plugin_name(key))
            detail = (str(error).strip().splitlines() or [type(error).__name__])[0]
            raise HarnessError(f"--scheduler {scheduler}: cannot give the workers {next(iter(files))} "
                               f"({type(error).__name__}: {detail})") from None
    return shipped


def _bundle(fmu: Path) -> tuple[str, dict[str, bytes]]:
    from harness.fmi.events import fmi3_counterpart
    try:
        files = {fmu.name: fmu.read_bytes()}
        counterpart = fmi3_counterpart(fmu)
        if counterpart is not None:
            files[f"{counterpart.parent.name}/{counterpart.name}"] = counterpart.read_bytes()
    except OSError as error:
        raise HarnessError(f"{error.filename}: cannot read the FMU ({error.strerror})") from None
    digest = hashlib.sha256()
    for name, data in files.items():
        digest.update(f"{name}\0{len(data)}\0".encode())
        digest.update(data)
    return f"{fmu.stem}-{digest.hexdigest()[:16]}", files


class LocalFmus:
    """An item function as it runs on a worker: its item's ShippedFmu become the paths of the
    worker's copies, and the paths of those copies (and of the files beside them in the bundle) in
    its result and in its HarnessError's message become the paths the item had."""

    def __init__(self, function: Callable):
        self.function = function

    def __call__(self, item):
        from distributed import get_worker
        worker = get_worker()
        folder = Path(worker.local_directory) / FOLDER
        originals = Originals()

        def local(value):
            if isinstance(value, ShippedFmu):
                path = folder / value.key / value.name
                if not path.is_file():
                    raise HarnessError(f"{value.original}: the worker {worker.address} was not given it")
                originals.add(str(path), value.original)
                return path if value.as_path else str(path)
            return value
        item = transform(item, local)
        try:
            result = self.function(item)
        except HarnessError as error:
            error.args = tuple(originals.text(a) if isinstance(a, str) else a for a in error.args)
            raise

        def original(value):
            if isinstance(value, (str, PurePath)):
                path = originals.path(os.fspath(value))
                if path is not None:
                    return Path(path) if isinstance(value, PurePath) else path
            return value
        return transform(result, original)


class Originals:
    """The paths of a worker's copies against the paths the item had: the file itself, and any file
    beside it in its bundle (the FMI 3.0 build, fmi3/<name>) under the original's folder."""

    def __init__(self):
        self.files: dict[str, str] = {}  # local path -> original path
        self.folders: dict[str, str] = {}  # local bundle folder/ -> the original's folder/ ("" for none)

    def add(self, local: str, original: str) -> None:
        self.files[local] = original
        parent = os.path.dirname(original)
        self.folders[os.path.dirname(local) + os.sep] = parent + os.sep if parent else ""

    def path(self, local: str) -> str | None:
        if local in self.files:
            return self.files[local]
        for folder, parent in self.folders.items():
            if local.startswith(folder):
                return parent + local[len(folder):]
        return None

    def text(self, text: str) -> str:
        for local, original in self.files.items():
            text = text.replace(local, original)
        for folder, parent in self.folders.items():
            text = text.replace(folder, parent)
        return text


def transform(value: Any, leaf: Callable[[Any], Any], _memo: dict | None = None) -> Any:
    """value with leaf(x) for each part x that leaf replaces, through tuples (named ones too), lists,
    dicts (keys and values), sets and dataclass instances; what changes is copied, the rest is shared,
    value itself is returned when nothing changed."""
    memo = {} if _memo is None else _memo
    if id(value) in memo:
        return memo[id(value)]
    replaced = leaf(value)
    if replaced is not value or isinstance(value, _ATOMS):
        return replaced
    memo[id(value)] = value  # a cycle keeps its reference
    new = value
    if isinstance(value, (tuple, frozenset)):
        parts = [transform(v, leaf, memo) for v in value]
        if any(a is not b for a, b in zip(parts, value)):
            new = value._make(parts) if hasattr(value, "_make") else type(value)(parts)
    elif isinstance(value, (list, set)):
        parts = [transform(v, leaf, memo) for v in value]
        if any(a is not b for a, b in zip(parts, value)):
            new = copy.copy(value)  # a subclass stays one
            new.clear()
            if isinstance(new, list):
                new.extend(parts)
            else:
                new.update(parts)
    elif isinstance(value, dict):
        pairs = [(transform(k, leaf, memo), transform(v, leaf, memo)) for k, v in value.items()]
        if any(a is not k or b is not v for (a, b), (k, v) in zip(pairs, value.items())):
            new = copy.copy(value)  # a defaultdict keeps its factory
            new.clear()
            new.update(pairs)
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        changed = {}
        for field in dataclasses.fields(value):
            part = getattr(value, field.name, dataclasses.MISSING)
            if part is not dataclasses.MISSING:
                result = transform(part, leaf, memo)
                if result is not part:
                    changed[field.name] = result
        if changed:
            new = copy.copy(value)  # not dataclasses.replace: no __post_init__ again (a System's checks)
            for name, part in changed.items():
                object.__setattr__(new, name, part)
    memo[id(value)] = new
    return new
