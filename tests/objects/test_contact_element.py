"""The Contact element (modelDescription/Contact.xml): Hertz's force with Hunt and Crossley's damping between
two bodies in different FMUs. Checked against the law written out here, against the work its forces do,
against the compliant constraint of an object file (the HertzCradle, generated code), and through its
event indicator in Model Exchange against the crossing solved in closed form."""
from __future__ import annotations

import ctypes
import math

import numpy as np
import pytest
from fmpy.fmi2 import fmi2EventInfo

from harness.fmi.fmu_instance import DISCARD, ERROR, FmuInstance, OK

K, N, R_A, R_B = 1.465e10, 1.5, 0.02, 0.02
POINTS = ("a_x", "a_y", "a_z", "b_x", "b_y", "b_z")
VELOCITIES = ("a_vx", "a_vy", "a_vz", "b_vx", "b_vy", "b_vz")
FORCES = ("Fa_x", "Fa_y", "Fa_z", "Fb_x", "Fb_y", "Fb_z")


def hertz(a, b, va, vb, k=K, n=N, c=0.0, reach=R_A + R_B):
    """(Fa, Fb, gap, gap rate, stored energy) of the law in SPEC 10, written out."""
    d, w = np.subtract(b, a), np.subtract(vb, va)
    r = math.sqrt(d @ d)
    e = d / r
    gap, rate = r - reach, w @ e
    overlap = max(-gap, 0.0)
    magnitude = max(k * overlap ** n * (1 - c * rate), 0.0) if overlap > 0 else 0.0
    return -magnitude * e, magnitude * e, gap, rate, k * overlap ** (n + 1) / (n + 1)


def configuration(instance: FmuInstance, a, b, va, vb, **parameters) -> None:
    instance.initialize(**parameters, **dict(zip(POINTS, [*a, *b])), **dict(zip(VELOCITIES, [*va, *vb])))


def fmu_of(fmu_paths, version: str):
    return fmu_paths["Contact"] if version == "2.0" else fmu_paths["Contact"].parent / "fmi3" / "Contact.fmu"


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_forces_gap_and_energy_follow_the_law_in_three_dimensions(fmu_paths, version):
    """Random centres around touch (apart, touching, overlapping up to 1 mm) and random velocities, with and
    without damping: each output against the law written out, the forces opposite and along b - a. The
    damping's never-pulling clip is among the samples (separating fast, c = 2 s/m)."""
    rng = np.random.default_rng(3)
    clipped = 0
    with FmuInstance(fmu_of(fmu_paths, version), name="contact") as instance:
        for sample in range(60):
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            a = rng.uniform(-1, 1, 3)
            b = a + direction * (R_A + R_B + rng.uniform(-1e-3, 3e-4))
            va, vb = rng.normal(size=3), rng.normal(size=3)
            c = (0.0, 0.3, 2.0)[sample % 3]
            instance.reset()
            configuration(instance, a, b, va, vb, c=c)
            got = np.array(instance.get(*FORCES, "gap", "gap_rate", "E_pot"))
            Fa, Fb, gap, rate, energy = hertz(a, b, va, vb, c=c)
            expected = np.concatenate([Fa, Fb, [gap, rate, energy]])
            scale = np.array([np.abs(Fa).max() + 1e-300] * 6 + [1e-3, 1.0, energy + 1e-300])
            assert np.all(np.abs(got - expected) <= 1e-12 * scale), (sample, got - expected)
            clipped += bool(gap < 0 and c * -rate < -1 and np.all(got[:6] == 0))
    assert clipped > 0  # the never-pulling case was met


def test_its_forces_do_the_work_its_stored_energy_gives_back(open_fmu):
    """Body b pressed into a and drawn back (its velocity relative to a's -3 cos(1000 t) m/s along x, set as
    the velocity input's slope each step), in Co-Simulation steps of 1 us while a drifts in 3-D: the work of
    both forces along the motion (the trapezoid rule over the step ends, checked against itself at twice
    the step) equals minus the change of E_pot, and all of it comes back when the bodies part (no damping)."""
    fmu = open_fmu("Contact")
    omega, H = 1000.0, 1e-6
    steps = 2 * round(math.pi / omega / H / 2) + 200  # the bodies part before the end
    fmu.initialize(a_vx=0.1, a_vy=0.05, a_vz=-0.02, b_x=0.041, b_y=0.0005, b_vx=0.1 - 3.0, b_vy=0.05, b_vz=-0.02)
    power, energy = [], []
    for i in range(steps + 1):
        if i:
            assert fmu.set_input_derivatives(b_vx=3.0 * omega * math.sin(omega * (i - 0.5) * H)) == OK
            assert fmu.do_step((i - 1) * H, H) == OK
        Fa, Fb = np.array(fmu.get(*FORCES[:3])), np.array(fmu.get(*FORCES[3:]))
        va, vb = np.array(fmu.get("a_vx", "a_vy", "a_vz")), np.array(fmu.get("b_vx", "b_vy", "b_vz"))
        power.append(Fa @ va + Fb @ vb)
        energy.append(fmu.get("E_pot")[0])
    power, energy = np.array(power), np.array(energy)
    assert energy.max() > 500.0  # a real overlap: about 1 kJ stored at the deepest point (2 mm)
    work = np.concatenate([[0.0], np.cumsum((power[:-1] + power[1:]) / 2 * H)])
    coarse = np.concatenate([[0.0], np.cumsum((power[:-2:2] + power[2::2]) * H)])
    assert np.max(np.abs(work[::2] - coarse)) < 1e-3 * energy.max()
    assert np.max(np.abs(work + energy - energy[0])) < 1e-4 * energy.max()
    assert energy[0] == 0.0 and energy[-1] == 0.0 and abs(work[-1]) < 1e-4 * energy.max()


def test_the_same_force_as_the_compliant_constraint_of_an_object(open_fmu):
    """The HertzCradle's contact12 (generated from its object file) and the Contact element on the same
    balls: two overlapping steel balls of the cradle, moving, with damping. The element gets the balls'
    centres and velocities as the cradle reports them, and gives its constraint's gap and force."""
    cradle = open_fmu("HertzCradle")
    cradle.initialize(phi1=0.0125, phi2=0.01, omega1=0.7, omega2=-0.3, c=0.4)
    ball = {k: cradle.get(*(f"ball{k}_{s}" for s in ("x", "y", "v_x", "v_y"))) for k in (1, 2)}
    gap, force = cradle.get("contact12_gap", "contact12_force")
    assert gap < -1e-5 and force > 1e3  # overlapping and pushing
    contact = open_fmu("Contact")
    contact.initialize(k=cradle.get("k")[0], c=0.4, a_x=ball[1][0], a_y=ball[1][1], a_vx=ball[1][2],
                       a_vy=ball[1][3], b_x=ball[2][0], b_y=ball[2][1], b_vx=ball[2][2], b_vy=ball[2][3])
    got_gap, Fb_x, Fb_y = contact.get("gap", "Fb_x", "Fb_y")
    assert got_gap == pytest.approx(gap, rel=1e-9)
    assert math.hypot(Fb_x, Fb_y) == pytest.approx(force, rel=1e-9)


def crossings(a0, va, b0) -> list[float]:
    """The times where |b0 - (a0 + va t)| = R_A + R_B: a quadratic, solved in closed form."""
    d0 = np.subtract(b0, a0)
    v = -np.asarray(va)
    qa, qb, qc = v @ v, 2 * d0 @ v, d0 @ d0 - (R_A + R_B) ** 2
    root = math.sqrt(qb * qb - 4 * qa * qc)
    return sorted([(-qb - root) / (2 * qa), (-qb + root) / (2 * qa)])


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_model_exchange_indicator_crosses_where_the_overlap_begins_and_ends(fmu_paths, version):
    """Centre a moves past b (inputs set along the path): the event indicator changes sign twice, at the
    closed-form onset and end of the overlap (found by bisection on the indicator, to 1e-13 s), and event
    mode changes no state."""
    a0, va, b0 = np.array([0.0, 0.0, 0.0]), np.array([0.5, -0.2, 0.1]), np.array([0.045, 0.01, 0.0])
    with FmuInstance(fmu_of(fmu_paths, version), kind="ME", name="contact") as instance:
        instance.initialize()
        prefix = instance.prefix
        if version == "2.0":
            instance.call("fmi2NewDiscreteStates", ctypes.byref(fmi2EventInfo()))
        assert instance.call(f"{prefix}EnterContinuousTimeMode") == OK
        z = (ctypes.c_double * 1)()

        def indicator(t: float) -> float:
            a = a0 + va * t
            assert instance.set(**dict(zip(POINTS, [*a, *b0])), a_vx=va[0], a_vy=va[1], a_vz=va[2]) == OK
            assert instance.call(f"{prefix}SetTime", ctypes.c_double(t)) == OK
            assert instance.call(f"{prefix}GetEventIndicators", z, ctypes.c_size_t(1)) == OK
            return z[0]

        grid = np.linspace(0.0, 0.3, 301)
        values = np.array([indicator(t) for t in grid])
        changes = np.nonzero(np.sign(values[:-1]) != np.sign(values[1:]))[0]
        found = []
        for i in changes:
            lo, hi = grid[i], grid[i + 1]
            while hi - lo > 1e-14:
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if np.sign(indicator(mid)) == np.sign(values[i]) else (lo, mid)
            found.append(0.5 * (lo + hi))
        expected = crossings(a0, va, b0)
        assert len(found) == 2
        # the indicator is gap + 1e-13 m: its zeros lie 1e-13 m / |gap rate| (< 1e-12 s here) inside the overlap
        assert found[0] == pytest.approx(expected[0], abs=2e-12) and found[1] == pytest.approx(expected[1], abs=2e-12)
        # an event there changes nothing
        indicator(found[0])
        assert instance.call(f"{prefix}EnterEventMode") == OK
        if version == "2.0":
            info = fmi2EventInfo()
            assert instance.call("fmi2NewDiscreteStates", ctypes.byref(info)) == OK
            assert (info.newDiscreteStatesNeeded, info.terminateSimulation, info.nominalsOfContinuousStatesChanged,
                    info.valuesOfContinuousStatesChanged, info.nextEventTimeDefined) == (0, 0, 0, 0, 0)
        else:
            flags = [ctypes.c_bool() for _ in range(5)]
            when = ctypes.c_double()
            assert instance.call("fmi3UpdateDiscreteStates", *(ctypes.byref(f) for f in flags),
                                 ctypes.byref(when)) == OK
            assert not any(f.value for f in flags)


def test_centres_at_one_point_are_refused_and_the_step_discarded(open_fmu):
    """r = 0 leaves the push without a direction: refused at initialization, and a step that brings the
    centres together is a discard naming the configuration, with the outputs of the last good point kept."""
    fmu = open_fmu("Contact")
    fmu.enter_initialization(b_x=0.0)
    assert fmu.role("exit_initialization") == ERROR
    assert "singular configuration" in fmu.last_message()
    moving = open_fmu("Contact")
    moving.initialize(b_x=0.01, b_vx=-0.01)
    before = moving.get("Fa_x")[0]
    assert before < 0 and math.isfinite(before)
    assert moving.do_step(0.0, 1.0) == DISCARD
    assert moving.get("Fa_x")[0] == before
