"""SymPy expressions as C, as a person would write them: small integer powers as products, square
roots as sqrt."""
from __future__ import annotations

import sympy as sp
from sympy.printing.c import C99CodePrinter


class _Printer(C99CodePrinter):
    """Small integer powers as products, as a person would write them."""

    def _print_Pow(self, expr):
        base, exponent = expr.args
        if exponent.is_Integer and 2 <= int(exponent) <= 4:
            b = self.parenthesize(base, 100)
            return "(" + "*".join([b] * int(exponent)) + ")"
        if exponent.is_Integer and -4 <= int(exponent) <= -1:
            b = self.parenthesize(base, 100)
            return "(1.0/(" + "*".join([b] * -int(exponent)) + "))"
        if exponent == sp.Rational(1, 2):
            return f"sqrt({self._print(base)})"
        if exponent == sp.Rational(-1, 2):
            return f"(1.0/sqrt({self._print(base)}))"
        return super()._print_Pow(expr)

    def _print_DiracDelta(self, expr):
        # from differentiating Abs or sign twice: zero wherever the expression is defined (a kink's
        # impulse is not a number the FMU can hand out)
        return "0.0"


_PRINTER = _Printer()


def c_expr(expr) -> str:
    return _PRINTER.doprint(sp.sympify(expr))
