"""The equations section of an object's documentation page (MathML: renders in any browser offline)."""
from __future__ import annotations

import html

import sympy as sp
from sympy.printing.mathml import mathml

from harness.objects.derivation import Derivation, readable


def _math(expr) -> str:
    return f'<math display="inline">{mathml(sp.sympify(expr), printer="presentation")}</math>'


def equations_html(derivation: Derivation) -> str:
    spec = derivation.spec
    n = derivation.n
    q = ", ".join(c.name for c in spec.coordinates)
    rows = ["<h2>Equations</h2>",
            f"<p>{html.escape(spec.description)}. Generated from the object file <code>{html.escape(spec.path.name)}"
            f"</code> by Lagrange's equations of the second kind. Generalized coordinates q = ({html.escape(q)}), "
            f"velocities v = ({html.escape(', '.join(c.velocity for c in spec.coordinates))}).</p>",
            "<ul>",
            f"<li>Kinetic energy T = {_math(spec.T)}</li>",
            f"<li>Potential energy U = {_math(spec.U)}</li>",
            "</ul>",
            "<p>With L = T &minus; U and p = &part;T/&part;v: M(q, t) a = f(q, v, t) + Q(q, t, F), then each "
            "acceleration gets &minus;d v (damping), where M = &part;&sup2;T/&part;v&sup2;, "
            "f = &part;L/&part;q &minus; (&part;p/&part;q) v &minus; &part;p/&part;t and "
            "Q<sub>j</sub> = &Sigma; F&middot;&part;r/&part;q<sub>j</sub> over the force inputs.</p>",
            "<table><tr><th>j</th><th>coordinate</th><th>row j of M</th><th>f<sub>j</sub></th>"
            "<th>Q<sub>j</sub></th></tr>"]
    shown = readable([*derivation.M, *derivation.f, *derivation.Q])  # one clock for the page
    M, f, Q = shown[:n * n], shown[n * n:n * n + n], shown[n * n + n:]
    for j, c in enumerate(spec.coordinates):
        row = ", ".join(_math(M[j * n + k]) for k in range(n))
        rows.append(f"<tr><td>{j + 1}</td><td>{html.escape(c.name)}</td><td>{row}</td>"
                    f"<td>{_math(f[j])}</td><td>{_math(Q[j])}</td></tr>")
    rows.append("</table>")
    rows.append("<h3>Points</h3><ul>")
    for point, position in zip(spec.points, derivation.positions):
        coordinates = ", ".join(_math(x) for x in point.position)
        names = ", ".join(point.outputs.values())
        rows.append(f"<li>{html.escape(point.name)} = ({coordinates}); outputs {html.escape(names)}</li>")
    rows.append("</ul>")
    if spec.outputs:
        rows.append("<h3>Further outputs</h3><ul>")
        for output in spec.outputs:
            unit = f" ({html.escape(output.unit)})" if output.unit else ""
            rows.append(f"<li>{html.escape(output.name)}{unit} = {_math(output.value)}</li>")
        rows.append("</ul>")
    if spec.forces:
        rows.append("<h3>Force inputs</h3><ul>")
        for force in spec.forces:
            rows.append(f"<li>{html.escape(', '.join(force.inputs.values()))} on {html.escape(force.point)}</li>")
        rows.append("</ul>")
    if spec.require:
        rows.append("<p>Singular where one of these is not positive: "
                    + ", ".join(_math(r) for r in spec.require) + "</p>")
    if derivation.linear is not None:
        lin = derivation.linear
        rest = ", ".join(f"{html.escape(c.name)} = {_math(r)}" for c, r in zip(spec.coordinates, lin.rest))
        rows.append(f"<h3>Linear model (<code>model = linear</code>)</h3><p>About the rest state {rest}: "
                    f"M<sub>0</sub> a + K<sub>0</sub> (q &minus; q<sub>rest</sub>) = B<sub>0</sub> F &minus; d "
                    f"M<sub>0</sub> v with M<sub>0</sub> = {_math(lin.M0)}, K<sub>0</sub> = {_math(lin.K0)}, solved "
                    f"in closed form over each communication step through its normal modes, forces held at their "
                    f"mid-step value. E_kin and E_pot are then the quadratic approximations.</p>")
    else:
        rows.append(f"<p>No linear model: {html.escape(derivation.linear_reason)}.</p>")
    rows.append("<p>Integrator: chosen by <code>solver</code> with internal step <code>h</code> (rkf45: step "
                "control on <code>tol</code>; gbs: order and step control on <code>tol</code>; taylor: order "
                "<code>taylor_order</code>, step control on <code>tol</code> or the fixed step <code>h</code> at "
                "<code>tol</code> = 0).</p>")
    return "\n".join(rows) + "\n"
