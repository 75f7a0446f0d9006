"""A coupled system: components (FMUs with start values) and connections between their variables,
and what every system must satisfy (names that can head CSV columns, one connection per input,
positive finite times), whichever file it was read from."""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from pathlib import Path

from harness.archives import remove_folder
from harness.errors import HarnessError


@dataclass
class Component:
    name: str
    fmu: Path
    start: dict[str, float | int | str] = field(default_factory=dict)


@dataclass(frozen=True)
class Connection:
    source: str  # component name
    output: str  # variable name
    target: str
    input: str

    def __str__(self) -> str:
        return f"{self.source}.{self.output} -> {self.target}.{self.input}"


@dataclass(frozen=True)
class Bond:
    """A power bond: at one point of a component, the force input a connection feeds and the
    velocity output that the force's source reads back (and, where the source also reads the
    point's position, that position output). Power F v flows through it."""
    component: str
    force: str  # input
    velocity: str  # output
    position: str | None = None  # output

    def __str__(self) -> str:
        return f"{self.component}.{self.force} with {self.component}.{self.velocity}"


def component_name_problem(name: str) -> str | None:
    """Why a name cannot label a component: it heads CSV columns as <name>.<variable>."""
    if not name:
        return "is empty"
    if len(name) > 200:
        return "is longer than 200 characters"
    bad = sorted({c for c in name if c in ',."' or not c.isprintable()})
    if bad:
        return f"contains {' '.join(repr(c) for c in bad)} (not allowed: comma, full stop, quote, control characters)"
    return None


@dataclass
class System:
    name: str
    components: list[Component]
    connections: list[Connection]
    stop: float | None = None
    step: float | None = None
    # a scene's visual needs (scene files only): {"position": metres} or {"pixels": n}, and the camera
    accuracy: dict = field(default_factory=dict)
    camera: dict = field(default_factory=dict)  # {"scale": pixels per metre, "frame_rate": frames per second}
    traces: dict = field(default_factory=dict)  # component -> [[x column, y column], ...] to draw
    # a temporary folder holding FMUs taken out of an .ssp archive: removed by close(), or when the
    # System is collected, or at exit, whichever comes first (copies sent to worker processes do not own it)
    workspace: Path | None = field(default=None, repr=False, compare=False)
    origin: str = field(default="", repr=False, compare=False)  # the file it was read from, for messages
    bonds: list[Bond] = field(default_factory=list)  # power bonds, checked where the energy coupling uses them
    description: str = ""  # free text (scene files)

    def __post_init__(self) -> None:
        self._remove_workspace = (weakref.finalize(self, remove_folder, self.workspace)
                                  if self.workspace is not None else None)
        self.check()

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_remove_workspace"] = None
        return state

    def close(self) -> None:
        if self._remove_workspace is not None:
            self._remove_workspace()

    def __enter__(self) -> "System":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def check(self) -> None:
        """What any system must satisfy, whichever file it came from."""
        where = self.origin or self.name
        names = set()
        for c in self.components:
            problem = component_name_problem(c.name if isinstance(c.name, str) else "")
            if problem:
                raise HarnessError(f"{where}: component name {c.name!r} {problem}")
            if c.name in names:
                raise HarnessError(f"{where}: component name {c.name!r} is used twice")
            names.add(c.name)
        fed: dict[tuple[str, str], Connection] = {}
        for c in self.connections:
            for end in (c.source, c.target):
                if end not in names:
                    raise HarnessError(f"{where}: connection {c}: no component {end!r}")
            earlier = fed.get((c.target, c.input))
            if earlier is not None:
                raise HarnessError(f"{where}: input {c.target}.{c.input} is fed by two connections "
                                   f"({earlier.source}.{earlier.output} and {c.source}.{c.output}); an input takes one")
            fed[c.target, c.input] = c
        for what, value in (("stop", self.stop), ("step", self.step)):
            if value is not None and not _positive(value):
                raise HarnessError(f"{where}: {what} = {value!r} must be a positive finite number")

    def bond_connections(self, bond: Bond) -> tuple[Connection, Connection, Connection | None]:
        """The force connection into the bond's force input and the connections from its velocity
        (and position) output back into the force's source; a HarnessError naming what is missing."""
        where = f"{self.origin or self.name}: power bond {bond}"
        force = next((c for c in self.connections if (c.target, c.input) == (bond.component, bond.force)), None)
        if force is None:
            raise HarnessError(f"{where}: no connection feeds {bond.component}.{bond.force}")
        found = []
        for output in (bond.velocity, bond.position):
            if output is None:
                found.append(None)
                continue
            back = [c for c in self.connections if (c.source, c.output) == (bond.component, output)
                    and c.target == force.source]
            if len(back) != 1:
                raise HarnessError(f"{where}: {bond.component}.{output} must feed exactly one input of "
                                   f"{force.source}, the force's source (it feeds {len(back)})")
            found.append(back[0])
        return force, found[0], found[1]

    def check_bonds(self) -> list[tuple[Connection, Connection, Connection | None]]:
        """Every bond is one (`bond_connections`, whose connections it returns per bond), no force
        input is in two, and between a force's source and the component it pushes the bonds name
        every output the source reads from it, so that they account for all the energy that passes
        (a Spring that reads a point's position needs it named as the third element). A HarnessError
        naming the first that is not so."""
        where = f"{self.origin or self.name}: power bond"
        named: dict[tuple[str, str], set[str]] = {}
        seen: set[tuple[str, str]] = set()
        found = []
        for bond in self.bonds:
            found.append(self.bond_connections(bond))
            force = found[-1][0]
            if (bond.component, bond.force) in seen:
                raise HarnessError(f"{where} {bond}: {bond.component}.{bond.force} is in another bond already")
            seen.add((bond.component, bond.force))
            named.setdefault((bond.component, force.source), set()).update(
                output for output in (bond.velocity, bond.position) if output is not None)
        for (receiver, source), outputs in named.items():
            read = [c.output for c in self.connections if (c.source, c.target) == (receiver, source)]
            missing = [output for output in read if output not in outputs]
            if missing:
                raise HarnessError(f"{where}s between {receiver} and {source}: {source} reads {receiver}."
                                   f"{missing[0]}, which no bond names (a position goes third: "
                                   f"[force, velocity, position])")
        return found

    def tolerance(self) -> float | None:
        """The position tolerance in metres the scene asks for (pixels through the camera's scale)."""
        if "position" in self.accuracy:
            return float(self.accuracy["position"])
        if "pixels" in self.accuracy:
            scale = self.camera.get("scale")
            if not scale:
                raise HarnessError(f"{self.name}: an accuracy in pixels needs the camera's \"scale\" "
                                   "(pixels per metre)")
            return float(self.accuracy["pixels"]) / float(scale)
        return None

    def frame_step(self) -> float | None:
        """The interval at which the scene is looked at: 1 / frame rate, else the communication step."""
        rate = self.camera.get("frame_rate")
        return 1.0 / float(rate) if rate else self.step

    def component(self, name: str) -> Component:
        for c in self.components:
            if c.name == name:
                return c
        raise HarnessError(f"system {self.name!r} has no component {name!r}")


def _positive(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0 and math.isfinite(value)
