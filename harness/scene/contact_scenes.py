"""Scenes of objects that touch across FMUs, joined by Contact elements, made by rule.

A SimplePendulum's bob has two force inputs, F and F2: a ball between two neighbours takes its left
contact through F and its right one through F2. Contacts are listed before the pendulums, so that
Gauss-Seidel hands every contact the balls at the step's start (it moves them by their velocities over
the step itself).
"""
from __future__ import annotations

import math

from harness.scene.spring_scenes import bob_bonds, element_joint

STEEL_STIFFNESS = 1.465e10  # Hertz stiffness of two steel balls of radius 0.02 m [N/m^1.5] (as the HertzCradle's)
TIP = ("x2", "y2", "v_x", "v_y")  # a DoublePendulum's tip
CART = ("cart_x", "cart_y", "cart_v_x", "cart_v_y")  # a CartPendulum's cart


def hertz_stiffness(radius_a: float, radius_b: float, modulus: float = 200e9, poisson: float = 0.3) -> float:
    """Hertz's k = 4/3 E* sqrt(R*) of two spheres of one material, E* = E / (2 (1 - nu^2)) and
    R* = R_a R_b / (R_a + R_b) (steel by default), to four digits [N/m^1.5]."""
    k = 4 / 3 * modulus / (2 * (1 - poisson ** 2)) * math.sqrt(radius_a * radius_b / (radius_a + radius_b))
    return float(f"{k:.4g}")


def pendulum_cradle(n: int = 5, length: float = 0.3, mass: float = 0.25, radius: float = 0.02,
                    released: int = 1, angle: float = -0.5, stop: float = 0.5, step: float = 1e-5,
                    solver: str = "nystrom5", h: float = 1e-5) -> dict:
    """Newton's cradle of n SimplePendulum FMUs (balls of `mass` on strings of `length`, pivots 2 `radius`
    apart, so that the balls touch at rest), neighbours joined by n - 1 Contact elements (steel); the first
    `released` balls start at `angle`. The same cradle as the HertzCradle object, in separate FMUs."""
    if n < 2 or not 1 <= released < n:
        raise ValueError("a cradle has at least two balls, and at least one ball is left hanging")
    pendulums = [f"ball{i + 1}" for i in range(n)]
    contacts = [f"contact{i + 1}{i + 2}" for i in range(n - 1)]
    pivots = [(2 * i - (n - 1)) * radius for i in range(n)]
    components: dict[str, dict] = {}
    connections: list[list[str]] = []
    bonds: list[list[str]] = []
    for i, contact in enumerate(contacts):
        components[contact] = {"fmu": "Contact", "start": {
            "k": STEEL_STIFFNESS, "c": 0.0, "R_a": radius, "R_b": radius,
            "a_x": pivots[i], "a_y": -length, "b_x": pivots[i + 1], "b_y": -length}}
        connections += element_joint(contact, "a", pendulums[i], "F2") + \
            element_joint(contact, "b", pendulums[i + 1], "F")
        bonds += bob_bonds(pendulums[i], "F2") + bob_bonds(pendulums[i + 1], "F")
    for i, pendulum in enumerate(pendulums):
        components[pendulum] = {"fmu": "SimplePendulum", "start": {
            "L": length, "m": mass, "anchor_x": pivots[i], "phi": angle if i < released else 0.0,
            "solver": solver, "h": h}, "traces": [["x", "y"]]}
    return {
        "name": f"Newton's cradle of {n} FMUs",
        "description": f"Newton's cradle of {n} steel balls, each a SimplePendulum FMU (strings of {length:g} m, "
                       f"{mass:g} kg), neighbours joined by Contact elements (Hertz); ball 1 is let go from "
                       f"{angle:g} rad: the strike travels through the row as a wave in about a millisecond.",
        "stop": stop, "step": step, "accuracy": {"position": 0.001},
        "camera": {"scale": 1500.0, "frame_rate": 25},
        "components": components, "connections": connections, "bonds": bonds}


def released_cradle(step: float, stop: float = 0.5) -> dict:
    """Newton's cradle of five steel balls (R = 0.02 m, m = 0.26 kg, L = 0.5 m, k = 1.5e10 N/m^1.5), ball 1 let go
    from -0.3 rad, each ball's solver and step the FMU's defaults, rows every `step`: the strike at 0.355 s, at
    0.66 m/s. The scene that showed a contact stepped through at an ordinary output interval."""
    data = pendulum_cradle(5, length=0.5, mass=0.26, angle=-0.3, stop=stop, step=step)
    for component in data["components"].values():
        if component["fmu"] == "Contact":
            component["start"]["k"] = 1.5e10
        else:
            del component["start"]["solver"], component["start"]["h"]
    return data


def ball_row(radii: list[float], masses: list[float], length: float = 0.5, angle: float = -0.3,
             stiffness_scale: float = 1.0, stop: float = 0.5, step: float = 1e-3,
             solver: str | None = None, h: float | None = None) -> dict:
    """A row of SimplePendulum balls of the given radii and masses on strings of `length`, each pivot as far from
    the next as their radii reach (they touch at rest, the gaps zero to a rounding), neighbours joined by Contact
    elements of Hertz's steel stiffness times `stiffness_scale`; ball 1 starts at `angle`. The solver and its step
    are the FMUs' defaults unless given."""
    if len(radii) != len(masses) or len(radii) < 2:
        raise ValueError("a row has at least two balls, each with a radius and a mass")
    data = pendulum_cradle(len(radii), length=length, angle=angle, stop=stop, step=step)
    pivots = [0.0]
    for left, right in zip(radii, radii[1:]):
        pivots.append(pivots[-1] + left + right)
    for i, (radius, mass) in enumerate(zip(radii, masses)):
        start = data["components"][f"ball{i + 1}"]["start"]
        start.update(m=mass, anchor_x=pivots[i])
        del start["solver"], start["h"]
        start.update({name: value for name, value in (("solver", solver), ("h", h)) if value is not None})
    for i in range(len(radii) - 1):
        start = data["components"][f"contact{i + 1}{i + 2}"]["start"]
        start.update(R_a=radii[i], R_b=radii[i + 1], a_x=pivots[i], b_x=pivots[i + 1],
                     k=hertz_stiffness(radii[i], radii[i + 1]) * stiffness_scale)
    data["name"] = f"a row of {len(radii)} balls"
    data["description"] = (f"{len(radii)} steel balls of radii {', '.join(f'{r:g}' for r in radii)} m and masses "
                           f"{', '.join(f'{m:g}' for m in masses)} kg on strings of {length:g} m, touching at rest; "
                           f"ball 1 is let go from {angle:g} rad.")
    return data


def double_strikes_ball(radius: float = 0.05, angle: float = -0.6, stop: float = 1.5, step: float = 1e-5) -> dict:
    """A double pendulum (links of 1 m) whose tip, a steel ball, swings from `angle` into a steel ball of
    0.5 kg resting on a string of 2 m (a SimplePendulum: the string stays taut, its tension well above zero)."""
    k = hertz_stiffness(radius, radius)
    components = {
        "contact": {"fmu": "Contact", "start": {"k": k, "c": 0.0, "R_a": radius, "R_b": radius,
                                                "a_x": -2 * radius, "a_y": -2.0, "b_x": 0.0, "b_y": -2.0}},
        "double": {"fmu": "DoublePendulum", "start": {"anchor_x": -2 * radius, "phi1": angle, "phi2": angle,
                                                      "solver": "nystrom5", "h": 1e-4},
                   "traces": [["x1", "y1"], ["x2", "y2"]]},
        "ball": {"fmu": "SimplePendulum", "start": {"L": 2.0, "m": 0.5, "phi": 0.0, "solver": "nystrom5", "h": 1e-4},
                 "traces": [["x", "y"]]},
    }
    connections = element_joint("contact", "a", "double", outputs=TIP) + element_joint("contact", "b", "ball")
    bonds = [["double.F_x", "double.v_x", "double.x2"], ["double.F_y", "double.v_y", "double.y2"], *bob_bonds("ball")]
    return {
        "name": "double pendulum strikes a ball",
        "description": f"A double pendulum (links of 1 m, 1 kg each) is let go from {angle:g} rad; its tip, a steel "
                       f"ball of radius {radius:g} m, strikes a steel ball of 0.5 kg resting on a string of 2 m "
                       "beside it (a Contact element between them). The contact lasts about a tenth of a millisecond.",
        "stop": stop, "step": step, "accuracy": {"position": 0.001},
        "camera": {"scale": 150.0, "frame_rate": 25},
        "components": components, "connections": connections, "bonds": bonds}


def colliding_carts(radius: float = 0.1, speed: float = 1.0, stop: float = 1.5, step: float = 1e-5) -> dict:
    """Two cart-pendulums on one rail, their carts bodies of `radius` with steel's stiffness: the left one rolls
    at `speed` into the right one at rest; the carts exchange most of their motion and both pendulums swing."""
    k = hertz_stiffness(radius, radius)
    components = {
        "contact": {"fmu": "Contact", "start": {"k": k, "c": 0.0, "R_a": radius, "R_b": radius,
                                                "a_x": -0.5, "b_x": 0.5}},
        "left": {"fmu": "CartPendulum", "start": {"x": -0.5, "v": speed, "phi": 0.0, "solver": "nystrom5", "h": 1e-4},
                 "traces": [["cart_x", "cart_y"], ["bob_x", "bob_y"]]},
        "right": {"fmu": "CartPendulum", "start": {"x": 0.5, "v": 0.0, "phi": 0.0, "solver": "nystrom5", "h": 1e-4},
                  "traces": [["cart_x", "cart_y"], ["bob_x", "bob_y"]]},
    }
    connections = element_joint("contact", "a", "left", outputs=CART) + \
        element_joint("contact", "b", "right", outputs=CART)
    bonds = [[f"{cart}.F_{axis}", f"{cart}.cart_v_{axis}", f"{cart}.cart_{axis}"] for cart in ("left", "right")
             for axis in "xy"]
    return {
        "name": "two carts collide",
        "description": f"Two cart-pendulums (carts of 2 kg, bobs of 0.5 kg on 0.8 m) on one rail: the left cart rolls "
                       f"at {speed:g} m/s into the right one at rest; a Contact element with steel's stiffness between "
                       f"the carts (bodies of radius {radius:g} m). The carts exchange most of their motion, and both "
                       "pendulums swing.",
        "stop": stop, "step": step, "accuracy": {"position": 0.001},
        "camera": {"scale": 200.0, "frame_rate": 25},
        "components": components, "connections": connections, "bonds": bonds}


def repository_scenes() -> dict[str, dict]:
    """The scene files in scenes/ that these rules write, by file name."""
    return {"contact_cradle.json": pendulum_cradle(), "double_strikes_ball.json": double_strikes_ball(),
            "colliding_carts.json": colliding_carts()}
