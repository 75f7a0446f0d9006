"""Scenes of pendulums joined by springs, made by rule: a chain of any length (the repository's
chain and row scene files are written by these functions, and the benchmarks make chains of a
thousand the same way) and the pendulum wave.

A SimplePendulum's bob has two force inputs, F and F2; an inner bob of a chain takes the spring on
its left through F and the one on its right through F2 (an FMI input takes one connection, so the
forces add up inside the FMU).
"""
from __future__ import annotations

import math

BOB = (("x", "x"), ("y", "y"), ("v_x", "vx"), ("v_y", "vy"))  # pendulum output, element input suffix


def element_joint(element: str, end: str, body: str, force: str = "F",
                  outputs: tuple[str, str, str, str] = ("x", "y", "v_x", "v_y")) -> list[list[str]]:
    """The connections of one end (a or b) of an element, a Spring or a Contact, at a body's point (by
    default a pendulum's bob; `outputs` names the point's x, y, v_x and v_y): position and velocity in,
    force back."""
    return [[f"{body}.{output}", f"{element}.{end}_{suffix}"] for output, (_, suffix) in zip(outputs, BOB)] + \
           [[f"{element}.F{end}_{axis}", f"{body}.{force}_{axis}"] for axis in "xy"]


def bob_bonds(pendulum: str, force: str = "F") -> list[list[str]]:
    """The power bonds of a force input pair at a pendulum's bob: the force with the bob's velocity."""
    return [[f"{pendulum}.{force}_{axis}", f"{pendulum}.v_{axis}", f"{pendulum}.{axis}"] for axis in "xy"]


def pendulum_chain(n: int, spacing: float = 1.0, k: float = 10.0, released: int = 0, angle: float = 0.5,
                   name: str | None = None, description: str | None = None, solver: str = "rk4",
                   h: float = 0.002, stop: float = 10.0, step: float = 0.01) -> dict:
    """n SimplePendulums of length 1 m, anchors `spacing` apart on a line, neighbouring bobs joined by
    springs of rest length `spacing` and stiffness k; pendulum `released` starts at `angle`, the others
    at rest. Springs are listed before the pendulums, so Gauss-Seidel hands every spring the bobs at
    the step's start."""
    if n < 1:
        raise ValueError("a chain has at least one pendulum")
    width = len(str(n))
    pendulums = [f"p{i + 1:0{width}d}" for i in range(n)]
    springs = [f"s{i + 1:0{width}d}" for i in range(n - 1)]
    components: dict[str, dict] = {}
    connections: list[list[str]] = []
    bonds: list[list[str]] = []
    for i, spring in enumerate(springs):
        components[spring] = {"fmu": "Spring", "start": {
            "k": k, "c": 0.0, "l0": spacing, "a_x": i * spacing, "a_y": -1.0, "b_x": (i + 1) * spacing, "b_y": -1.0}}
        connections += (element_joint(spring, "a", pendulums[i], "F2")
                        + element_joint(spring, "b", pendulums[i + 1], "F"))
        bonds += bob_bonds(pendulums[i], "F2") + bob_bonds(pendulums[i + 1], "F")
    for i, pendulum in enumerate(pendulums):
        components[pendulum] = {"fmu": "SimplePendulum", "start": {
            "phi": angle if i == released else 0.0, "anchor_x": i * spacing, "solver": solver, "h": h},
            "traces": [["x", "y"]]}
    return {
        "name": name or f"chain of {n} pendulums",
        "description": description or (f"{n} simple pendulums in a row, anchors {spacing:g} m apart, neighbouring "
                                       f"bobs joined by springs of {k:g} N/m; pendulum {released + 1} is released "
                                       f"at {angle:g} rad and its swing travels along the chain."),
        "stop": stop, "step": step, "accuracy": {"position": 0.001},
        "camera": {"scale": min(200.0, 900.0 / max(1.0, (n - 1) * spacing + 2.0)), "frame_rate": 25},
        "components": components, "connections": connections, "bonds": bonds}


def pendulum_wave(n: int = 15, cycle: float = 60.0, first: int = 51, spacing: float = 0.1, angle: float = 0.3,
                  stop: float = 60.0) -> dict:
    """n SimplePendulums, pendulum i (from 0) of the length that makes `first + i` swings in `cycle`
    seconds (small-angle period), all released together at `angle`: they drift out of phase in
    travelling waves and line up again after `cycle` seconds."""
    g = 9.81
    components = {}
    for i in range(n):
        period = cycle / (first + i)
        length = g * (period / (2 * math.pi)) ** 2
        components[f"p{i + 1:02d}"] = {"fmu": "SimplePendulum", "start": {
            "L": round(length, 12), "phi": angle, "anchor_x": round(i * spacing, 12), "solver": "rk4", "h": 0.002},
            "traces": [["x", "y"]]}
    return {
        "name": "pendulum wave",
        "description": f"{n} simple pendulums of graded lengths: pendulum i makes {first} + i swings in "
                       f"{cycle:g} s (small-angle periods), so, released together at {angle:g} rad, they fall out "
                       f"of phase in travelling waves and line up again after {cycle:g} s (at this amplitude the "
                       "periods are about 0.6% longer, so the realignment comes slightly late).",
        "stop": stop, "step": 0.01, "accuracy": {"position": 0.001},
        "camera": {"scale": 400.0, "frame_rate": 25},
        "components": components, "connections": []}


def double_and_cart() -> dict:
    """A double pendulum whose tip is joined by a spring to the cart of a cart-pendulum."""
    components = {
        "spring": {"fmu": "Spring", "start": {"k": 10.0, "c": 0.0, "l0": 1.5, "a_x": 0.0, "a_y": -2.0,
                                              "b_x": 1.5, "b_y": -2.0}},
        "double": {"fmu": "DoublePendulum", "start": {"phi1": 0.3, "phi2": 0.0, "solver": "rk4", "h": 0.002},
                   "traces": [["x1", "y1"], ["x2", "y2"]]},
        "cart": {"fmu": "CartPendulum", "start": {"x": 1.5, "phi": 0.0, "rail_y": -2.0, "solver": "rk4",
                                                  "h": 0.002},
                 "traces": [["cart_x", "cart_y"], ["bob_x", "bob_y"]]},
    }
    connections = [[f"double.{o}", f"spring.a_{s}"] for o, s in (("x2", "x"), ("y2", "y"), ("v_x", "vx"),
                                                                  ("v_y", "vy"))] + \
                  [[f"cart.cart_{o}", f"spring.b_{s}"] for o, s in (("x", "x"), ("y", "y"), ("v_x", "vx"),
                                                                     ("v_y", "vy"))] + \
                  [["spring.Fa_x", "double.F_x"], ["spring.Fa_y", "double.F_y"],
                   ["spring.Fb_x", "cart.F_x"], ["spring.Fb_y", "cart.F_y"]]
    bonds = [["double.F_x", "double.v_x", "double.x2"], ["double.F_y", "double.v_y", "double.y2"],
             ["cart.F_x", "cart.cart_v_x", "cart.cart_x"], ["cart.F_y", "cart.cart_v_y", "cart.cart_y"]]
    return {
        "name": "double pendulum and cart",
        "description": "A double pendulum (links 1 m, anchor at the origin, released at 0.3 rad) whose tip is joined "
                       "by a spring of 10 N/m and rest length 1.5 m to the cart of a cart-pendulum on a rail 2 m "
                       "below the anchor: the spring pulls the cart, the cart's own pendulum swings up.",
        "stop": 10.0, "step": 0.01, "accuracy": {"position": 0.001},
        "camera": {"scale": 150.0, "frame_rate": 25},
        "components": components, "connections": connections, "bonds": bonds}


def repository_scenes() -> dict[str, dict]:
    """The scene files in scenes/ that these rules write, by file name."""
    return {
        "pendulums_in_a_row.json": pendulum_chain(
            3, spacing=1.5, released=1, name="three pendulums in a row",
            description="Three simple pendulums, anchors 1.5 m apart, neighbouring bobs joined by springs of "
                        "10 N/m and rest length 1.5 m; the middle one is released at 0.5 rad and hands its swing "
                        "to both sides."),
        "double_and_cart.json": double_and_cart(),
        "pendulum_wave.json": pendulum_wave(),
        "spring_chain.json": pendulum_chain(10),
    }
