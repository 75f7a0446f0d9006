"""The Taylor method's coefficients in C: Taylor-arithmetic recurrences generated from an object's
equations M(q, t) a = f(q, v, t) + Q(q, t) F, so that model_taylor computes x(t + s) = sum_k x_k s^k
to any order from x_0 = x(t).

Each subexpression of M, f and Q becomes one series w (coefficients w[0], w[1], ...), and coefficient k
of every series follows from coefficients 0 ... k of its operands:
* sums, and products by constants, term by term; products by the Cauchy product (a b)_k = sum_j a_j b_(k-j);
* quotients w = a / b: w_k = (a_k - sum_{j=1..k} b_j w_(k-j)) / b_0;
* square roots w = sqrt(a): w_k = (a_k - sum_{j=1..k-1} w_j w_(k-j)) / (2 w_0);
* powers w = a^r: k a_0 w_k = sum_{j=0..k-1} (r (k - j) - j) a_(k-j) w_j;
* functions with a known derivative, w' = g a' (sin and cos as a pair, sinh and cosh, exp, atan, ...):
  w_k = (1/k) sum_{j=1..k} d_j g_(k-j) with d_j = j a_j kept as a series, where g needs only coefficients
  below k;
* log: w_k = (a_k - (1/k) sum_{j=1..k-1} j w_j a_(k-j)) / a_0.
Then M_0 a_k = b_k - sum_{j=1..k} M_j a_(k-j) (M_0 factored once per step) and, from q' = v and
v' = a - d v, q_(k+1) = v_k / (k + 1) and v_(k+1) = (a_k - d v_k) / (k + 1).

How the C is laid out for speed (the cost of a step of order p is about p^2 / 2 multiply-adds per
convolution): in every convolution the terms with 0 < j < k use only coefficients below k, all known when
order k begins. So each order first runs one loop over j that accumulates all of those inner sums side by
side (independent additions the processor overlaps, each loaded coefficient shared), and only then, in
the order of the expressions, adds the two boundary terms (j = 0 and j = k) of each. Coefficient 0 is
computed before the loop over k, so that no statement tests k; the force terms have a loop of their own
(with inputs) beside the one without; 1 / k comes from a table of constants. And products of sines and
cosines of the coordinates are turned into sines and cosines of their sums and differences where that
makes fewer convolutions (the double pendulum's cos(phi1 - phi2): one sine-cosine pair instead of four
products).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

from harness.objects.c_expression import c_expr

TAYLOR_MAX_ORDER = 30
ACCUMULATORS_PER_LOOP = 12  # inner sums per loop over j: as many as the registers hold beside the operands


class TaylorUnavailable(Exception):
    """The equations use a function without a Taylor recurrence here: the reason, one line."""


@dataclass
class _Node:
    scalar: str | None = None  # a C expression constant over the step
    series: str | None = None  # a C pointer to coefficients: x[i], us[i], ts, w[j]


@dataclass
class _Pair:
    """An inner sum: sum over 0 < j < k of a[j] b[k - j] (half: over 0 < j < k / 2 with b = a)."""
    name: str
    a: str
    b: str
    half: bool
    forces: bool


@dataclass
class TaylorCode:
    series: int          # work series (each TAYLOR_SLOTS doubles)
    first: list[str]     # statements for coefficient 0 of everything, then the state's coefficient 1
    pairs: list[_Pair]   # the inner sums each order k >= 1 accumulates first
    later: list[tuple[str, bool]]  # statements for coefficient k >= 1 (and whether only with forces)
    cost: float          # multiply-adds per order, per unit of k: the convolutions' count


@dataclass
class _Builder:
    variables: dict[sp.Symbol, str]        # state, input and time symbols -> their series
    first: list[str] = field(default_factory=list)
    later: list[tuple[str, bool]] = field(default_factory=list)
    pairs: list[_Pair] = field(default_factory=list)
    memo: dict = field(default_factory=dict)
    rates: dict[str, str] = field(default_factory=dict)  # series a -> the series j a_j
    count: int = 0
    locals_: int = 0
    forces: bool = False                   # building the force terms: computed only with inputs

    def new(self) -> str:
        self.count += 1
        return f"w[{self.count - 1}]"

    def local(self) -> str:
        """A double kept over the step (1 / b_0 of a quotient, say)."""
        self.locals_ += 1
        return f"z{self.locals_ - 1}"

    def pair(self, a: str, b: str, half: bool = False) -> str:
        name = f"p{len(self.pairs)}"
        self.pairs.append(_Pair(name, a, b, half, self.forces))
        return name

    def emit(self, first: str, later: str) -> None:
        self.first.append(f"    if (forces) {{ {first} }}" if self.forces else f"    {first}")
        self.later.append((f"        {later}", self.forces))

    def rate(self, a: str) -> str:
        """The series d_j = j a_j (its coefficient k set as soon as a's is known)."""
        if a not in self.rates:
            d = self.new()
            self.rates[a] = d
            self.emit(f"{d}[0] = 0.0;", f"{d}[k] = kd * {a}[k];")
        return self.rates[a]

    def node(self, expr) -> _Node:
        expr = sp.sympify(expr)
        if expr in self.memo:
            return self.memo[expr]
        result = self._build(expr)
        self.memo[expr] = result
        return result

    def first_coefficient(self, expr) -> str:
        """Coefficient 0 of expr, in C."""
        node = self.node(expr)
        return node.scalar if node.series is None else f"{node.series}[0]"

    def is_scalar(self, expr) -> bool:
        return not (expr.free_symbols & set(self.variables))

    # ---- the operations
    def _build(self, expr) -> _Node:
        if self.is_scalar(expr):
            return _Node(scalar=c_expr(expr))
        if expr.is_Symbol:
            return _Node(series=self.variables[expr])
        if isinstance(expr, sp.Add):
            return self._sum(expr.args)
        if isinstance(expr, sp.Mul):
            return self._product(expr.args)
        if isinstance(expr, sp.Pow):
            return self._power(*expr.args)
        return self._function(expr)

    def _sum(self, args) -> _Node:
        scalars = [a for a in args if self.is_scalar(a)]
        terms = [self.node(a).series for a in args if not self.is_scalar(a)]
        w = self.new()
        constant = f" + {c_expr(sp.Add(*scalars))}" if scalars else ""
        self.emit(f"{w}[0] = {' + '.join(f'{t}[0]' for t in terms)}{constant};",
                  f"{w}[k] = {' + '.join(f'{t}[k]' for t in terms)};")
        return _Node(series=w)

    def _product(self, args) -> _Node:
        scalar = sp.Mul(*[a for a in args if self.is_scalar(a)])
        numerator, denominator = [], []
        for a in args:
            if self.is_scalar(a):
                continue
            if isinstance(a, sp.Pow) and a.exp.is_Integer and a.exp < 0:
                denominator.append(a.base ** -a.exp)
            else:
                numerator.append(a)
        # the product of the series factors once, whatever constant multiplies it where
        top = None if not numerator else (self._chain(numerator) if scalar == 1 and not denominator
                                          else self.node(sp.Mul(*numerator)).series)
        if denominator:  # a constant numerator goes into the quotient
            top = self._quotient(top, c_expr(scalar) if top is None else None, self.node(sp.Mul(*denominator)).series)
            if not numerator:
                return _Node(series=top)
        if scalar == 1:
            return _Node(series=top)
        w = self.new()
        self.emit(f"{w}[0] = {c_expr(scalar)} * {top}[0];", f"{w}[k] = {c_expr(scalar)} * {top}[k];")
        return _Node(series=w)

    def _quotient(self, top: str | None, constant: str | None, bottom: str) -> str:
        """w = top / bottom (top a series, or the constant where it is None)."""
        w, inverse = self.new(), self.local()
        inner = self.pair(bottom, w)
        a0, ak = (f"{top}[0]", f"{top}[k]") if top else (constant, None)
        numerator = f"{ak} - {inner}" if ak else f"-{inner}"
        self.emit(f"{inverse} = 1.0 / {bottom}[0]; {w}[0] = {a0} * {inverse};",
                  f"{w}[k] = ({numerator} - {bottom}[k] * {w}[0]) * {inverse};")
        return w

    def _chain(self, factors) -> str | None:
        """The product of series factors, one Cauchy product at a time (None for no factor)."""
        series = [self.node(f).series for f in sorted(factors, key=sp.default_sort_key)]
        if not series:
            return None
        result = series[0]
        for other in series[1:]:
            result = self._cauchy(result, other)
        return result

    def _cauchy(self, a: str, b: str) -> str:
        w = self.new()
        inner = self.pair(a, b)
        self.emit(f"{w}[0] = {a}[0] * {b}[0];", f"{w}[k] = {inner} + {a}[0] * {b}[k] + {a}[k] * {b}[0];")
        return w

    def _square(self, a: str) -> str:
        w = self.new()
        inner = self.pair(a, a, half=True)
        self.emit(f"{w}[0] = {a}[0] * {a}[0];",
                  f"{w}[k] = 2.0 * ({inner} + {a}[0] * {a}[k]) + ((k & 1) ? 0.0 : {a}[k / 2] * {a}[k / 2]);")
        return w

    def _power(self, base, exponent) -> _Node:
        if not self.is_scalar(exponent):  # b^e = exp(e log b)
            return self.node(sp.exp(exponent * sp.log(base)))
        if self.is_scalar(base):
            return _Node(scalar=c_expr(base ** exponent))
        a = self.node(base).series
        if exponent == 2:
            return _Node(series=self._square(a))
        if exponent.is_Integer and exponent > 2:
            w = self._square(self.node(base ** (exponent // 2)).series)
            return _Node(series=self._cauchy(w, a) if exponent % 2 else w)
        if exponent.is_Integer and exponent < 0:
            return _Node(series=self._quotient(None, "1.0", self.node(base ** -exponent).series))
        w = self.new()
        if exponent == sp.Rational(1, 2):
            inverse = self.local()
            inner = self.pair(w, w)
            self.emit(f"{w}[0] = sqrt({a}[0]); {inverse} = 0.5 / {w}[0];",
                      f"{w}[k] = ({a}[k] - {inner}) * {inverse};")
        else:  # rare: its own loop over j
            r = c_expr(exponent)
            self.emit(f"{w}[0] = pow({a}[0], {r});", f"{w}[k] = taylor_power({a}, {r}, {w}, k);")
        return _Node(series=w)

    def _derivative_rule(self, argument, first: str, derivative, sign: str = "", start: str | None = None) -> _Node:
        """w = F(a) with w(0) = first (C, of a[0]; or `start`, C as it stands) and w' = derivative(w) a'
        (derivative: w -> sympy expression in w's own symbol and the argument)."""
        a = self.node(argument).series
        d = self.rate(a)
        w = self.new()
        own = sp.Dummy("own")
        self.variables[own] = w
        # g's coefficients below k are all w_k needs: g is computed after w at each k
        self.emit("", "")
        index_first, index_later = len(self.first) - 1, len(self.later) - 1
        forces = self.forces
        g = self.node(derivative(own)).series
        inner = self.pair(d, g)
        self.first[index_first] = (f"    if (forces) {{ {w}[0] = {start or first.format(a=f'{a}[0]')}; }}" if forces
                                   else f"    {w}[0] = {start or first.format(a=f'{a}[0]')};")
        self.later[index_later] = (f"        {w}[k] = {sign}(({inner} + {d}[k] * {g}[0]) * inverse[k]);", forces)
        return _Node(series=w)

    def _function(self, expr) -> _Node:
        name = type(expr).__name__
        if name in ("sin", "cos", "sinh", "cosh"):
            a = self.node(expr.args[0]).series
            hyperbolic = name in ("sinh", "cosh")
            d = self.rate(a)
            s, c = self.new(), self.new()
            f0, g0 = ("sinh", "cosh") if hyperbolic else ("sin", "cos")
            sign = "" if hyperbolic else "-"
            sine, cosine = self.pair(d, c), self.pair(d, s)
            # one argument in a local: the compiler then pairs sin and cos into one call of sincos
            self.emit(f"{{ const double angle = {a}[0]; {s}[0] = {f0}(angle); {c}[0] = {g0}(angle); }}",
                      f"{s}[k] = ({sine} + {d}[k] * {c}[0]) * inverse[k]; "
                      f"{c}[k] = {sign}(({cosine} + {d}[k] * {s}[0]) * inverse[k]);")
            self.memo[getattr(sp, f0)(expr.args[0])] = _Node(series=s)
            self.memo[getattr(sp, g0)(expr.args[0])] = _Node(series=c)
            return _Node(series=s if name in ("sin", "sinh") else c)
        argument = expr.args[0]
        if name == "exp":
            return self._derivative_rule(argument, "exp({a})", lambda own: own)
        if name == "tan":
            return self.node(sp.sin(argument) / sp.cos(argument))
        if name == "tanh":
            return self.node(sp.sinh(argument) / sp.cosh(argument))
        if name == "atan":
            return self._derivative_rule(argument, "atan({a})", lambda own: 1 / (1 + argument ** 2))
        if name == "asin":
            return self._derivative_rule(argument, "asin({a})", lambda own: 1 / sp.sqrt(1 - argument ** 2))
        if name == "acos":
            return self._derivative_rule(argument, "acos({a})", lambda own: 1 / sp.sqrt(1 - argument ** 2), "-")
        if name == "atan2":  # atan(y/x) plus the quadrant's constant: atan2 at k = 0, atan's rule after
            y, x = expr.args
            ratio = y / x
            start = f"atan2({self.first_coefficient(y)}, {self.first_coefficient(x)})"
            return self._derivative_rule(ratio, "", lambda own: 1 / (1 + ratio ** 2), start=start)
        if name == "log":
            a = self.node(argument).series
            w = self.new()
            self.emit(f"{w}[0] = log({a}[0]);", f"{w}[k] = taylor_log({a}, {w}, k);")
            return _Node(series=w)
        if name == "Abs":  # smooth on each side of its kink
            a = self.node(argument).series
            w = self.new()
            self.emit(f"{w}[0] = {a}[0] < 0.0 ? -{a}[0] : {a}[0];", f"{w}[k] = {a}[0] < 0.0 ? -{a}[k] : {a}[k];")
            return _Node(series=w)
        if name == "DiracDelta":  # from a kink differentiated twice: zero wherever defined
            return _Node(scalar="0.0")
        if name == "sign":  # constant on each side of its jump
            w = self.new()
            self.emit(f"{w}[0] = {self.first_coefficient(argument)} > 0.0 ? 1.0 : -1.0;", f"{w}[k] = 0.0;")
            return _Node(series=w)
        raise TaylorUnavailable(f"{name} has no Taylor recurrence here")


def contract_trigonometry(expr: sp.Expr, angles: set[sp.Symbol], states: set[sp.Symbol]) -> sp.Expr:
    """expr with each product of sines and cosines of different arguments (functions of `angles`) turned
    into sines and cosines of their sums and differences, even powers of a sine into powers of its cosine,
    and the terms with the same dependence on `states` collected under one factor (factored): the expanded
    cos(phi1) cos(phi2) + sin(phi1) sin(phi2) back to cos(phi1 - phi2), sin(phi)^2 + cos(phi)^2 to 1."""
    def trig(factor) -> bool:
        return isinstance(factor, (sp.sin, sp.cos)) and bool(factor.args[0].free_symbols & angles)

    def term(monomial):
        factors = []
        for factor in sp.Mul.make_args(monomial):
            base, exponent = factor.as_base_exp()
            if trig(base) and exponent.is_Integer and exponent > 0:
                factors += [base] * int(exponent)
            else:
                factors.append(factor)
        trigs = [f for f in factors if trig(f)]
        if len({f.args[0] for f in trigs}) < 2:
            return monomial
        rest = sp.Mul(*[f for f in factors if not trig(f)])
        result = trigs[0]
        for other in trigs[1:]:
            result = sp.expand(_product_to_sum(result, other, trig))
        return rest * result

    def pythagoras(power):  # sin(x)^n = sin(x)^(n mod 2) (1 - cos(x)^2)^(n // 2): sin^2 + cos^2 cancel to 1
        x, n = power.base.args[0], int(power.exp)
        return sp.sin(x) ** (n % 2) * (1 - sp.cos(x) ** 2) ** (n // 2)

    previous = None
    expanded = sp.expand(expr.replace(lambda e: e.is_Pow and isinstance(e.base, sp.sin) and trig(e.base)
                                      and e.exp.is_Integer and e.exp >= 2, pythagoras))
    while expanded != previous:
        previous = expanded
        expanded = sp.expand(sp.Add(*[term(m) for m in sp.Add.make_args(expanded)]))
    collected: dict[sp.Expr, sp.Expr] = {}
    for monomial in sp.Add.make_args(expanded):
        factors = sp.Mul.make_args(monomial)
        varying = sp.Mul(*[f for f in factors if f.free_symbols & states])
        collected[varying] = collected.get(varying, sp.Integer(0)) + sp.Mul(*[f for f in factors
                                                                               if not f.free_symbols & states])
    return sp.Add(*[sp.factor(constant) * varying for varying, constant in collected.items()])


def _product_to_sum(left: sp.Expr, right: sp.Expr, trig) -> sp.Expr:
    """left * right for a sum of terms (each a constant times at most one sine or cosine) and a sine or
    cosine: each product of two by the angle-sum formulas."""
    result = sp.Integer(0)
    for monomial in sp.Add.make_args(left):
        factors = sp.Mul.make_args(monomial)
        found = [f for f in factors if trig(f)]
        if len(found) != 1 or found[0].args[0] == right.args[0]:
            result += monomial * right
            continue
        f = found[0]
        rest = sp.Mul(*[g for g in factors if g is not f])
        x, y = f.args[0], right.args[0]
        if isinstance(f, sp.sin) and isinstance(right, sp.sin):
            pair = (sp.cos(x - y) - sp.cos(x + y)) / 2
        elif isinstance(f, sp.cos) and isinstance(right, sp.cos):
            pair = (sp.cos(x - y) + sp.cos(x + y)) / 2
        elif isinstance(f, sp.sin):
            pair = (sp.sin(x + y) + sp.sin(x - y)) / 2
        else:
            pair = (sp.sin(x + y) - sp.sin(x - y)) / 2
        result += rest * pair
    return result


def taylor_code(n: int, mass: dict[tuple[int, int], sp.Expr], diagonal: bool, forcing: list, forces: list,
                variables: dict[sp.Symbol, str]) -> TaylorCode:
    """The recurrences of M a = forcing + forces, the force terms only with inputs (`forces` in C), for a
    diagonal M both already divided by its diagonal; the expressions are prepared (constants hoisted),
    their states, inputs and time the keys of `variables`."""
    builder = _Builder(dict(variables))

    def coefficient(node: _Node, k: str) -> str:
        return f"{node.series}[{k}]" if node.series else (node.scalar if k == "0" else "0.0")

    forcing_nodes = [builder.node(e) for e in forcing]
    entries = {} if diagonal else {key: builder.node(value) for key, value in mass.items()}
    # after everything else: a subexpression first met among the force terms is computed only with inputs
    builder.forces = True
    force_nodes = [builder.node(e) for e in forces]
    builder.forces = False
    sums = []
    for j in range(n):
        total = builder.new()
        pushed = bool(force_nodes) and forces[j] != 0
        force = f" + (forces ? {coefficient(force_nodes[j], '0')} : 0.0)" if pushed else ""
        builder.emit(f"{total}[0] = {coefficient(forcing_nodes[j], '0')}{force};",
                     f"{total}[k] = {coefficient(forcing_nodes[j], 'k')};")
        if pushed:  # the force's coefficient k, in the loop with inputs
            builder.later.append((f"        {total}[k] += {coefficient(force_nodes[j], 'k')};", True))
        sums.append(total)
    if diagonal:
        accelerations = sums
    else:
        def entry(i: int, j: int) -> _Node:
            return entries[(max(i, j), min(i, j))]
        accelerations = [builder.new() for _ in range(n)]
        fill = " ".join(f"m0[{i * n + j}] = {builder.first_coefficient(mass[(max(i, j), min(i, j))])};"
                        for i in range(n) for j in range(n))
        builder.first.append(f"    {fill}")
        builder.first.append(f"    if (!taylor_factor(m0, {n})) return 0;")
        builder.first += [f"    r[{i}] = {sums[i]}[0];" for i in range(n)]
        shifted = {}
        for i in range(n):
            for j in range(n):
                if entry(i, j).series:
                    shifted[(i, j)] = builder.pair(entry(i, j).series, accelerations[j])
        for i in range(n):
            terms = "".join(f" - ({shifted[(i, j)]} + {entry(i, j).series}[k] * {accelerations[j]}[0])"
                            for j in range(n) if (i, j) in shifted)
            builder.later.append((f"        r[{i}] = {sums[i]}[k]{terms};", False))
        builder.first.append(f"    taylor_solve(m0, {n}, r);")
        builder.later.append((f"        taylor_solve(m0, {n}, r);", False))
        builder.first += [f"    {a}[0] = r[{j}];" for j, a in enumerate(accelerations)]
        builder.later += [(f"        {a}[k] = r[{j}];", False) for j, a in enumerate(accelerations)]
    for k, lines in (("0", builder.first), ("k", None)):
        step = [f"x[{j}][{k} + 1] = x[{n + j}][{k}] * inverse[{k} + 1];" for j in range(n)]
        step += [f"x[{n + j}][{k} + 1] = ({a}[{k}] - c->d * x[{n + j}][{k}]) * inverse[{k} + 1];"
                 for j, a in enumerate(accelerations)]
        if lines is not None:
            lines += [f"    {s}" for s in step]
        else:
            builder.later += [(f"        {s}", False) for s in step]
    cost = sum(0.5 if p.half else 1.0 for p in builder.pairs)
    return TaylorCode(builder.count, builder.first, builder.pairs, builder.later, cost)


def loop_over_orders(code: TaylorCode, forces: bool) -> list[str]:
    """The loop over orders k = 1 ... order - 1 (with the force terms or without): the inner sums first,
    in loops over j of ACCUMULATORS_PER_LOOP sums each, then each coefficient k in turn."""
    pairs = [p for p in code.pairs if forces or not p.forces]
    lines = ["    for (k = 1; k < order && k < TAYLOR_MAX_ORDER; k++) { /* the second bound for the compiler */",
             "        const double kd = (double)k;", "        int j;", "        (void)kd, (void)j;"]
    for half in (False, True):
        group = [p for p in pairs if p.half == half]
        for start in range(0, len(group), ACCUMULATORS_PER_LOOP):
            chunk = group[start:start + ACCUMULATORS_PER_LOOP]
            lines += _inner_loop(chunk, half)
    lines += [text for text, only_with_forces in code.later if text.strip() and (forces or not only_with_forces)]
    lines.append("    }")
    return lines


def _inner_loop(chunk: list[_Pair], half: bool) -> list[str]:
    """One loop over j accumulating the chunk's sums; a chunk of a few sums in two halves (odd and even j),
    so that enough additions run side by side (the simple pendulum's sine and cosine: four, not two)."""
    bound = "2 * j < k" if half else "j < k"
    lines = [f"        double {', '.join(f'{p.name} = 0.0' for p in chunk)};"]
    if len(chunk) > 4:
        lines.append(f"        for (j = 1; {bound}; j++) {{")
        lines += [f"            {p.name} += {p.a}[j] * {p.b}[k - j];" for p in chunk]
        return lines + ["        }"]
    lines.append(f"        double {', '.join(f'{p.name}_even = 0.0' for p in chunk)};")
    lines.append(f"        for (j = 1; {'2 * j + 2 < k' if half else 'j + 1 < k'}; j += 2) {{")
    lines += [f"            {p.name} += {p.a}[j] * {p.b}[k - j]; {p.name}_even += {p.a}[j + 1] * {p.b}[k - j - 1];"
              for p in chunk]
    lines.append("        }")
    lines.append(f"        if ({bound}) {{")
    lines += [f"            {p.name} += {p.a}[j] * {p.b}[k - j];" for p in chunk]
    lines.append("        }")
    return lines + [f"        {p.name} += {p.name}_even;" for p in chunk]
