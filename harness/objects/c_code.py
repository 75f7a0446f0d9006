"""The C physics of an object from its derivation: physics.h (constants and the right-hand side,
inlined into the integrators) and physics.c (start-up, outputs, output derivatives).

What the generated code does, and why:
* parameter-only subexpressions are computed once when the parameters are known (model_prepare);
* common subexpressions are eliminated (SymPy's cse) within each function;
* M a = f + Q is solved by an LDL^T factorization unrolled for the object's size, skipping entries
  that are zero for every state; a pivot that is not positive means M is not positive definite
  there: the derivatives become NaN, which the framework turns into fmi2Error at initialization and
  fmi2Discard in a step;
* the generalized forces are computed only when the framework passes inputs (u != NULL): with the
  force inputs zero and without derivatives, it passes NULL and the force terms vanish after inlining.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import sympy as sp

from harness.fmi.methods import FREE_MOTION_ONLY, GBS_COLUMNS, GBS_SMALLEST_TOL, TAYLOR_ORDERS
from harness.objects.c_expression import c_expr
from harness.objects.derivation import Derivation, constraints_beyond_free_motion, total_derivative
from harness.objects.object_file import (ANGLE_LIMIT, FRAMEWORK_PARAMETERS, MAX_EVALUATIONS_PER_CALL, REQUIRE_MARGIN,
                                         ObjectSpec, Parameter)
from harness.objects.taylor_code import TaylorUnavailable, contract_trigonometry, loop_over_orders, taylor_code


@dataclass
class _Names:
    """SymPy symbols standing for C lvalues: c->p_<parameter>, s_<state>, u[k], t."""
    mapping: dict[sp.Symbol, sp.Symbol] = field(default_factory=dict)

    def to_c(self, expr):
        return sp.sympify(expr).xreplace(self.mapping)


class _Constants:
    """Parameter-only subexpressions, hoisted into ModelConst and computed in model_prepare."""

    def __init__(self, parameters: set[sp.Symbol]):
        self.parameters = parameters
        self.known: dict[sp.Expr, sp.Symbol] = {}
        self.definitions: list[tuple[sp.Symbol, sp.Expr]] = []

    def is_constant(self, expr) -> bool:
        return expr.free_symbols <= self.parameters

    def symbol_for(self, expr) -> sp.Expr:
        if expr.is_Atom:
            return expr
        if expr not in self.known:
            symbol = sp.Symbol(f"c->k[{len(self.definitions)}]", real=True)
            self.known[expr] = symbol
            self.definitions.append((symbol, expr))
            self.parameters = self.parameters | {symbol}
        return self.known[expr]

    def hoist(self, expr):
        expr = sp.sympify(expr)
        if expr.is_Atom:
            return expr
        if self.is_constant(expr):
            return self.symbol_for(expr)
        if isinstance(expr, (sp.Add, sp.Mul)):
            constant = [a for a in expr.args if self.is_constant(a)]
            varying = [self.hoist(a) for a in expr.args if not self.is_constant(a)]
            if len(constant) > 1 or (constant and not constant[0].is_Atom):
                return expr.func(self.symbol_for(expr.func(*constant)), *varying)
            return expr.func(*constant, *varying)
        return expr.func(*[self.hoist(a) for a in expr.args])


def _cse_lines(expressions, prefix: str, indent: str = "    "):
    """Common subexpressions of expressions as C declarations; returns (lines, reduced expressions)."""
    replacements, reduced = sp.cse(list(expressions), symbols=sp.numbered_symbols(prefix, real=True),
                                   optimizations="basic")
    lines = [f"{indent}const double {symbol} = {c_expr(value)};" for symbol, value in replacements]
    return lines, reduced, replacements


def _reuse(expressions, replacements):
    """Rewrite expressions in terms of already computed common subexpressions where they match."""
    result = []
    for expr in expressions:
        for symbol, value in replacements:
            expr = expr.xreplace({value: symbol})
        result.append(expr)
    return result


@dataclass
class GeneratedC:
    header: str
    source: str


@dataclass
class _Generation:
    """What every part of the C code shares: the derivation, its symbols' C names and the constants hoisted so far."""
    derivation: Derivation
    parameters: list[Parameter]  # the object's own: the framework's have fields of their own
    names: _Names
    constants: _Constants
    accelerations: list[sp.Symbol]  # a_j, the accelerations of the outputs' rates
    state_locals: list[str]  # s_<state> = x[...], for the functions of (t, x)

    @property
    def spec(self) -> ObjectSpec:
        return self.derivation.spec

    @property
    def n(self) -> int:
        return self.derivation.n

    @property
    def nf(self) -> int:
        return len(self.derivation.inputs)

    @property
    def has_linear(self) -> bool:
        return self.derivation.linear is not None

    @property
    def real_locals(self) -> list[str]:
        """s_<state> = real[VR_<state>], for the functions of the variables."""
        return [f"    const double s_{c.name} = real[VR_{c.name}];" for c in self.spec.coordinates] + \
               [f"    const double s_{c.velocity} = real[VR_{c.velocity}];" for c in self.spec.coordinates]

    @property
    def accelerations_now(self) -> dict[sp.Symbol, sp.Symbol]:
        """The accelerations der(VELOCITY) of the further outputs as the derivatives dx[n + j]."""
        return {a: sp.Symbol(f"dx[{self.n + j}]", real=True) for j, a in enumerate(self.spec.accelerations)}

    def prepared(self, expr):
        """expr in C names, its parameter-only subexpressions hoisted into the constants."""
        return self.constants.hoist(self.names.to_c(expr))


def generate_c(derivation: Derivation) -> GeneratedC:
    """physics.h and physics.c of a derivation."""
    # model_prepare computes the constants every other part hoists, so it comes last; the parts before it keep
    # their order, which numbers the constants.
    generation = _generation_of(derivation)
    rhs = _right_hand_side(generation)
    taylor = _model_taylor(generation, rhs)
    targets, values = _point_outputs(derivation.spec, derivation.positions, derivation.velocities)
    outputs = _outputs_body(generation, targets, values)
    constraint_functions = (_constraint_functions(derivation, generation.prepared, generation.state_locals)
                            if derivation.spec.constraints else "")
    # the outputs' rates hold the accelerations a_j, which are the derivatives dx[n + j] from here on
    generation.names.mapping.update({a: sp.Symbol(f"dx[{derivation.n + j}]", real=True)
                                     for j, a in enumerate(generation.accelerations)})
    rates = _rates_body(generation, targets)
    directional = _directional_body(generation, targets, values)
    diagonals = [_diagonal_entry(derivation, derivation.spec, generation.names, j) for j in range(derivation.n)]
    prepare = _prepare_body(generation, rhs, diagonals)
    state_ok = _state_ok_body(generation, rhs.requirements)
    explain = _explanation_body(generation, rhs, diagonals)
    return GeneratedC(_physics_h(generation, rhs, taylor),
                      _physics_c(generation, constraint_functions, prepare=prepare, state_ok=state_ok, explain=explain,
                                 outputs=outputs, rates=rates, directional=directional, taylor=taylor.lines))


def _generation_of(derivation: Derivation) -> _Generation:
    """The C names of the derivation's symbols, with no constant hoisted yet."""
    spec = derivation.spec
    n = derivation.n
    names = _Names()
    parameters = [p for p in spec.parameters if p.name not in FRAMEWORK_PARAMETERS]
    for p in parameters:
        names.mapping[spec.symbols[p.name]] = sp.Symbol(f"c->p_{p.name}", real=True)
    for j, c in enumerate(spec.coordinates):
        names.mapping[spec.symbols[c.name]] = sp.Symbol(f"s_{c.name}", real=True)
        names.mapping[spec.symbols[c.velocity]] = sp.Symbol(f"s_{c.velocity}", real=True)
    for k, F in enumerate(derivation.inputs):
        names.mapping[F] = sp.Symbol(f"u[{k}]", real=True)
    names.mapping[spec.time] = sp.Symbol("t", real=True)
    names.mapping[spec.symbols["d"]] = sp.Symbol("c->d", real=True)  # the damping, in an output's expression
    accelerations = [sp.Symbol(f"a_{j}", real=True) for j in range(n)]
    constants = _Constants({names.mapping[spec.symbols[p.name]] for p in parameters})
    state_locals = [f"    const double s_{c.name} = x[{j}];" for j, c in enumerate(spec.coordinates)] + \
                   [f"    const double s_{c.velocity} = x[{n + j}];" for j, c in enumerate(spec.coordinates)]
    return _Generation(derivation, parameters, names, constants, accelerations, state_locals)


@dataclass
class _RightHandSide:
    """The right-hand side: the body of model_equations and what the other parts take from it."""
    body: list[str]
    requirements: list[sp.Expr]  # prepared
    upper: list[tuple[int, int]]  # the entries of M stored, row by row up to the diagonal
    mass: list[sp.Expr]  # M at upper, prepared
    diagonal: bool
    pivots: list[sp.Expr]  # prepared, checked at run time
    forcing: list[sp.Expr]  # f as solved (over the diagonal of a diagonal M), not prepared
    forces: list[sp.Expr]  # Q likewise
    constant_pivots: list[tuple[int, str]]
    constant_factor_lines: list[str]
    factor_constants: list[str]


def _right_hand_side(generation: _Generation) -> _RightHandSide:
    """model_equations' body, dx = (v, a - d v) with M a = f + Q, and the parts of it the other parts reuse."""
    derivation, spec, n, prepared = generation.derivation, generation.spec, generation.n, generation.prepared
    constants = generation.constants
    body: list[str] = []
    requirements = [prepared(r) for r in spec.require]
    for k, requirement in enumerate(requirements):
        body.append(f"    if (!({c_expr(requirement)} > 0.0)) goto singular; /* require[{k}] */")
    upper = [(i, j) for i in range(n) for j in range(i + 1)]
    mass = [prepared(derivation.M[i, j]) for i, j in upper]
    diagonal = all(derivation.M[i, j] == 0 for i, j in upper if i != j)
    forces_q = list(derivation.Q)
    forcing_f = list(derivation.f)
    pivots: list[sp.Expr] = []
    states = set(spec.q) | set(spec.v) | {spec.time}
    if diagonal:
        # M a = b solves entry by entry: the division goes into the expressions, where constant
        # factors fold into the hoisted constants. A pivot that the object file's ranges and
        # requirements keep positive needs no check.
        for j in range(n):
            inverse = 1 / derivation.M[j, j]
            forcing_f[j] = forcing_f[j] * inverse
            forces_q[j] = forces_q[j] * inverse
            if not (constants.is_constant(prepared(derivation.M[j, j]))
                    or _positive_by_declaration(derivation.M[j, j], spec)):
                pivots.append(prepared(derivation.M[j, j]))
    forcing_f = [_tidy(e, states, spec.v) for e in forcing_f]
    forces_q = [_tidy(e, states, spec.v) for e in forces_q]
    forcing = [prepared(e) for e in forcing_f]
    lines, reduced, replacements = _cse_lines(pivots + mass + forcing, "w")
    body += lines
    for k, pivot in enumerate(reduced[:len(pivots)]):
        body.append(f"    if (!({c_expr(pivot)} > 0.0)) goto singular; /* M not positive definite here */")
    reduced = reduced[len(pivots):]
    mass_c = dict(zip(upper, reduced[:len(upper)]))
    for j in range(n):
        body.append(f"    double b{j} = {c_expr(reduced[len(upper) + j])};")
    if generation.nf:
        forces = _reuse([prepared(e) for e in forces_q], replacements)
        force_lines, force_reduced, _ = _cse_lines(forces, "z", indent="        ")
        body.append("    if (u) {")
        body += force_lines
        body += [f"        b{j} += {c_expr(e)};" for j, e in enumerate(force_reduced) if e != 0]
        body.append("    }")
    if diagonal:
        factor_lines, factor_constants = [f"    const double a{j} = b{j};" for j in range(n)], []
        constant_pivots = [(j, c_expr(m)) for j, m in enumerate(mass_c[(j, j)] for j in range(n))
                           if constants.is_constant(m)]
        constant_factor_lines = []
    else:
        factor_lines, constant_pivots, constant_factor_lines, factor_constants = _ldl_solve(n, mass_c)
    body += factor_lines
    body += [f"    dx[{j}] = s_{c.velocity};" for j, c in enumerate(spec.coordinates)]
    body += [f"    dx[{n + j}] = a{j} - c->d * s_{c.velocity};" for j, c in enumerate(spec.coordinates)]
    if any("goto singular" in line for line in body):
        body += ["    return;", "singular:", f"    {{ int i; for (i = 0; i < {2 * n}; i++) dx[i] = NAN; }}"]
    return _RightHandSide(_with_locals(generation.state_locals, body), requirements, upper, mass, diagonal, pivots,
                          forcing_f, forces_q, constant_pivots, constant_factor_lines, factor_constants)


def _model_taylor(generation: _Generation, rhs: _RightHandSide) -> _TaylorFunction:
    """model_taylor of the right-hand side, from whichever variant of its equations needs fewer convolutions."""
    derivation, spec, prepared = generation.derivation, generation.spec, generation.prepared
    M, nf = derivation.M, generation.nf
    angles = set(spec.q) | {spec.time}
    # the equations as derived, and with products of sines and cosines contracted, the terms collected by
    # their dependence on the state
    contracted = [lambda e: e,
                  lambda e: contract_trigonometry(e, angles, angles | set(spec.v) | set(derivation.inputs))]
    return _taylor_function(spec, generation.n, nf, rhs.diagonal, rhs.pivots,
                            [{key: prepared(variant(M[key])) for key in rhs.upper} for variant in contracted],
                            [[prepared(variant(e)) for e in rhs.forcing] for variant in contracted],
                            [[prepared(variant(e)) for e in rhs.forces] if nf else [] for variant in contracted],
                            generation.state_locals)


def _outputs_body(generation: _Generation, targets: list[str], values: list) -> list[str]:
    """outputs_of's body: the points' positions and velocities, the energies, the further and constraint outputs."""
    derivation, spec, prepared = generation.derivation, generation.spec, generation.prepared
    body = _output_function("real", targets, [prepared(e) for e in values + [derivation.T, derivation.U]],
                            "&real[VR_E_kin], &real[VR_E_pot], NULL, NULL" if generation.has_linear else None)
    if spec.outputs:
        body += _further_outputs("real", [o.name for o in spec.outputs],
                                 [prepared(o.value.xreplace(generation.accelerations_now)) for o in spec.outputs],
                                 derivation.inputs)
    body = _with_locals(generation.real_locals, body)
    if spec.constraints:
        body += _constraint_output_call(derivation.inputs)
    return body


def _rates_body(generation: _Generation, targets: list[str]) -> list[str]:
    """model_output_rates' body: the exact time derivative of every output (a_j in it read as dx[n + j])."""
    derivation, spec, n, prepared = generation.derivation, generation.spec, generation.n, generation.prepared
    q, v, t, accelerations = spec.q, spec.v, spec.time, generation.accelerations
    accelerated = [[total_derivative(x, q, v, accelerations, t) for x in velocity]
                   for velocity in derivation.velocities]
    _, rates = _point_outputs(spec, derivation.velocities, accelerated)
    energy_rates = [total_derivative(e, q, v, accelerations, t) for e in (derivation.T, derivation.U)]
    body = _output_function("rate", targets, [prepared(e) for e in rates + energy_rates],
                            "NULL, NULL, &rate[VR_E_kin], &rate[VR_E_pot]" if generation.has_linear else None)
    if spec.outputs:
        jerk = [sp.Symbol(f"jerk[{n + j}]", real=True) for j in range(n)]
        input_rates = [sp.Symbol(f"du[{k}]", real=True) for k in range(generation.nf)]
        output_rates = [_output_rate(o.value, spec, accelerations, derivation.inputs, input_rates, jerk)
                        for o in spec.outputs]
        uses_jerk = any(o.value.free_symbols & set(spec.accelerations) for o in spec.outputs)
        if uses_jerk:  # the accelerations' rates: their directional derivative along (v, a, du)
            body += [f"    double jerk[{2 * n}], scratch[N_REAL];",
                     "    model_directional(c, t, real, dx, dx, du, jerk, scratch);"]
        body += _further_outputs("rate", [o.name for o in spec.outputs],
                                 [prepared(e.xreplace(generation.accelerations_now)) for e in output_rates],
                                 derivation.inputs)
    body = _with_locals(generation.real_locals, body)
    if spec.constraints:
        body += ["    {", *_inputs_from_real(derivation.inputs),
                 f"        constraint_output_rates(c, t, real, dx, {'u' if generation.nf else 'NULL'}, rate);", "    }"]
    return body


def _directional_body(generation: _Generation, targets: list[str], values: list) -> list[str]:
    """model_directional's body: the derivatives' and the outputs' change along a seed."""
    derivation, n, prepared = generation.derivation, generation.n, generation.prepared
    return _with_locals(
        generation.real_locals + [f"    const double acc{j} = dx[{n + j}] + c->d * s_{c.velocity};"
                                  for j, c in enumerate(generation.spec.coordinates)],
        _directional_lines(derivation, prepared, targets, values, generation.has_linear,
                           _further_output_changes(derivation, prepared, generation.accelerations_now)))


def _prepare_body(generation: _Generation, rhs: _RightHandSide, diagonals: list[tuple[str, str]]) -> list[str]:
    """model_prepare's body: the parameters, constraint laws, hoisted constants, constant pivots and linear model."""
    derivation, spec, n, names = generation.derivation, generation.spec, generation.n, generation.names
    prepare = [f"    c->p_{p.name} = real[VR_{p.name}];" for p in generation.parameters]
    prepare.append("    c->d = real[VR_d];")
    for k, constraint in enumerate(spec.constraints):
        law = f"c->law[{k}]"
        prepare += [f"    {law}.bilateral = {int(constraint.bilateral)};",
                    f"    {law}.compliant = {int(constraint.compliant)};",
                    f"    {law}.restitution = {c_expr(names.to_c(constraint.restitution))};",
                    f"    {law}.stiffness = {c_expr(names.to_c(constraint.stiffness if constraint.compliant else 0))};",
                    f"    {law}.exponent = {constraint.exponent!r};",
                    f"    {law}.damping = {c_expr(names.to_c(constraint.damping))};"]
    prepare += [f"    {c_expr(symbol)} = {c_expr(value)};" for symbol, value in generation.constants.definitions]
    prepare += rhs.constant_factor_lines
    for j, pivot in rhs.constant_pivots:
        text, values = diagonals[j]
        prepare += [f"    if (!({pivot} > 0.0)) {{",
                    f'        snprintf(message, size, "the mass matrix d2T/dv2 is not positive definite for these '
                    f'parameters (pivot {j + 1} of its factorization, of {spec.coordinates[j].velocity}, = %g; '
                    f'{text})", {pivot}{values});',
                    "        return 1;", "    }"]
    if generation.has_linear:
        lin, nf = derivation.linear, generation.nf
        prepare.append("    c->linear = integer[INT_model] == MODEL_LINEAR;")
        prepare.append("    {")
        prepare.append(f"        double M0[{n * n}], K0[{n * n}], B0[{max(1, n * nf)}];")
        prepare.append(f"        const double rest[{n}] = {{{', '.join(c_expr(names.to_c(r)) for r in lin.rest)}}};")
        for i in range(n):
            for j in range(n):
                prepare.append(f"        M0[{i * n + j}] = {c_expr(names.to_c(lin.M0[i, j]))};")
                prepare.append(f"        K0[{i * n + j}] = {c_expr(names.to_c(lin.K0[i, j]))};")
            for k in range(nf):
                prepare.append(f"        B0[{i * nf + k}] = {c_expr(names.to_c(lin.B0[i, k]))};")
        prepare.append(f"        if (linear_model_prepare(&c->lin, M0, K0, B0, rest, {c_expr(names.to_c(lin.U0))}, "
                       "message, size) && c->linear) return 1;")
        prepare.append("    }")
    prepare.append("    return 0;")
    return prepare


def _state_ok_body(generation: _Generation, requirements: list[sp.Expr]) -> list[str]:
    """model_state_ok's body: 1 where the state is finite, its angles keep their precision and requirements hold."""
    n = generation.n
    checks = " && ".join(f"isfinite(x[{i}])" for i in range(2 * n))
    ok_body = [f"    if (!({checks})) return 0;"]
    angles = [(j, c.name) for j, c in enumerate(generation.spec.coordinates) if c.unit == "rad"]
    for j, _ in angles:
        ok_body.append(f"    if (!(fabs(x[{j}]) <= {ANGLE_LIMIT!r})) return 0;")
    for requirement in requirements:
        ok_body.append(f"    if (!({_required(requirement)})) return 0;")
    ok_body.append("    return 1;")
    return _with_locals(generation.state_locals, ok_body)


def _explanation_body(generation: _Generation, rhs: _RightHandSide, diagonals: list[tuple[str, str]]) -> list[str]:
    """model_explain_singularity's body: the message naming the angle, requirement or pivot that is singular."""
    spec = generation.spec
    explain = []
    angles = [(j, c.name) for j, c in enumerate(spec.coordinates) if c.unit == "rad"]
    for j, name in angles:
        explain += [f"    if (fabs(x[{j}]) > {ANGLE_LIMIT!r}) {{",
                    f'        snprintf(message, size, "{name} = %g rad is beyond +-{ANGLE_LIMIT:.10g} rad, where an '
                    f'angle has no precision left for the motion (one ulp is %g rad there)", x[{j}], '
                    f'nextafter(fabs(x[{j}]), INFINITY) - fabs(x[{j}]));', "        return 1;", "    }"]
    for k, (requirement, text) in enumerate(zip(rhs.requirements, spec.require)):
        size = _terms_size(requirement)
        terms = " + ".join(f"|{term}|" for term in sp.sympify(text).args) if size is not None else ""
        bound = (f" above %g, {REQUIRE_MARGIN:g} of {_c_string(terms)} (closer to 0 it is the terms' rounding;"
                 if size is not None else " > 0 (")
        bound_value = f", (double)({REQUIRE_MARGIN!r} * ({c_expr(size)}))" if size is not None else ""
        explain += [f"    if (!({_required(requirement)})) {{",
                    f'        snprintf(message, size, "{_c_string(str(text))} = %g must stay{bound} require[{k}] of '
                    f'the object file)", (double)({c_expr(requirement)}){bound_value});', "        return 1;", "    }"]
    explain_mass, explain_reduced, _ = _cse_lines(rhs.mass, "w")
    explain += explain_mass
    explain += _pivot_report(generation.n, dict(zip(rhs.upper, explain_reduced)), spec, diagonals)
    explain.append("    return 0;")
    return _with_locals(generation.state_locals, explain)


def _physics_h(generation: _Generation, rhs: _RightHandSide, taylor: _TaylorFunction) -> str:
    """physics.h: the object's constants, ModelConst and the inlined right-hand side."""
    derivation, spec, has_linear = generation.derivation, generation.spec, generation.has_linear
    return _HEADER.format(
        taylor_available=1 if taylor.available else 0, taylor_reason=_c_string(taylor.reason),
        taylor_series=max(1, taylor.series), taylor_max_order=TAYLOR_ORDERS[1], gbs_columns=GBS_COLUMNS,
        gbs_smallest_tol=GBS_SMALLEST_TOL,
        identifier=spec.identifier, n=generation.n, nf=generation.nf, has_linear=1 if has_linear else 0,
        split=0 if derivation.split_reason else 1, split_reason=_c_string(derivation.split_reason),
        max_evaluations=MAX_EVALUATIONS_PER_CALL,
        parameter_fields="".join(f" p_{p.name}," for p in generation.parameters).rstrip(","),
        n_constants=max(1, len(generation.constants.definitions)),
        factor_fields="".join(f"    double {name};\n" for name in rhs.factor_constants),
        linear_field="    int linear;\n    LinearModel lin;\n" if has_linear else "",
        constraint_fields=("    ConstraintLaw law[N_CONSTRAINTS];\n    const int32_t *active; /* the FMU state's "
                           "active constraints, a bit each */\n") if spec.constraints else "",
        constraints=_constraint_header(spec),
        equations="model_free_equations" if spec.constraints else "model_equations",
        constrained=_CONSTRAINED_EQUATIONS if spec.constraints else "",
        derivatives="\n".join(rhs.body), file=spec.path.name,
        selected=("    if (c->linear) {\n        linear_model_derivatives(&c->lin, c->d, x, u, dx);\n"
                  "        return;\n    }\n"
                  if has_linear else "") + "    model_equations(c, t, x, u, dx);")


def _physics_c(generation: _Generation, constraint_functions: str, **bodies: list[str]) -> str:
    """physics.c: the bodies of its functions, by their names in _SOURCE, and the constraints' functions."""
    spec = generation.spec
    return _SOURCE.format(
        identifier=spec.identifier, file=spec.path.name, constraint_functions=constraint_functions,
        closed_form=("    if (!c->linear) return 0;\n    linear_model_step(&c->lin, c->d, H, u, x);\n    return 1;"
                     if generation.has_linear else "    (void)c, (void)H, (void)u, (void)x;\n    return 0;"),
        **{name: "\n".join(lines) for name, lines in bodies.items()})


@dataclass
class _TaylorFunction:
    available: bool
    reason: str
    series: int
    lines: list[str]


def _taylor_function(spec, n: int, nf: int, diagonal: bool, pivots: list, mass: dict, forcing: list, forces: list,
                     state_locals: list[str]) -> _TaylorFunction:
    """The body of model_taylor, or one that refuses (with the reason) where a function of the
    equations has no Taylor recurrence here. `mass`, `forcing` and `forces` map each variant of the
    equations (as derived; with products of sines and cosines contracted) to its prepared expressions: the
    one with fewer convolutions is generated."""
    variables = {sp.Symbol(f"s_{c.name}", real=True): f"x[{j}]" for j, c in enumerate(spec.coordinates)}
    variables.update({sp.Symbol(f"s_{c.velocity}", real=True): f"x[{n + j}]" for j, c in enumerate(spec.coordinates)})
    variables.update({sp.Symbol(f"u[{k}]", real=True): f"us[{k}]" for k in range(nf)})
    variables[sp.Symbol("t", real=True)] = "ts"
    try:
        reason = constraints_beyond_free_motion(spec)
        if reason:
            raise TaylorUnavailable(f"{reason}, which its series do not hold")
        code = min((taylor_code(n, mass[variant], diagonal, forcing[variant], forces[variant], variables)
                    for variant in range(len(mass))), key=lambda candidate: candidate.cost)
    except TaylorUnavailable as reason:
        return _TaylorFunction(False, str(reason), 0,
                               ["    (void)c, (void)t, (void)u0, (void)du, (void)order, (void)x, (void)w;",
                                "    return 0;"])
    text = "\n".join(code.first + [line for line, _ in code.later] + [f"{p.a} {p.b}" for p in code.pairs])
    inverses = ", ".join(["0.0"] + [repr(1.0 / k) for k in range(1, TAYLOR_ORDERS[1] + 2)])
    lines = ["    const int forces = u0 != NULL;",
             f"    static const double inverse[TAYLOR_SLOTS + 1] = {{{inverses}}}; /* 1 / k */"]
    if "ts[" in text or "ts," in text:
        lines.append("    double ts[TAYLOR_SLOTS] = {0.0};")
    if "us[" in text:
        lines.append(f"    double us[{nf}][TAYLOR_SLOTS];")
    if not diagonal:
        lines.append(f"    double m0[{n * n}], r[{n}];")
    quotients = sorted(set(re.findall(r"\bz\d+\b", text)), key=lambda name: int(name[1:]))
    if quotients:
        lines.append(f"    double {', '.join(f'{z} = 0.0' for z in quotients)}; /* set with coefficient 0 */")
    lines += ["    int k;", "    (void)forces, (void)du, (void)t;"]
    start = [f"    if (!({c_expr(pivot)} > 0.0)) return 0; /* M not positive definite here */" for pivot in pivots]
    lines += _with_locals([f"{d[:-1]}[0];" for d in state_locals], start)  # coefficient 0: the state
    if "ts[" in text or "ts," in text:
        lines.append("    ts[0] = t;\n    ts[1] = 1.0;")
    if "us[" in text:
        lines += ["    if (forces) {", "        int i;", f"        for (i = 0; i < {nf}; i++) {{",
                  "            memset(us[i], 0, sizeof us[i]);", "            us[i][0] = u0[i];",
                  "            us[i][1] = du ? du[i] : 0.0;", "        }", "    }"]
    lines.append("    if (order < 1) return 1;")
    lines += code.first
    with_forces = any(p.forces for p in code.pairs) or any(only for _, only in code.later)
    if with_forces:
        lines.append("    if (forces) {")
        lines += ["    " + line for line in loop_over_orders(code, True)]
        lines.append("    } else {")
        lines += ["    " + line for line in loop_over_orders(code, False)]
        lines.append("    }")
    else:
        lines += loop_over_orders(code, False)
    lines.append("    return 1;")
    return _TaylorFunction(True, "", code.series, lines)


def _further_outputs(array: str, names: list[str], values: list, inputs: list) -> list[str]:
    """array[VR_<name>] = value for the object file's further outputs, in a block of their own (with the force
    inputs from real where they need them)."""
    lines, reduced, _ = _cse_lines(values, "r", indent="        ")
    lines += [f"        {array}[VR_{name}] = {c_expr(e)};" for name, e in zip(names, reduced)]
    if any(re.search(r"\bu\[", line) for line in lines):
        lines = _inputs_from_real(inputs) + lines
    return ["    {", *lines, "    }"]


def _output_rate(value, spec, accelerations, inputs, input_rates, jerk):
    """d/dt of a further output: along the motion (q' = v, v' = a), the inputs' rates and, for the
    accelerations it holds, their rates (jerk)."""
    rate = total_derivative(value, spec.q, spec.v, accelerations, spec.time)
    rate = rate.xreplace(dict(zip(accelerations, spec.accelerations)))
    rate += sum((sp.diff(value, F) * dF for F, dF in zip(inputs, input_rates)), sp.Integer(0))
    rate += sum((sp.diff(value, a) * da for a, da in zip(spec.accelerations, jerk)), sp.Integer(0))
    return rate


def _further_output_changes(derivation: Derivation, prepared, accelerations_now: dict) -> list[str]:
    """change[VR_<name>] of each further output along the seed, once ddx holds the accelerations' change."""
    spec, n = derivation.spec, derivation.n
    if not spec.outputs:
        return []
    seeds = [sp.Symbol(f"seed_x[{j}]", real=True) for j in range(2 * n)]
    seed_u = [sp.Symbol(f"seed_u[{k}]", real=True) for k in range(len(derivation.inputs))]
    changed = [sp.Symbol(f"ddx[{n + j}]", real=True) for j in range(n)]
    changes = []
    for output in spec.outputs:
        value = output.value
        change = sum((sp.diff(value, x) * dx for x, dx in zip(list(spec.q) + list(spec.v), seeds)), sp.Integer(0))
        change += sum((sp.diff(value, F) * dF for F, dF in zip(derivation.inputs, seed_u)), sp.Integer(0))
        change += sum((sp.diff(value, a) * da for a, da in zip(spec.accelerations, changed)), sp.Integer(0))
        changes.append(prepared(change.xreplace(accelerations_now)))
    return _further_outputs("change", [o.name for o in spec.outputs], changes, derivation.inputs)


def _directional_lines(derivation: Derivation, prepared, targets: list[str], values: list, has_linear: bool,
                       further: list[str]) -> list[str]:
    """The body of model_directional: the exact Jacobian of (v, a) and of the outputs times a seed.
    Differentiating M a = f + Q along the seed (dq, dv, du) gives M da = df + dQ - dM a, solved with
    the same LDL^T factorization as the right-hand side; the damping adds -d dv."""
    spec, n = derivation.spec, derivation.n
    q, v = spec.q, spec.v
    seed_q = [sp.Symbol(f"seed_x[{j}]", real=True) for j in range(n)]
    seed_v = [sp.Symbol(f"seed_x[{n + j}]", real=True) for j in range(n)]
    seed_u = [sp.Symbol(f"seed_u[{k}]", real=True) for k in range(len(derivation.inputs))]
    acceleration = [sp.Symbol(f"acc{j}", real=True) for j in range(n)]  # of M a = f + Q, before damping

    def along_seed(expr, with_inputs: bool = False):
        change = sum((sp.diff(expr, qk) * dq for qk, dq in zip(q, seed_q)), sp.Integer(0))
        change += sum((sp.diff(expr, vk) * dv for vk, dv in zip(v, seed_v)), sp.Integer(0))
        if with_inputs:
            change += sum((sp.diff(expr, F) * du for F, du in zip(derivation.inputs, seed_u)), sp.Integer(0))
        return change

    # the outputs: positions, velocities and energies depend on (q, v) only
    lines, reduced, _ = _cse_lines([prepared(along_seed(e)) for e in values + [derivation.T, derivation.U]], "o")
    lines += [f"    change[VR_{name}] = {c_expr(e)};" for name, e in zip(targets, reduced)]
    lines += [f"    change[VR_E_kin] = {c_expr(reduced[-2])};", f"    change[VR_E_pot] = {c_expr(reduced[-1])};"]
    if has_linear:
        lines += ["    if (c->linear) {",
                  "        linear_model_directional(&c->lin, c->d, real, seed_x, seed_u, ddx, &change[VR_E_kin], "
                  "&change[VR_E_pot]);",
                  "        change[VR_E] = change[VR_E_kin] + change[VR_E_pot];",
                  *["    " + line for line in further], "        return;", "    }"]
    lines.append("    change[VR_E] = change[VR_E_kin] + change[VR_E_pot];")
    # the accelerations
    M = derivation.M
    rhs = [along_seed(derivation.f[j] + derivation.Q[j], with_inputs=True)
           - sum((along_seed(M[j, i]) * acceleration[i] for i in range(n)), sp.Integer(0)) for j in range(n)]
    upper = [(i, j) for i in range(n) for j in range(i + 1)]
    if all(M[i, j] == 0 for i, j in upper if i != j):
        solve_lines, reduced, _ = _cse_lines([prepared(r / M[j, j]) for j, r in enumerate(rhs)], "w")
        lines += solve_lines + [f"    const double a{j} = {c_expr(e)};" for j, e in enumerate(reduced)]
    else:
        mass_lines, reduced, _ = _cse_lines([prepared(M[i, j]) for i, j in upper] + [prepared(r) for r in rhs], "w")
        lines += mass_lines
        lines += [f"    const double b{j} = {c_expr(e)};" for j, e in enumerate(reduced[len(upper):])]
        lines += _ldl_solve(n, dict(zip(upper, reduced[:len(upper)])))[0]  # its constants exist already
    if any(re.search(r"\bu\[", line) for line in lines):  # the force inputs' values, in the order of u
        values_of_u = ", ".join(f"real[VR_{F}]" for F in derivation.inputs)
        lines.insert(0, f"    const double u[{len(derivation.inputs)}] = {{{values_of_u}}};")
    lines += [f"    ddx[{j}] = seed_x[{n + j}];" for j in range(n)]
    lines += [f"    ddx[{n + j}] = a{j} - c->d * seed_x[{n + j}];" for j in range(n)]
    lines += further
    if any("goto singular" in line for line in lines):
        lines += ["    return;", "singular:", f"    {{ int i; for (i = 0; i < {2 * n}; i++) ddx[i] = NAN; }}"]
    return lines


def _point_outputs(spec, positions, velocities):
    """(output names, values) of every point's position and, where it has them, velocity outputs."""
    targets, values = [], []
    for point, position, velocity in zip(spec.points, positions, velocities):
        targets += [point.outputs[axis] for axis in "xyz"[:len(position)]]
        values += list(position)
        if point.velocity:
            targets += [point.outputs[f"v_{axis}"] for axis in "xyz"[:len(velocity)]]
            values += list(velocity)
    return targets, values


def _output_function(array: str, targets: list[str], values: list, linear_arguments: str | None) -> list[str]:
    """array[VR_<target>] = value for each point output, then E_kin, E_pot (the last two values) and E;
    with a linear model, its quadratic energies replace E_kin and E_pot in linear mode."""
    lines, reduced, _ = _cse_lines(values, "w")
    lines += [f"    {array}[VR_{name}] = {c_expr(e)};" for name, e in zip(targets, reduced)]
    lines += [f"    {array}[VR_E_kin] = {c_expr(reduced[-2])};", f"    {array}[VR_E_pot] = {c_expr(reduced[-1])};"]
    if linear_arguments:
        lines.append(f"    if (c->linear) linear_model_energies(&c->lin, real, dx, {linear_arguments});")
    lines.append(f"    {array}[VR_E] = {array}[VR_E_kin] + {array}[VR_E_pot];")
    return lines


def _tidy(expr, states: set[sp.Symbol], velocities: list[sp.Symbol]):
    """Cancels common factors of a quotient, divides each term of the numerator by the parameter-only
    factors of the denominator (r w^2 - (D/m) eps, not (m r w^2 - D eps)/m) and gathers the terms of
    each function of the state, so that parameter factors fold into one hoisted constant
    (k*sin(phi), not k1*sin(phi) + k2*sin(phi))."""
    numerator, denominator = sp.fraction(sp.cancel(sp.sympify(expr)))
    by_parameters, by_states = sp.Integer(1), sp.Integer(1)
    for factor in sp.Mul.make_args(sp.factor(denominator)):
        if factor.free_symbols & states:
            by_states *= factor
        else:
            by_parameters *= factor
    numerator = sp.expand(numerator / by_parameters)
    atoms = sorted((a for a in numerator.atoms(sp.Function) if a.free_symbols & states), key=sp.default_sort_key)
    return sp.collect(numerator, velocities + atoms) / by_states


def _terms_size(requirement: sp.Expr) -> sp.Expr | None:
    """|a| + |b| + ... of a requirement that is a sum a + b + ... (None otherwise: no cancellation)."""
    return sp.Add(*(sp.Abs(term) for term in requirement.args)) if isinstance(requirement, sp.Add) else None


def _required(requirement: sp.Expr) -> str:
    """The C condition of a requirement: positive, and a sum above REQUIRE_MARGIN of its terms' sizes."""
    size = _terms_size(requirement)
    if size is None:
        return f"{c_expr(requirement)} > 0.0"
    return f"{c_expr(requirement)} > {REQUIRE_MARGIN!r} * ({c_expr(size)})"


def _positive_by_declaration(expr, spec) -> bool:
    """Whether the object file guarantees expr > 0 wherever its requirements hold: a positive number
    times parameters with a positive lower bound and required expressions, or their powers."""
    positive = {spec.symbols[p.name] for p in spec.parameters if p.min is not None and p.min > 0}
    required = [sp.expand(r) for r in spec.require]
    coefficient, factors = sp.factor_list(sp.expand(expr))
    if not (coefficient.is_number and coefficient > 0):
        return False
    for factor, multiplicity in factors:
        if factor in positive or any(sp.expand(factor - r) == 0 for r in required):
            continue
        if multiplicity % 2 == 0 and any(sp.expand(factor + r) == 0 for r in required):
            continue
        return False
    return True


def _with_locals(declarations: list[str], lines: list[str]) -> list[str]:
    """The declarations whose variable the lines use, then the lines (no unused-variable warnings)."""
    text = "\n".join(lines)
    used = [d for d in declarations if re.search(rf"\b{d.split()[2]}\b", text)]
    return used + lines


def _c_string(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"').replace("%", "%%")


def _ldl_solve(n: int, mass: dict[tuple[int, int], sp.Expr]):
    """Unrolled LDL^T factorization and solve of M a = b. Factor entries that depend only on
    constants move to model_prepare. Returns (runtime lines, constant pivots, prepare lines)."""
    constant_names: set[str] = set()
    runtime: list[str] = []
    prepare: list[str] = []
    constant_pivots: list[tuple[int, str]] = []
    L: dict[tuple[int, int], str | None] = {}
    D: dict[int, str] = {}

    def is_const(expr_text_symbols: set[str]) -> bool:
        return all(s in constant_names for s in expr_text_symbols)

    def entry(i, j):
        value = mass[(max(i, j), min(i, j))]
        return value

    def deps(expr) -> set[str]:
        return {str(s) for s in sp.sympify(expr).free_symbols}

    def emit(name: str, expr, constant_ok: bool = True):
        text = c_expr(expr)
        if constant_ok and all(s.startswith("c->") or s in constant_names for s in deps(expr)):
            constant_names.add(name)
            prepare.append(f"    c->{name} = {text};")
            return f"c->{name}"
        runtime.append(f"    const double {name} = {text};")
        return name

    # Factorization: names are plain symbols so that later steps can refer to them.
    sym = {}
    for j in range(n):
        value = entry(j, j)
        for k in range(j):
            if L.get((j, k)) is not None:
                value = value - sym[L[(j, k)]] ** 2 * sym[D[k]]
        D[j] = emit(f"D{j}", value)
        sym[D[j]] = sp.Symbol(D[j], real=True)
        if D[j].startswith("c->"):
            constant_pivots.append((j, D[j]))
        else:
            runtime.append(f"    if (!({D[j]} > 0.0)) goto singular; /* M not positive definite here */")
        inverse = emit(f"iD{j}", 1 / sym[D[j]])
        sym[inverse] = sp.Symbol(inverse, real=True)
        D[(j, "inv")] = inverse
        for i in range(j + 1, n):
            value = entry(i, j)
            for k in range(j):
                if L.get((i, k)) is not None and L.get((j, k)) is not None:
                    value = value - sym[L[(i, k)]] * sym[L[(j, k)]] * sym[D[k]]
            value = sp.sympify(value)
            if value == 0:
                L[(i, j)] = None
                continue
            L[(i, j)] = emit(f"L{i}{j}", value * sym[inverse])
            sym[L[(i, j)]] = sp.Symbol(L[(i, j)], real=True)
    # Solve: forward (unit lower), diagonal, backward.
    for i in range(n):
        terms = "".join(f" - {L[(i, k)]} * y{k}" for k in range(i) if L.get((i, k)) is not None)
        runtime.append(f"    const double y{i} = b{i}{terms};")
    for i in reversed(range(n)):
        terms = "".join(f" - {L[(k, i)]} * a{k}" for k in range(i + 1, n) if L.get((k, i)) is not None)
        runtime.append(f"    const double a{i} = y{i} * {D[(i, 'inv')]}{terms};")
    return runtime, constant_pivots, prepare, sorted(constant_names)


def _diagonal_entry(derivation: Derivation, spec, names, j: int) -> tuple[str, str]:
    """A diagonal entry of the mass matrix for a message: its expression and the values of the
    parameters and coordinates in it (format text, C arguments), which name what makes a pivot vanish."""
    entry = sp.factor(sp.trigsimp(derivation.M[j, j]))  # m1*(l1**2 sin**2 + l1**2 cos**2) reads l1**2*m1
    symbols = sorted((s for s in entry.free_symbols if s in names.mapping), key=lambda s: s.name)
    values = " with " + ", ".join(f"{s.name} = %g" for s in symbols) if symbols else ""
    arguments = "".join(f", (double)({c_expr(names.mapping[s])})" for s in symbols)
    return (_c_string(f"its diagonal entry {entry}") + f" = %g{values}",
            f", (double)({c_expr(names.to_c(entry))}){arguments}")


def _pivot_report(n: int, mass: dict[tuple[int, int], sp.Expr], spec, diagonals: list[tuple[str, str]]) -> list[str]:
    """Cold-path LDL^T pivots for the explanation of a singular state, naming the velocity of the pivot
    that vanishes and the parameters and coordinates of its diagonal entry."""
    lines = [f"    double M[{n}][{n}], D[{n}], L[{n}][{n}];", "    int i, j, k;"]
    for (i, j), value in mass.items():
        lines.append(f"    M[{i}][{j}] = {c_expr(value)};" if i == j
                     else f"    M[{i}][{j}] = M[{j}][{i}] = {c_expr(value)};")
    lines += [f"    for (j = 0; j < {n}; j++) {{",
              "        D[j] = M[j][j];",
              "        for (k = 0; k < j; k++) D[j] -= L[j][k] * L[j][k] * D[k];",
              "        if (!(D[j] > 0.0)) {"]
    for j, (text, values) in enumerate(diagonals):
        lines += [f"            {'if' if j == 0 else 'else if'} (j == {j})",
                  '                snprintf(message, size, "the mass matrix d2T/dv2 is not positive definite here '
                  f'(pivot {j + 1} of its factorization, of {spec.coordinates[j].velocity}, = %g; {text})", '
                  f'D[j]{values});']
    lines += ["            return 1;", "        }",
              f"        for (i = j + 1; i < {n}; i++) {{",
              "            L[i][j] = M[i][j];",
              "            for (k = 0; k < j; k++) L[i][j] -= L[i][k] * L[j][k] * D[k];",
              "            L[i][j] /= D[j];", "        }", "    }"]
    return lines


_HEADER = """/* {identifier}: generated from modelDescription/{file} by harness.objects. \
Do not edit: edit the object file. */
#ifndef PHYSICS_H
#define PHYSICS_H

#include <math.h>
#include <stddef.h>

#define N_COORDINATES {n}
#define N_FORCE_INPUTS {nf}
#define HAS_LINEAR_MODEL {has_linear}
/* Stormer-Verlet needs accelerations a(t, q, F) - d v: a constant mass matrix, no velocity in f. */
#define SPLIT_ACCELERATIONS {split}
#define SPLIT_REASON "{split_reason}"
#define MAX_EVALUATIONS_PER_CALL {max_evaluations}.0 /* right-hand sides per fmi2DoStep */
/* The Taylor method: its recurrences (model_taylor) need this many work series, or say why there are none. */
#define TAYLOR_AVAILABLE {taylor_available}
#define TAYLOR_REASON "{taylor_reason}"
#define TAYLOR_SERIES {taylor_series}
#define TAYLOR_MAX_ORDER {taylor_max_order}
/* Gragg-Bulirsch-Stoer: columns of its extrapolation table (harness.fmi.methods). */
#define GBS_MAX_COLUMNS {gbs_columns}
#define GBS_SMALLEST_TOL {gbs_smallest_tol!r}
#include "linear_model.h"
{constraints}
/* Parameters (p_), the damping d and parameter-only subexpressions (k), set by model_prepare. */
typedef struct {{
    double{parameter_fields};
    double d;
    double k[{n_constants}];
{factor_fields}{linear_field}{constraint_fields}}} ModelConst;

/* dx = f(t, x, u) of the object's equations: x = (q, v), dx = (v, a). u == NULL means every force
 * input is zero. Inlined into the integrators' loops (model = linear never reaches them: its closed
 * form takes every step). */
static inline void {equations}(const ModelConst *c, double t, const double *x, const double *u, double *dx)
{{
{derivatives}
}}
{constrained}
/* dx = f(t, x, u) of the model selected by `model`: for Model Exchange and the outputs. */
static inline void model_derivatives(const ModelConst *c, double t, const double *x, const double *u, double *dx)
{{
{selected}
}}

#endif
"""

_SOURCE = """/* {identifier}: generated from modelDescription/{file} by harness.objects. \
Do not edit: edit the object file. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "framework.h"

int model_prepare(const double *real, const int32_t *integer, ModelConst *c, char *message, size_t size)
{{
    (void)integer;
{prepare}
}}

int model_state_ok(const ModelConst *c, const double *x)
{{
    (void)c;
{state_ok}
}}

int model_explain_singularity(const ModelConst *c, double t, const double *x, char *message, size_t size)
{{
{explain}
}}

int model_closed_form_step(const ModelConst *c, double H, const double *u, double *x)
{{
{closed_form}
}}

/* The outputs, inlined into model_outputs and into model_evaluate, where each sine and cosine they share with the
 * derivatives is then computed once. */
#if defined(__GNUC__) || defined(__clang__)
__attribute__((always_inline))
#endif
static inline int outputs_of(const ModelConst *c, double t, const double *dx, double *real)
{{
{outputs}
    return 1;
}}

int model_outputs(const ModelConst *c, double t, const double *dx, double *real)
{{
    return outputs_of(c, t, dx, real);
}}

int model_evaluate(const ModelConst *c, double t, const double *u, double *real)
{{
    model_derivatives(c, t, real, u, real + N_STATES);
    return outputs_of(c, t, real + N_STATES, real);
}}

void model_output_rates(const ModelConst *c, double t, const double *real, const double *dx, const double *du,
                        double *rate)
{{
    (void)du;
{rates}
}}

void model_directional(const ModelConst *c, double t, const double *real, const double *dx, const double *seed_x,
                       const double *seed_u, double *ddx, double *change)
{{
    (void)seed_u;
{directional}
}}

/* Taylor coefficients 1 ... order of the state from x[i][0] at t; u0 (NULL: no forces) and du the
 * inputs and their rates at t; w holds TAYLOR_SERIES work series. 0 where M is not positive definite. */
int model_taylor(const ModelConst *restrict c, double t, const double *restrict u0, const double *restrict du,
                 int order, double (*restrict x)[TAYLOR_SLOTS], double (*restrict w)[TAYLOR_SLOTS])
{{
{taylor}
}}

void model_advance_inputs(double *real, const double *du, double H) {{ advance_inputs_linearly(real, du, H); }}
{constraint_functions}"""


_CONSTRAINED_EQUATIONS = """
/* The motion with the constraint forces (constraints.c): the free motion above, then the forces of the
 * compliant constraints that overlap and of the rigid ones that act. */
INTERNAL int constrain_motion(const ModelConst *c, double t, const double *x, double *dx, double *lambda);
static inline void model_equations(const ModelConst *c, double t, const double *x, const double *u, double *dx)
{
    model_free_equations(c, t, x, u, dx);
    /* free flight, the common case between events, needs no geometry */
    if (N_COMPLIANT > 0 || N_BILATERAL > 0 || (*c->active & RIGID_UNILATERAL_BITS)) constrain_motion(c, t, x, dx, NULL);
}
"""


def _constraint_header(spec) -> str:
    if not spec.constraints:
        return "#define N_CONSTRAINTS 0\n"
    k = len(spec.constraints)
    names = ", ".join(f'"{c.name}"' for c in spec.constraints)
    gaps = ", ".join(f"VR_{c.outputs[0]}" for c in spec.constraints)
    forces = ", ".join(f"VR_{c.outputs[1]}" for c in spec.constraints)
    indicators = ", ".join(f"VR_{c.indicator}" for c in spec.constraints)
    rigid_unilateral = sum(1 << i for i, c in enumerate(spec.constraints) if not c.compliant and not c.bilateral)
    free_motion_only = " || ".join(f"(solver) == SOLVER_{name.upper()}" for name in FREE_MOTION_ONLY)
    return (f"#define N_CONSTRAINTS {k}\n#define N_COMPLIANT {sum(c.compliant for c in spec.constraints)}\n"
            f"#define N_BILATERAL {sum(c.bilateral for c in spec.constraints)}\n"
            f"#define RIGID_UNILATERAL_BITS {rigid_unilateral:#x}\n"
            f"/* the methods built on the free equations: only while no rigid constraint acts */\n"
            f"#define FREE_MOTION_ONLY(solver) ({free_motion_only})\n"
            f"#include \"constraints.h\"\n"
            f"static const char *const CONSTRAINT_NAMES[N_CONSTRAINTS] = {{{names}}};\n"
            f"static const unsigned CONSTRAINT_GAP_VRS[N_CONSTRAINTS] = {{{gaps}}};\n"
            f"static const unsigned CONSTRAINT_FORCE_VRS[N_CONSTRAINTS] = {{{forces}}};\n"
            f"static const unsigned CONSTRAINT_INDICATOR_VRS[N_CONSTRAINTS] = {{{indicators}}};\n")


def _inputs_from_real(inputs: list) -> list[str]:
    if not inputs:
        return []
    return [f"        const double u[{len(inputs)}] = {{{', '.join(f'real[VR_{s}]' for s in inputs)}}};"]


def _constraint_output_call(inputs: list) -> list[str]:
    """model_outputs' last part for an object with constraints: gaps, forces and the compliant energies."""
    return ["    {", *_inputs_from_real(inputs),
            f"        if (!constraint_outputs(c, t, {'u' if inputs else 'NULL'}, real)) return 0;", "    }"]


def _constraint_functions(derivation: Derivation, prepared, state_locals: list[str]) -> str:
    """model_constraints (g, G = dg/dq row by row, g' and gamma = g'' - G a) and model_mass (M, full)."""
    n, terms = derivation.n, derivation.constraints
    values = []
    for term in terms:
        values += [term.gap, *term.G, term.rate, term.gamma]
    lines, reduced, _ = _cse_lines([prepared(v) for v in values], "w")
    width = n + 3
    for k in range(len(terms)):
        g, *G, rate, gamma = reduced[k * width:(k + 1) * width]
        lines.append(f"    g[{k}] = {c_expr(g)};")
        lines += [f"    G[{k * n + j}] = {c_expr(e)};" for j, e in enumerate(G)]
        lines += [f"    rate[{k}] = {c_expr(rate)};", f"    gamma[{k}] = {c_expr(gamma)};"]
    gap_lines, gap_reduced, _ = _cse_lines([prepared(term.gap) for term in terms], "w")
    gap_lines += [f"    g[{k}] = {c_expr(e)};" for k, e in enumerate(gap_reduced)]
    rate_lines, rate_reduced, _ = _cse_lines([prepared(v) for term in terms for v in (term.gap, term.rate)], "w")
    rate_lines += [f"    {'g' if j % 2 == 0 else 'rate'}[{j // 2}] = {c_expr(e)};" for j, e in enumerate(rate_reduced)]
    mass_lines, mass_reduced, _ = _cse_lines([prepared(derivation.M[i, j]) for i in range(n) for j in range(n)], "w")
    mass_lines += [f"    M[{k}] = {c_expr(e)};" for k, e in enumerate(mass_reduced)]
    signature = "const ModelConst *c, double t, const double *x"
    return "\n".join([
        "", "/* The constraints at (t, x): gaps g, their gradients G (a row of N_COORDINATES each), rates g' and",
        " * gamma = g'' - G a. */",
        f"void model_constraints({signature}, double *g, double *G, double *rate, double *gamma)", "{",
        *_with_locals(state_locals, lines + ["    (void)c, (void)t;"]), "}", "",
        "/* The gaps alone (what an event indicator needs between events). */",
        f"void model_gaps({signature}, double *g)", "{",
        *_with_locals(state_locals, gap_lines + ["    (void)c, (void)t;"]), "}", "",
        "/* The gaps and their rates g' (whether a contact can open and close again within a step). */",
        f"void model_gap_rates({signature}, double *g, double *rate)", "{",
        *_with_locals(state_locals, rate_lines + ["    (void)c, (void)t;"]), "}", "",
        "/* The mass matrix d2T/dv2 at (t, x), row by row. */",
        f"void model_mass({signature}, double *M)", "{",
        *_with_locals(state_locals, mass_lines + ["    (void)c, (void)t, (void)x;"]), "}", ""])
