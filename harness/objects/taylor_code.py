"""The Taylor method's coefficients in C: Taylor-arithmetic recurrences generated from an object's
equations M(q, t) a = f(q, v, t) + Q(q, t) F, so that model_taylor computes x(t + s) = sum_k x_k s^k
to any order from x_0 = x(t).

Each subexpression of M, f and Q becomes one series w (coefficients w[0], w[1], ...), and coefficient k
of every series follows from coefficients 0 ... k of its operands:
* sums, and products by constants, term by term; products by the Cauchy product;
* quotients w = a / b: w_k = (a_k - sum_{j=1..k} b_j w_(k-j)) / b_0;
* square roots w = sqrt(a): w_k = (a_k - sum_{j=1..k-1} w_j w_(k-j)) / (2 w_0);
* powers w = a^r: k a_0 w_k = sum_{j=0..k-1} (r (k - j) - j) a_(k-j) w_j;
* functions with a known derivative, w' = g a' (sin and cos as a pair, sinh and cosh, exp, atan, ...):
  w_k = (1/k) sum_{j=1..k} j a_j g_(k-j), where g needs only coefficients below k (a pair in one pass over
  the j a_j it shares, kept as a series);
* log: w_k = (a_k - (1/k) sum_{j=1..k-1} j w_j a_(k-j)) / a_0.
Then M_0 a_k = b_k - sum_{j=1..k} M_j a_(k-j) (M_0 factored once per step) and, from q' = v and
v' = a - d v, q_(k+1) = v_k / (k + 1) and v_(k+1) = (a_k - d v_k) / (k + 1), each division a product with
1 / (k + 1), divided once per order (inverse_next; inverse_k = 1 / k from the order before).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

from harness.objects.c_expression import c_expr

TAYLOR_MAX_ORDER = 30


class TaylorUnavailable(Exception):
    """The equations use a function without a Taylor recurrence here: the reason, one line."""


@dataclass
class _Node:
    scalar: str | None = None  # a C expression constant over the step
    series: str | None = None  # a C pointer to coefficients: x[i], us[i], ts, w[j]


@dataclass
class TaylorCode:
    series: int          # work series (each TAYLOR_SLOTS doubles)
    body: list[str]      # statements for coefficient k of everything, then the state's k + 1


@dataclass
class _Builder:
    variables: dict[sp.Symbol, str]        # state, input and time symbols -> their series
    lines: list[str] = field(default_factory=list)
    memo: dict = field(default_factory=dict)
    count: int = 0
    forces: bool = False                   # building the force terms: computed only with inputs

    def new(self) -> str:
        self.count += 1
        return f"w[{self.count - 1}]"

    def emit(self, text: str) -> None:
        self.lines.append(f"        if (forces) {text}" if self.forces else f"        {text}")

    def node(self, expr) -> _Node:
        expr = sp.sympify(expr)
        if expr in self.memo:
            return self.memo[expr]
        result = self._build(expr)
        self.memo[expr] = result
        return result

    def first(self, expr) -> str:
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
        constant = f" + (k == 0 ? {c_expr(sp.Add(*scalars))} : 0.0)" if scalars else ""
        self.emit(f"{w}[k] = {' + '.join(f'{t}[k]' for t in terms)}{constant};")
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
        if denominator:
            bottom = self.node(sp.Mul(*denominator))
            w = self.new()
            if top is None:  # scalar / series
                self.emit(f"{w}[k] = taylor_quotient(k == 0 ? {c_expr(scalar)} : 0.0, {bottom.series}, {w}, k);")
                return _Node(series=w)
            self.emit(f"{w}[k] = taylor_quotient({top}[k], {bottom.series}, {w}, k);")
            top = w
        if scalar == 1:
            return _Node(series=top)
        w = self.new()
        self.emit(f"{w}[k] = {c_expr(scalar)} * {top}[k];")
        return _Node(series=w)

    def _chain(self, factors) -> str | None:
        """The product of series factors, one Cauchy product at a time (None for no factor)."""
        series = [self.node(f).series for f in sorted(factors, key=sp.default_sort_key)]
        if not series:
            return None
        result = series[0]
        for other in series[1:]:
            w = self.new()
            self.emit(f"{w}[k] = taylor_product({result}, {other}, k);")
            result = w
        return result

    def _power(self, base, exponent) -> _Node:
        if not self.is_scalar(exponent):  # b^e = exp(e log b)
            return self.node(sp.exp(exponent * sp.log(base)))
        if self.is_scalar(base):
            return _Node(scalar=c_expr(base ** exponent))
        a = self.node(base).series
        w = self.new()
        if exponent == 2:
            self.emit(f"{w}[k] = taylor_square({a}, k);")
        elif exponent.is_Integer and exponent > 2:
            half = self.node(base ** (exponent // 2)).series
            self.emit(f"{w}[k] = taylor_square({half}, k);")
            if exponent % 2:
                odd = self.new()
                self.emit(f"{odd}[k] = taylor_product({w}, {a}, k);")
                return _Node(series=odd)
        elif exponent.is_Integer and exponent < 0:
            inner = self.node(base ** -exponent).series
            self.emit(f"{w}[k] = taylor_quotient(k == 0 ? 1.0 : 0.0, {inner}, {w}, k);")
        elif exponent == sp.Rational(1, 2):
            self.emit(f"{w}[k] = k == 0 ? sqrt({a}[0]) : taylor_sqrt({a}, {w}, k);")
        else:
            r = c_expr(exponent)
            self.emit(f"{w}[k] = k == 0 ? pow({a}[0], {r}) : taylor_power({a}, {r}, {w}, k);")
        return _Node(series=w)

    def _derivative_rule(self, argument, first: str, derivative, sign: str = "") -> _Node:
        """w = F(a) with w(0) = first (C, of a[0]) and w' = derivative(w) a' (derivative: w -> sympy
        expression in w's own symbol and the argument)."""
        a = self.node(argument).series
        w = self.new()
        own = sp.Dummy("own")
        self.variables[own] = w
        self.emit(f"{w}[k] = k == 0 ? {first.format(a=f'{a}[0]')} : {sign}taylor_chain({a}, DERIVATIVE, k);")
        index = len(self.lines) - 1
        g = self.node(derivative(own)).series
        self.lines[index] = self.lines[index].replace("DERIVATIVE", g)
        # g's coefficient k - 1 is all w_k needs: g is computed after w at each k
        return _Node(series=w)

    def _function(self, expr) -> _Node:
        name = type(expr).__name__
        if name in ("sin", "cos", "sinh", "cosh"):
            a = self.node(expr.args[0]).series
            hyperbolic = name in ("sinh", "cosh")
            s, c, d = self.new(), self.new(), self.new()  # d: the coefficients j a_j both sums share
            f0, g0 = ("sinh", "cosh") if hyperbolic else ("sin", "cos")
            sign = "1.0" if hyperbolic else "-1.0"
            self.emit(f"if (k == 0) {{ {s}[0] = {f0}({a}[0]); {c}[0] = {g0}({a}[0]); }} else "
                      f"taylor_sincos({a}, {d}, {s}, {c}, {sign}, inverse_k, k);")
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
            a = self.node(ratio).series
            first = f"atan2({self.first(y)}, {self.first(x)})"
            w = self.new()
            self.emit(f"{w}[k] = k == 0 ? {first} : taylor_chain({a}, DERIVATIVE, k);")
            index = len(self.lines) - 1
            g = self.node(1 / (1 + ratio ** 2)).series
            self.lines[index] = self.lines[index].replace("DERIVATIVE", g)
            return _Node(series=w)
        if name == "log":
            a = self.node(argument).series
            w = self.new()
            self.emit(f"{w}[k] = k == 0 ? log({a}[0]) : taylor_log({a}, {w}, k);")
            return _Node(series=w)
        if name == "Abs":  # smooth on each side of its kink
            a = self.node(argument).series
            w = self.new()
            self.emit(f"{w}[k] = {a}[0] < 0.0 ? -{a}[k] : {a}[k];")
            return _Node(series=w)
        if name == "DiracDelta":  # from a kink differentiated twice: zero wherever defined
            return _Node(scalar="0.0")
        if name == "sign":  # constant on each side of its jump
            w = self.new()
            self.emit(f"{w}[k] = k == 0 ? ({self.first(argument)} > 0.0 ? 1.0 : -1.0) : 0.0;")
            return _Node(series=w)
        raise TaylorUnavailable(f"{name} has no Taylor recurrence here")



def taylor_code(n: int, mass: dict[tuple[int, int], sp.Expr], diagonal: bool, forcing: list, forces: list,
                variables: dict[sp.Symbol, str]) -> TaylorCode:
    """The body of the loop over k of model_taylor: M a = forcing + forces, the force terms only with
    inputs (`forces` in C), for a diagonal M both already divided by its diagonal; the expressions are
    prepared (constants hoisted), their states, inputs and time the keys of `variables`."""
    builder = _Builder(dict(variables))

    def coefficient(node: _Node) -> str:
        return f"{node.series}[k]" if node.series else f"(k == 0 ? {node.scalar} : 0.0)"

    forcing_nodes = [builder.node(e) for e in forcing]
    entries = {} if diagonal else {key: builder.node(value) for key, value in mass.items()}
    # after everything else: a subexpression first met among the force terms is computed only with inputs
    builder.forces = True
    force_nodes = [builder.node(e) for e in forces]
    builder.forces = False
    sums = []
    for j in range(n):
        total = builder.new()
        force = f" + (forces ? {coefficient(force_nodes[j])} : 0.0)" if force_nodes and forces[j] != 0 else ""
        builder.emit(f"{total}[k] = {coefficient(forcing_nodes[j])}{force};")
        sums.append(total)
    if diagonal:
        accelerations = sums
    else:
        def entry(i: int, j: int) -> _Node:
            return entries[(max(i, j), min(i, j))]
        accelerations = [builder.new() for _ in range(n)]
        fill = " ".join(f"m0[{i * n + j}] = {builder.first(mass[(max(i, j), min(i, j))])};"
                        for i in range(n) for j in range(n))
        builder.emit(f"if (k == 0) {{ {fill} if (!taylor_factor(m0, {n})) return 0; }}")
        for i in range(n):
            shifted = "".join(f" - taylor_shifted({entry(i, j).series}, {accelerations[j]}, k)"
                              for j in range(n) if entry(i, j).series)
            builder.emit(f"r[{i}] = {sums[i]}[k]{shifted};")
        builder.emit(f"taylor_solve(m0, {n}, r);")
        builder.lines += [f"        {a}[k] = r[{j}];" for j, a in enumerate(accelerations)]
    builder.lines += [f"        x[{j}][k + 1] = x[{n + j}][k] * inverse_next;" for j in range(n)]
    builder.lines += [f"        x[{n + j}][k + 1] = ({a}[k] - c->d * x[{n + j}][k]) * inverse_next;"
                      for j, a in enumerate(accelerations)]
    return TaylorCode(builder.count, builder.lines)
