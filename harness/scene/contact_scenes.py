"""Scenes of objects that touch across FMUs, joined by Contact elements, made by rule.

A SimplePendulum's bob has two force inputs, F and F2: a ball between two neighbours takes its left
contact through F and its right one through F2. Contacts are listed before the pendulums, so that
Gauss-Seidel hands every contact the balls at the step's start (it moves them by their velocities over
the step itself).
"""
from __future__ import annotations

from harness.scene.spring_scenes import bob_bonds, element_joint

STEEL_STIFFNESS = 1.465e10  # Hertz stiffness of two steel balls of radius 0.02 m [N/m^1.5] (as the HertzCradle's)


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


def repository_scenes() -> dict[str, dict]:
    """The scene files in scenes/ that these rules write, by file name."""
    return {"contact_cradle.json": pendulum_cradle()}
