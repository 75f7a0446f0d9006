"""Object files: a mechanical object described by its kinetic and potential energy (TOML).

Reading checks everything that can be checked without deriving the equations: names, numbers,
expressions and the symbols they use. Every problem is one `ObjectFileError` line naming the file,
the key and the problem.
"""
from __future__ import annotations

import itertools
import keyword
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import sympy as sp
from sympy.parsing.sympy_parser import parse_expr, standard_transformations

from harness.fmi.methods import COUNTER_NAMES, GBS_SMALLEST_TOL

# What every object gets from the framework; an object file may restate d, h or tol (to set its
# default, range or position among the parameters) but may not use the other names.
# The work one fmi2DoStep may do, in right-hand-side evaluations: a fixed-step method refuses a
# communication step that needs more (fmi2Error), rkf45 and gbs stop where they run out (fmi2Discard). About
# 0.1 s for the simple pendulum, 4 s for the five-link chain.
MAX_EVALUATIONS_PER_CALL = 10_000_000
# A requirement that is a sum (l0 + eps) must stay above this fraction of the sum of its terms' sizes:
# closer to 0 its value is the rounding of the terms, and the configuration is as singular as at 0.
REQUIRE_MARGIN = 1e-9
# Beyond this many radians an angle coordinate has no precision left for the motion (one ulp is 2.4e-7 rad
# at 2^30): its start is refused, and a step that takes it there is discarded.
ANGLE_LIMIT = 2.0 ** 30
FRAMEWORK_PARAMETERS = {
    "d": dict(start=0.0, unit="1/s", min=0.0, description="damping: each generalized acceleration gets -d times "
                                                            "its velocity"),
    "h": dict(start=0.008, unit="s", min=1e-9,
              description=f"internal step (initial step for rkf45 and gbs); one Co-Simulation step evaluates the "
                          f"right-hand side at most {MAX_EVALUATIONS_PER_CALL:.0e} times".replace("e+0", "e")),
    "tol": dict(start=1e-6, unit="1", min=0.0, max=1.0,
                description="tolerance: rkf45 and gbs keep their error estimates err_i within tol (1 + |y_i|), RMS "
                            f"norm (gbs: tol >= {GBS_SMALLEST_TOL:g}); taylor keeps its last terms below tol "
                            "(1 + |y|_inf); taylor and gbs take the fixed step h at tol = 0, which rkf45 refuses"),
}
EVENT_COUNTER = "n_events"  # the objects with constraints count their events
RESERVED = {"solver", "model", "taylor_order", "gbs_columns", *COUNTER_NAMES, EVENT_COUNTER, "E_kin", "E_pot", "E",
            "t", "time"}
FUNCTIONS = {name: getattr(sp, name) for name in (
    "sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp", "log", "sqrt", "Abs")}
FUNCTIONS["pi"] = sp.pi
IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
MAX_NESTING = 100  # parentheses in one expression: Python's parser and SymPy's recursion give up near 200
AXES = ("x", "y", "z")
# Which constraints are active is a bit set in the FMU state (a 32-bit integer).
MAX_CONSTRAINTS = 31


# The object file's format: each table's keys and what they mean. The reader allows exactly these keys,
# and the reference page of the format (docs/reference/object-file.md) is written from here.
FORMAT = {
    "file": {
        "identifier": "the model's name: a C identifier of at most 60 characters, equal to the file's name in "
                      "modelDescription/",
        "description": "one line saying what the object is",
        "parameters": "table of parameters, each `NAME = { ... }` (keys below); `d`, `h` and `tol` may be restated "
                      "to set their default, range or place",
        "coordinates": "table of generalized coordinates, each with its velocity (keys below); at least one",
        "energy": "the kinetic and potential energy, `T` and `U`",
        "points": "table of named points whose positions (and velocities) become outputs; at least one",
        "forces": "table of force inputs, each acting on a point",
        "rest": "the rest state of the linear model: a coordinate's value, an expression in the parameters "
                "(default 0)",
        "require": "list of expressions in parameters, coordinates and t that must stay positive; where one is "
                   f"not, the state is singular (a sum must stay above {REQUIRE_MARGIN:g} of the sum of its terms' "
                   "sizes, below which it is rounding)",
        "constraints": "table of constraints, each `NAME = { gap = \"...\", ... }` (keys below): contacts, strings, "
                       "walls and rods, with outputs `NAME_gap`, `NAME_force` and the counter `n_events`",
        "outputs": "table of further outputs, each `NAME = { value = \"...\", unit = \"N\" }` (keys below): what "
                   "the motion makes, such as the tension a rod carries",
    },
    "parameters": {
        "start": "default value (required but for d, h and tol)",
        "unit": "unit, e.g. \"m\", \"kg\", \"N/m\"",
        "min": "smallest allowed value (inclusive)",
        "max": "largest allowed value (inclusive)",
        "description": "text for the model description",
    },
    "coordinates": {
        "start": "start value (default 0)",
        "unit": "unit of the coordinate",
        "velocity": "name of its velocity (required)",
        "velocity_start": "start value of the velocity (default 0)",
        "description": "text for the coordinate's variable",
        "velocity_description": "text for the velocity's variable",
    },
    "energy": {
        "T": "kinetic energy: quadratic and positive in the velocities; parameters, coordinates, velocities, t and "
             "`speed2(point)`, the squared speed of a named point",
        "U": "potential energy in parameters, coordinates and t",
    },
    "points": {
        "x": "horizontal position (expression in parameters, coordinates and t)",
        "y": "vertical position, up",
        "z": "third axis, for a 3-D point",
        "names": "output names other than `<point>_x`, `<point>_v_x`, ...: `{ x = \"x2\", v_x = \"v_x\" }`",
        "description": "text for the point's outputs",
        "velocity": "false: no velocity outputs (default true)",
        "link": "for drawing: the fixed end of the point's string or rod, `{ x = \"-2*R\", y = \"0\" }` in "
                "parameters (without links the view joins the anchor and the points in file order)",
        "radius": "for drawing: the point is a ball of this radius (an expression in parameters)",
    },
    "constraints": {
        "gap": "the gap g in parameters, coordinates and t (required): the motion keeps g >= 0 (unilateral) or "
               "g = 0 (bilateral); its force acts along dg/dq",
        "kind": "\"unilateral\" (default: the constraint only pushes) or \"bilateral\" (a rod or a guide: it "
                "pushes and pulls)",
        "restitution": "Newton's coefficient e of a rigid unilateral constraint: a number or a parameter's name, in "
                       "[0, 1] (default 0); the gap's rate after an impact is -e times the rate before",
        "stiffness": "makes the constraint compliant: the force k * delta**exponent * (1 + damping * d(delta)/dt) "
                     "for the overlap delta = -g > 0 (Hertz, Hunt and Crossley), zero when apart, never pulling; a "
                     "positive number or a parameter's name",
        "exponent": "the compliant law's exponent, a number >= 1 (default 1.5, Hertz)",
        "damping": "the compliant law's damping in s per gap unit, a number >= 0 or a parameter's name (default 0)",
        "unit": "the gap's unit (default \"m\"; \"rad\" makes its force a torque in N.m)",
        "description": "text for the constraint's outputs",
    },
    "outputs": {
        "value": "its value (required): an expression in parameters (`d` included: the damping, a drag -d v on "
                 "every bit of mass), coordinates, velocities, t, the force inputs and the accelerations "
                 "`der(VELOCITY)` (the motion's, damping included; not in an object with constraints)",
        "unit": "its unit",
        "description": "text for the output",
    },
    "forces": {
        "point": "the point the force acts on (required); inputs `<force>_x`, `<force>_y` (and `_z`)",
        "names": "input names other than `<force>_x`, ...: `{ x = \"F_x\", y = \"F_y\" }`",
        "description": "text for the force's inputs",
    },
}


class ObjectFileError(Exception):
    """A bad object file: the message is one line naming the file, the key and the problem."""


@dataclass
class Parameter:
    name: str
    start: float
    unit: str = ""
    min: float | None = None
    max: float | None = None
    description: str = ""


@dataclass
class Coordinate:
    name: str
    start: float
    unit: str
    velocity: str
    velocity_start: float = 0.0
    description: str = ""
    velocity_description: str = ""


@dataclass
class Point:
    name: str
    position: list[sp.Expr]           # x, y (and z for a 3-D point)
    outputs: dict[str, str]           # "x", "y", "z", "v_x", ... -> output variable name
    description: str = ""
    velocity: bool = True
    link: list[sp.Expr] | None = None  # drawing only: the string's or rod's fixed end
    radius: sp.Expr | None = None      # drawing only: a ball's radius


@dataclass
class Force:
    name: str
    point: str
    inputs: dict[str, str]            # axis -> input variable name
    description: str = ""


@dataclass
class Constraint:
    name: str
    gap: sp.Expr                      # in parameters, coordinates and t
    bilateral: bool = False
    restitution: sp.Expr = sp.Integer(0)   # a number or a parameter's symbol, in [0, 1]
    stiffness: sp.Expr | None = None       # compliant law (None: rigid)
    exponent: float = 1.5
    damping: sp.Expr = sp.Integer(0)
    unit: str = "m"
    description: str = ""

    @property
    def compliant(self) -> bool:
        return self.stiffness is not None

    @property
    def force_unit(self) -> str:
        return {"m": "N", "rad": "N.m"}.get(self.unit, "")

    @property
    def outputs(self) -> tuple[str, str]:
        return f"{self.name}_gap", f"{self.name}_force"

    @property
    def indicator(self) -> str:
        """Its event indicator's variable (a local: FMI 3.0 names each event indicator by a variable)."""
        return f"{self.name}_indicator"


@dataclass
class Output:
    """A further output: value is an expression in parameters, coordinates, velocities, t, force inputs and
    the accelerations (the symbols of ObjectSpec.accelerations)."""
    name: str
    value: sp.Expr
    unit: str = ""
    description: str = ""


def acceleration_symbol(velocity: str) -> sp.Symbol:
    """The symbol der(VELOCITY) of an output's expression stands for."""
    return sp.Symbol(f"der({velocity})", real=True)


@dataclass
class ObjectSpec:
    """One object as its file describes it, with every expression parsed into SymPy."""
    path: Path
    identifier: str
    description: str
    parameters: list[Parameter]       # the object's own and the restated framework ones, in file order
    coordinates: list[Coordinate]
    T: sp.Expr
    U: sp.Expr
    points: list[Point]
    forces: list[Force]
    rest: dict[str, sp.Expr]          # rest state of the linear model (parameters allowed)
    require: list[sp.Expr]            # expressions that stay positive; the state is singular elsewhere
    constraints: list[Constraint] = field(default_factory=list)
    symbols: dict[str, sp.Symbol] = field(repr=False, default_factory=dict)
    outputs: list[Output] = field(default_factory=list)

    @property
    def accelerations(self) -> list[sp.Symbol]:
        """The symbols der(VELOCITY) that outputs may hold, in the order of the coordinates."""
        return [acceleration_symbol(c.velocity) for c in self.coordinates]

    @property
    def time(self) -> sp.Symbol:
        return self.symbols["t"]

    def parameter_symbols(self) -> list[sp.Symbol]:
        return [self.symbols[p.name] for p in self.parameters if p.name not in FRAMEWORK_PARAMETERS]

    @property
    def q(self) -> list[sp.Symbol]:
        return [self.symbols[c.name] for c in self.coordinates]

    @property
    def v(self) -> list[sp.Symbol]:
        return [self.symbols[c.velocity] for c in self.coordinates]

    @property
    def dimension(self) -> int:
        return max(len(p.position) for p in self.points) if self.points else 2

    @property
    def rheonomic(self) -> bool:
        t = self.time
        return any(t in e.free_symbols for e in [self.T, self.U] + [x for p in self.points for x in p.position])


def _finite(value: int | float) -> bool:
    try:
        return math.isfinite(float(value))
    except OverflowError:  # an integer beyond any double
        return False


LARGEST_EXPONENT = 308  # decimal digits a double can hold before the point


def _number_problem(expr) -> str | None:
    """Why a parsed (not yet evaluated) expression holds a number no double can: a literal beyond
    1e308, or a power of numbers whose value would be (SymPy would compute it exactly, without end
    for 9**9**9**9). A power of numbers needs a literal exponent."""
    for node in sp.preorder_traversal(expr):
        if isinstance(node, sp.Number) and node.is_finite and abs(node) > 10 ** LARGEST_EXPONENT:
            return "a number beyond double precision"
        if isinstance(node, sp.Pow) and not node.free_symbols:
            base, exponent = node.args
            if not isinstance(exponent, sp.Number):
                return "a power of numbers needs a plain number as its exponent"
            if isinstance(base, sp.Number) and base != 0 and \
                    abs(float(exponent)) * math.log10(abs(float(base))) > LARGEST_EXPONENT:
                return "a power of numbers beyond double precision"
        if isinstance(node, sp.Pow) and isinstance(node.args[1], sp.Number) and abs(node.args[1]) > 1024:
            return "an exponent above 1024"
    return None


class _Reader:
    def __init__(self, path: Path):
        self.path = path

    def fail(self, key: str, problem: str) -> ObjectFileError:
        return ObjectFileError(f"{self.path}: {key}: {problem}")

    def table(self, data: dict, key: str, required: bool = True) -> dict:
        value = data.get(key)
        if value is None:
            if required:
                raise self.fail(key, "missing")
            return {}
        if not isinstance(value, dict):
            raise self.fail(key, "must be a table")
        return value

    def string(self, data: dict, key: str, where: str, default: str | None = None) -> str:
        value = data.get(key, default)
        if value is None:
            raise self.fail(where, "missing")
        if not isinstance(value, str):
            raise self.fail(where, f"must be a string, not {value!r}")
        return value

    def number(self, data: dict, key: str, where: str, default: float | None = None) -> float | None:
        value = data.get(key, default)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not _finite(value):
            shown = repr(value) if len(repr(value)) <= 40 else f"a number of {len(str(value))} digits"
            raise self.fail(where, f"must be a finite number, not {shown}")
        return float(value)

    def name(self, name: str, where: str) -> str:
        if not IDENTIFIER.match(name):
            raise self.fail(where, f"{name!r} is not a name (a letter, then letters, digits or _)")
        if keyword.iskeyword(name) or name in FUNCTIONS:
            raise self.fail(where, f"{name!r} is a reserved word")
        return name

    def known_keys(self, data: dict, allowed: set[str], where: str) -> None:
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise self.fail(f"{where}.{unknown[0]}", f"unknown key (allowed: {', '.join(sorted(allowed))})")

    def expression(self, text: object, where: str, symbols: dict[str, sp.Symbol],
                   allowed: set[sp.Symbol]) -> sp.Expr:
        if isinstance(text, (int, float)) and not isinstance(text, bool):
            return sp.Float(text) if isinstance(text, float) else sp.Integer(text)
        if not isinstance(text, str) or not text.strip():
            raise self.fail(where, f"must be an expression in a string, not {text!r}")
        # parse_expr evaluates Python: allow nothing but names, numbers and arithmetic.
        if re.search(r"__|\.\s*[A-Za-z_]|[^A-Za-z0-9_+\-*/(). ,\t]", text):
            bad = re.search(r"__|\.\s*[A-Za-z_]|[^A-Za-z0-9_+\-*/(). ,\t]", text).group(0)
            hint = " (write powers as **)" if bad == "^" else ""
            raise self.fail(where, f"{text!r}: {bad!r} is not allowed in an expression{hint}")
        depth = max(itertools.accumulate((c == "(") - (c == ")") for c in text), default=0)
        if depth > MAX_NESTING:
            raise self.fail(where, f"parentheses nested {depth} deep (at most {MAX_NESTING})")
        namespace = {"__builtins__": {}, "Integer": sp.Integer, "Float": sp.Float, "Rational": sp.Rational,
                     "Symbol": sp.Symbol, "Add": sp.Add, "Mul": sp.Mul, "Pow": sp.Pow, **FUNCTIONS}
        try:
            unevaluated = parse_expr(text, local_dict=dict(symbols), global_dict=namespace,
                                     transformations=standard_transformations, evaluate=False)
            problem = _number_problem(unevaluated)
            if problem:
                raise self.fail(where, f"{text!r}: {problem}")
            expr = parse_expr(text, local_dict=dict(symbols), global_dict=namespace,
                              transformations=standard_transformations, evaluate=True)
        except ObjectFileError:
            raise
        except Exception as error:  # SymPy reports syntax errors in several exception types
            raise self.fail(where, f"{text!r} is not an expression ({type(error).__name__})") from None
        if not isinstance(expr, sp.Expr):
            raise self.fail(where, f"{text!r} is not an expression")
        unknown = sorted(str(s) for s in expr.free_symbols if s not in allowed)
        if unknown:
            known_but_not_here = [u for u in unknown if u in symbols]
            if known_but_not_here:
                raise self.fail(where, f"{known_but_not_here[0]!r} may not appear here")
            raise self.fail(where, f"unknown symbol {unknown[0]!r}")
        if expr.has(sp.zoo, sp.oo, sp.nan, sp.I):
            raise self.fail(where, f"{text!r} is not a finite real expression")
        return expr


def read_object_file(path: str | Path, text: str | None = None) -> ObjectSpec:
    """Reads and checks an object file (text, when given, is its content: path then only names it);
    raises ObjectFileError with a one-line message."""
    # The tables are read in this order, which is the order of their checks: a file with several problems is
    # told the first.
    reader = _Reader(Path(path))
    data = _read_toml(reader, text)
    identifier, description = _read_identity(reader, data)
    names = _TakenNames(reader)
    parameters = _read_parameters(reader, data, names)
    coordinates = _read_coordinates(reader, data, names)
    symbols, params, q, v, t = _symbols_of(names, parameters, coordinates)
    points = _read_points(reader, data, names, symbols, params, params | q | t)
    T, U = _read_energy(reader, data, symbols, coordinates, points, params, q, v, t)
    forces = _read_forces(reader, data, names, points)
    # the force inputs are known names from here on, which only the outputs may use
    symbols.update({name: sp.Symbol(name, real=True) for force in forces for name in force.inputs.values()})
    rest = _read_rest(reader, data, coordinates, symbols, params)
    require = _read_require(reader, data, symbols, params | q | t)
    constraints = _read_constraints(reader, reader.table(data, "constraints", required=False), names.claim, symbols,
                                    parameters, params | q | t, q)
    inputs = {symbols[name] for force in forces for name in force.inputs.values()}
    outputs = _read_outputs(reader, reader.table(data, "outputs", required=False), names.claim, symbols, coordinates,
                            params | q | v | t | inputs | {symbols["d"]}, bool(constraints))
    spec = ObjectSpec(reader.path, identifier, description, parameters, coordinates, T, U, points, forces, rest,
                      require, constraints, symbols, outputs)
    _check_object(reader, spec)
    return spec


def _read_toml(reader: _Reader, text: str | None) -> dict:
    """The file's top-level table (text, when given, is its content), its keys checked."""
    path = reader.path
    if text is None and path.exists() and not path.is_file():  # a pipe or a device could block for ever
        raise ObjectFileError(f"{path}: is not a regular file")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8") if text is None else text)
    except OSError as error:
        raise ObjectFileError(f"{path}: cannot be read ({error.strerror or error})") from None
    except UnicodeDecodeError:
        raise ObjectFileError(f"{path}: is not UTF-8 text") from None
    except tomllib.TOMLDecodeError as error:
        raise ObjectFileError(f"{path}: is not valid TOML ({error})") from None
    reader.known_keys(data, set(FORMAT["file"]), "file")
    return data


def _read_identity(reader: _Reader, data: dict) -> tuple[str, str]:
    """The object's identifier and description."""
    identifier = reader.string(data, "identifier", "identifier")
    if not IDENTIFIER.match(identifier) or len(identifier) > 60:
        raise reader.fail("identifier", f"{identifier!r} must be a C identifier of at most 60 characters")
    description = reader.string(data, "description", "description", default="")
    return identifier, description


class _TakenNames:
    """The names an object file has given so far, each with the key that gave it: one object has each name once."""

    def __init__(self, reader: _Reader):
        self.reader = reader
        self.taken: dict[str, str] = {}  # name -> key, in the order given

    def claim(self, name: str, where: str) -> str:
        """The name, now taken by the key where."""
        reader = self.reader
        reader.name(name, where)
        if name in RESERVED:
            raise reader.fail(where, f"{name!r} is a name every object already has")
        if name in self.taken:
            raise reader.fail(where, f"{name!r} is already used by {self.taken[name]}")
        self.taken[name] = where
        return name

    def entry(self, section: str, name: str, entry, example: str, allowed: set[str]) -> str:
        """The key section.name of a table's entry, its name taken and its keys checked."""
        where = f"{section}.{name}"
        self.claim(name, where)
        if not isinstance(entry, dict):
            raise self.reader.fail(where, f"must be a table such as {example}")
        self.reader.known_keys(entry, allowed, where)
        return where


def _read_parameters(reader: _Reader, data: dict, names: _TakenNames) -> list[Parameter]:
    """The parameters in file order, then the framework's the file does not restate."""
    parameters: list[Parameter] = []
    for name, entry in reader.table(data, "parameters").items():
        where = names.entry("parameters", name, entry, '{ start = 1.0, unit = "m" }', set(FORMAT["parameters"]))
        defaults = FRAMEWORK_PARAMETERS.get(name, {})
        start = reader.number(entry, "start", f"{where}.start", defaults.get("start"))
        if start is None:
            raise reader.fail(f"{where}.start", "missing")
        p = Parameter(name, start, reader.string(entry, "unit", f"{where}.unit", defaults.get("unit", "")),
                      reader.number(entry, "min", f"{where}.min", defaults.get("min")),
                      reader.number(entry, "max", f"{where}.max", defaults.get("max")),
                      reader.string(entry, "description", f"{where}.description", defaults.get("description", "")))
        _check_range(reader, where, p.start, p.min, p.max)
        parameters.append(p)
    for name, defaults in FRAMEWORK_PARAMETERS.items():
        if name not in names.taken:
            names.claim(name, f"parameters.{name}")
            parameters.append(Parameter(name, **defaults))
    return parameters


def _read_coordinates(reader: _Reader, data: dict, names: _TakenNames) -> list[Coordinate]:
    """The generalized coordinates, at least one, each with its velocity."""
    coordinates: list[Coordinate] = []
    for name, entry in reader.table(data, "coordinates").items():
        where = names.entry("coordinates", name, entry, '{ start = 0.5, unit = "rad", velocity = "omega" }',
                            set(FORMAT["coordinates"]))
        if "velocity" not in entry:
            raise reader.fail(f"{where}.velocity", "missing: every coordinate needs the name of its velocity")
        velocity = names.claim(reader.string(entry, "velocity", f"{where}.velocity"), f"{where}.velocity")
        start = reader.number(entry, "start", f"{where}.start", 0.0)
        coordinates.append(Coordinate(name, start, reader.string(entry, "unit", f"{where}.unit", ""), velocity,
                                      reader.number(entry, "velocity_start", f"{where}.velocity_start", 0.0),
                                      reader.string(entry, "description", f"{where}.description", ""),
                                      reader.string(entry, "velocity_description", f"{where}.velocity_description",
                                                    "")))
    if not coordinates:
        raise reader.fail("coordinates", "an object needs at least one generalized coordinate")
    return coordinates


def _symbols_of(names: _TakenNames, parameters: list[Parameter],
                coordinates: list[Coordinate]) -> tuple[dict[str, sp.Symbol], set, set, set, set]:
    """The symbols of the names taken so far and of t, and the sets (parameters, coordinates, velocities, t)."""
    symbols = {name: sp.Symbol(name, real=True) for name in names.taken}
    symbols["t"] = sp.Symbol("t", real=True)
    params = {symbols[p.name] for p in parameters if p.name not in FRAMEWORK_PARAMETERS}
    q = {symbols[c.name] for c in coordinates}
    v = {symbols[c.velocity] for c in coordinates}
    t = {symbols["t"]}
    return symbols, params, q, v, t


def _read_points(reader: _Reader, data: dict, names: _TakenNames, symbols: dict[str, sp.Symbol], params: set,
                 allowed: set) -> list[Point]:
    """The named points: positions in the allowed symbols, drawing hints (link, radius) in the parameters."""
    points: list[Point] = []
    for name, entry in reader.table(data, "points", required=False).items():
        where = f"points.{name}"
        reader.name(name, where)
        if not isinstance(entry, dict):
            raise reader.fail(where, "must be a table such as { x = \"L*sin(phi)\", y = \"-L*cos(phi)\" }")
        reader.known_keys(entry, set(FORMAT["points"]), where)
        axes = [a for a in AXES if a in entry]
        if axes not in (["x", "y"], ["x", "y", "z"]):
            raise reader.fail(where, "needs x and y expressions (and z for a 3-D point)")
        position = [reader.expression(entry[a], f"{where}.{a}", symbols, allowed) for a in axes]
        with_velocity = entry.get("velocity", True)
        if not isinstance(with_velocity, bool):
            raise reader.fail(f"{where}.velocity", "must be true or false")
        kinds = axes + ([f"v_{a}" for a in axes] if with_velocity else [])
        output_names = reader.table(entry, "names", required=False)
        reader.known_keys(output_names, set(kinds), f"{where}.names")
        outputs = {}
        for kind in kinds:
            output = output_names.get(kind, f"{name}_{kind}")
            if not isinstance(output, str):
                raise reader.fail(f"{where}.names.{kind}", "must be a string")
            outputs[kind] = names.claim(output, f"{where}.names.{kind}")
        link = None
        if "link" in entry:
            ends = entry["link"]
            if not isinstance(ends, dict):
                raise reader.fail(f"{where}.link", "must be a table such as { x = \"0\", y = \"0\" }")
            reader.known_keys(ends, set(axes), f"{where}.link")
            if set(ends) != set(axes):
                raise reader.fail(f"{where}.link", f"needs {' and '.join(axes)}, as the point has")
            link = [reader.expression(ends[a], f"{where}.link.{a}", symbols, params) for a in axes]
        radius = reader.expression(entry["radius"], f"{where}.radius", symbols, params) if "radius" in entry else None
        points.append(Point(name, position, outputs, reader.string(entry, "description", f"{where}.description", ""),
                            with_velocity, link, radius))
    return points


def _read_energy(reader: _Reader, data: dict, symbols: dict[str, sp.Symbol], coordinates: list[Coordinate],
                 points: list[Point], params: set, q: set, v: set, t: set) -> tuple[sp.Expr, sp.Expr]:
    """The kinetic and the potential energy T and U, each speed2(point) in T replaced by its value."""
    energy = reader.table(data, "energy")
    reader.known_keys(energy, set(FORMAT["energy"]), "energy")
    for key in ("T", "U"):
        if key not in energy:
            raise reader.fail(f"energy.{key}", "missing")
    velocity_keys = {f"velocity of {symbols[c.name]}": symbols[c.velocity] for c in coordinates}
    # speed2(point) in T: the squared speed of a named point (m/2*speed2(bob) for a point mass)
    speed2 = sp.Function("speed2")
    point_symbols = {p.name: sp.Symbol(f"point {p.name}") for p in points}
    T = reader.expression(energy["T"], "energy.T", {**symbols, **point_symbols, "speed2": speed2},
                          params | q | v | t | set(point_symbols.values()))
    T = _replace_speed2(reader, T, speed2, point_symbols, points, sorted(q, key=str), {**symbols, **velocity_keys})
    U = reader.expression(energy["U"], "energy.U", symbols, params | q | t)
    return T, U


def _read_forces(reader: _Reader, data: dict, names: _TakenNames, points: list[Point]) -> list[Force]:
    """The force inputs, each acting on a point along its axes."""
    forces: list[Force] = []
    point_names = {p.name: p for p in points}
    for name, entry in reader.table(data, "forces", required=False).items():
        where = f"forces.{name}"
        reader.name(name, where)
        if not isinstance(entry, dict):
            raise reader.fail(where, "must be a table such as { point = \"bob\" }")
        reader.known_keys(entry, set(FORMAT["forces"]), where)
        point = reader.string(entry, "point", f"{where}.point")
        if point not in point_names:
            raise reader.fail(f"{where}.point", f"{point!r} is not one of the points ({', '.join(point_names)})")
        axes = AXES[:len(point_names[point].position)]
        input_names = reader.table(entry, "names", required=False)
        reader.known_keys(input_names, set(axes), f"{where}.names")
        inputs = {}
        for axis in axes:
            inputs[axis] = names.claim(input_names.get(axis, f"{name}_{axis}"), f"{where}.names.{axis}")
        forces.append(Force(name, point, inputs, reader.string(entry, "description", f"{where}.description", "")))
    return forces


def _read_rest(reader: _Reader, data: dict, coordinates: list[Coordinate], symbols: dict[str, sp.Symbol],
               params: set) -> dict[str, sp.Expr]:
    """The linear model's rest state: each coordinate's value in the parameters (0 where not given)."""
    rest_table = reader.table(data, "rest", required=False)
    reader.known_keys(rest_table, {c.name for c in coordinates}, "rest")
    return {c.name: reader.expression(rest_table.get(c.name, 0), f"rest.{c.name}", symbols, params)
            for c in coordinates}


def _read_require(reader: _Reader, data: dict, symbols: dict[str, sp.Symbol], allowed: set) -> list[sp.Expr]:
    """The expressions that must stay positive, each depending on some symbol."""
    require_list = data.get("require", [])
    if not isinstance(require_list, list):
        raise reader.fail("require", "must be a list of expressions that stay positive")
    require = [reader.expression(e, f"require[{k}]", symbols, allowed) for k, e in enumerate(require_list)]
    for k, expression in enumerate(require):
        if not expression.free_symbols:  # always true or always false: a mistake, never a condition
            raise reader.fail(f"require[{k}]", f"= {expression} depends on no parameter or coordinate")
    return require


def _check_object(reader: _Reader, spec: ObjectSpec) -> None:
    """None: raises where the whole object is wrong (no point, or a driven object's outputs with accelerations)."""
    if not spec.points:
        raise reader.fail("points", "an object needs at least one point (its position is what a scene shows)")
    for output in spec.outputs:
        if spec.rheonomic and output.value.free_symbols & set(spec.accelerations):
            raise reader.fail(f"outputs.{output.name}.value", "the accelerations of a driven object (t in its energies "
                                                              "or points) are not offered to outputs")


def _read_outputs(reader: _Reader, table: dict, claim, symbols: dict, coordinates: list[Coordinate], allowed: set,
                  constrained: bool) -> list[Output]:
    der = sp.Function("der")
    velocities = {symbols[c.velocity]: c.velocity for c in coordinates}
    outputs = []
    for name, entry in table.items():
        where = f"outputs.{name}"
        claim(name, where)
        if not isinstance(entry, dict):
            raise reader.fail(where, 'must be a table such as { value = "m*(g*cos(phi) + L*omega**2)", unit = "N" }')
        reader.known_keys(entry, set(FORMAT["outputs"]), where)
        if "value" not in entry:
            raise reader.fail(f"{where}.value", "missing")
        value = reader.expression(entry["value"], f"{where}.value", {**symbols, "der": der}, allowed)
        replacements = {}
        for call in value.atoms(sp.Function):
            if call.func != der:
                continue
            if len(call.args) != 1 or call.args[0] not in velocities:
                raise reader.fail(f"{where}.value",
                                  f"{call}: der() takes one velocity ({', '.join(velocities.values())})")
            if constrained:
                raise reader.fail(f"{where}.value", f"{call}: an object with constraints offers no accelerations to "
                                                    "its outputs (its constraint forces are outputs already)")
            replacements[call] = acceleration_symbol(velocities[call.args[0]])
        outputs.append(Output(name, value.xreplace(replacements),
                              reader.string(entry, "unit", f"{where}.unit", ""),
                              reader.string(entry, "description", f"{where}.description", "")))
    return outputs


def _read_constraints(reader: _Reader, table: dict, claim, symbols: dict, parameters: list[Parameter],
                      allowed: set, q: set) -> list[Constraint]:
    if len(table) > MAX_CONSTRAINTS:
        raise reader.fail("constraints", f"{len(table)} constraints (at most {MAX_CONSTRAINTS})")
    by_name = {p.name: p for p in parameters if p.name not in FRAMEWORK_PARAMETERS}
    result = []
    for name, entry in table.items():
        where = f"constraints.{name}"
        reader.name(name, where)
        if not isinstance(entry, dict):
            raise reader.fail(where, 'must be a table such as { gap = "y - R", restitution = 0.8 }')
        reader.known_keys(entry, set(FORMAT["constraints"]), where)
        if "gap" not in entry:
            raise reader.fail(f"{where}.gap", "missing")
        gap = reader.expression(entry["gap"], f"{where}.gap", symbols, allowed)
        if not gap.free_symbols & q:
            raise reader.fail(f"{where}.gap", f"= {gap} is not a function of the coordinates")
        kind = reader.string(entry, "kind", f"{where}.kind", "unilateral")
        if kind not in ("unilateral", "bilateral"):
            raise reader.fail(f"{where}.kind", f"{kind!r}: must be \"unilateral\" or \"bilateral\"")
        compliant = "stiffness" in entry
        for key in ("exponent", "damping"):
            if key in entry and not compliant:
                raise reader.fail(f"{where}.{key}", "belongs to a compliant constraint: give its stiffness too")
        if kind == "bilateral" and (compliant or "restitution" in entry):
            raise reader.fail(f"{where}.{'stiffness' if compliant else 'restitution'}",
                              "a bilateral constraint is rigid and never separates (no restitution, no stiffness)")
        if compliant and "restitution" in entry:
            raise reader.fail(f"{where}.restitution", "a compliant constraint loses energy by its damping, not by a "
                                                      "restitution")

        def coefficient(key: str, default: float, low: float, high: float | None, strict: bool = False) -> sp.Expr:
            value = entry.get(key, default)
            shown = f"[{low:g}, {high:g}]" if high is not None else f"{'> ' if strict else '>= '}{low:g}"
            if isinstance(value, str) and IDENTIFIER.match(value) and value in by_name:
                p = by_name[value]
                if p.min is None or p.min < low or (strict and p.min <= low) or \
                        (high is not None and (p.max is None or p.max > high)):
                    raise reader.fail(f"{where}.{key}", f"parameter {value!r} may take values outside {shown}: "
                                                        f"declare its {'min and max' if high is not None else 'min'} "
                                                        "within it")
                return symbols[value]
            number = reader.number(entry, key, f"{where}.{key}", default) if not isinstance(value, str) else None
            if number is None:
                raise reader.fail(f"{where}.{key}", f"{value!r} is neither a number nor a parameter's name")
            if number < low or (strict and number <= low) or (high is not None and number > high):
                raise reader.fail(f"{where}.{key}", f"{number:g} is outside {shown}")
            return sp.Float(number)

        exponent = reader.number(entry, "exponent", f"{where}.exponent", 1.5)
        if not 1.0 <= exponent <= 10.0:
            raise reader.fail(f"{where}.exponent", f"{exponent:g} is outside [1, 10]")
        result.append(Constraint(
            name, gap, bilateral=kind == "bilateral",
            restitution=coefficient("restitution", 0.0, 0.0, 1.0),
            stiffness=coefficient("stiffness", 1.0, 0.0, None, strict=True) if compliant else None,
            exponent=exponent, damping=coefficient("damping", 0.0, 0.0, None),
            unit=reader.string(entry, "unit", f"{where}.unit", "m"),
            description=reader.string(entry, "description", f"{where}.description", "")))
        for output in (*result[-1].outputs, result[-1].indicator):
            claim(output, where)
    return result


def _replace_speed2(reader: _Reader, T, speed2, point_symbols, points, q, symbols):
    by_symbol = {point_symbols[p.name]: p for p in points}
    coordinates = list(q)
    velocity_of = {}
    for call in T.atoms(sp.core.function.AppliedUndef):
        if call.func != speed2 or len(call.args) != 1 or call.args[0] not in by_symbol:
            raise reader.fail("energy.T", f"{call} must be speed2(<a point's name>)")
        position = by_symbol[call.args[0]].position
        velocity = [sp.diff(x, symbols["t"]) + sum(sp.diff(x, qj) * symbols[f"velocity of {qj}"] for qj in coordinates)
                    for x in position]
        velocity_of[call] = sum(component ** 2 for component in velocity)
    T = T.xreplace(velocity_of)
    stray = T.free_symbols & set(point_symbols.values())
    if stray:
        raise reader.fail("energy.T", f"a point's name may appear only inside speed2(): {sorted(map(str, stray))[0]}")
    return T


def _check_range(reader: _Reader, where: str, start: float, low: float | None, high: float | None) -> None:
    if low is not None and high is not None and low > high:
        raise reader.fail(where, f"min = {low} is above max = {high}")
    if low is not None and start < low:
        raise reader.fail(f"{where}.start", f"{start} is below min = {low}")
    if high is not None and start > high:
        raise reader.fail(f"{where}.start", f"{start} is above max = {high}")
