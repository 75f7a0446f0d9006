"""What the tests of the methods with their own step share: a run of any object under a force that varies
in time, and a ball in free fall, whose motion is a polynomial in time."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from harness.fmi.fmu_instance import FmuInstance
from harness.objects.build import derive_fmu
from harness.objects.proof import object_file_in


def states_under_a_varying_force(open_fmu, fmu: str, name: str, settings: dict) -> tuple[list[str], np.ndarray]:
    """The object's states after ten communication steps of 0.1 s with `settings`, its first force
    input 0.5 sin(3 t) (value and derivative set each step); the state names and values."""
    spec = object_file_in(fmu)
    names = [c.name for c in spec.coordinates] + [c.velocity for c in spec.coordinates]
    inputs = [name for force in spec.forces for name in force.inputs.values()]
    instance = open_fmu(name)
    instance.initialize(**settings)
    t = 0.0
    for _ in range(10):
        if inputs:
            instance.set(**{inputs[0]: 0.5 * np.sin(3 * t)})
            instance.set_input_derivatives(**{inputs[0]: 1.5 * np.cos(3 * t)})
        assert instance.do_step(t, 0.1) == 0, instance.last_message()
        t += 0.1
    return names, np.array(instance.get(*names))


FREE_FALL = """
identifier = "Ball"
description = "a point mass in a vertical plane under gravity, pushed by a force"

[parameters]
g = { start = 9.81, unit = "m/s2" }
m = { start = 2.0, unit = "kg", min = 0.1 }

[coordinates]
x = { start = 0.0, unit = "m", velocity = "x_dot", velocity_start = 3.0 }
y = { start = 10.0, unit = "m", velocity = "y_dot", velocity_start = 4.0 }

[energy]
T = "m/2*speed2(ball)"
U = "m*g*y"

[points]
ball = { x = "x", y = "y" }

[forces]
F = { point = "ball" }
"""


def ball_fmu(folder: Path) -> Path:
    """The ball's FMU, derived into folder."""
    (folder / "Ball.toml").write_text(FREE_FALL)
    return derive_fmu(folder / "Ball.toml", folder / "out").path


def assert_polynomial_motion_is_exact(ball: Path, parabola: dict, cubic: dict) -> tuple[int, int]:
    """The ball in free fall for 5 s with `parabola`, then under F_x = 2 t (its rate set, so that x = 3 t +
    t^3 / (3 m)) for 3 s with `cubic`, in communication steps of 1 s: both to rounding. Returns the free
    fall's (n_steps, n_rejected)."""
    with FmuInstance(ball) as fmu:
        fmu.initialize(**parabola)
        for k in range(5):
            assert fmu.do_step(float(k), 1.0) == 0
        x, y, vx, vy = fmu.get("x", "y", "x_dot", "y_dot")
        t = 5.0
        assert x == pytest.approx(3.0 * t, abs=1e-13) and vx == pytest.approx(3.0, abs=1e-14)
        assert y == pytest.approx(10.0 + 4.0 * t - 9.81 / 2 * t * t, abs=1e-12)
        assert vy == pytest.approx(4.0 - 9.81 * t, abs=1e-13)
        counters = tuple(fmu.get("n_steps", "n_rejected"))
        fmu.reset()
        fmu.initialize(**cubic)
        for k in range(3):
            fmu.set(F_x=2.0 * k)
            fmu.set_input_derivatives(F_x=2.0)
            assert fmu.do_step(float(k), 1.0) == 0
        assert fmu.get("x")[0] == pytest.approx(3.0 * 3 + 27.0 / 6.0, abs=1e-12)
    return counters
