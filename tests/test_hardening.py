"""What an FMU does at the edges a hostile user finds: singular or meaningless configurations reached
at the start or inside a step, parameters that make the mass matrix singular, crafted serialized
states, subnormal numbers, and the state round trip of every method where its memory matters."""
from __future__ import annotations

import math
import struct
import sys

import pytest

from harness.fmi.methods import METHODS

from test_fmi_behaviour import _fnv1a64

OK, DISCARD, ERROR = 0, 2, 3


# ---------------------------------------------------------------- singular and meaningless configurations

def test_a_start_on_the_pivot_within_rounding_is_refused_by_name(open_fmu):
    """eps = -l0 + 2e-16 leaves l0 + eps at one rounding of l0: the mass is at the pivot, where the polar
    coordinates are singular. Refused at initialization, naming the requirement and its coordinate."""
    fmu = open_fmu("SpringPendulum")
    fmu.enter_initialization(eps=-1.0 + 2e-16)
    assert fmu.role("exit_initialization") == ERROR
    message = fmu.last_message()
    assert "eps + l0 = 2.22045e-16 must stay above 2e-09" in message and "require[0]" in message, message


def test_a_start_just_outside_the_rounding_is_accepted(open_fmu):
    fmu = open_fmu("SpringPendulum")
    fmu.initialize(eps=-1.0 + 1e-6, phi=0.3)
    assert fmu.do_step(0.0, 1e-6) in (OK, DISCARD)


@pytest.mark.parametrize("name,angle", [("SimplePendulum", "phi"), ("SpringPendulum", "phi"),
                                        ("DoublePendulum", "phi2")])
def test_an_angle_without_precision_is_refused_by_name(open_fmu, name, angle):
    """phi = 1e300 rad: sin(phi) is a number, but one ulp of phi is 1.5e284 rad, so the motion cannot move
    it (the energy drifted from 5.6 J to 134 J in 2 s). Refused, naming the coordinate and the limit."""
    fmu = open_fmu(name)
    fmu.enter_initialization(**{angle: 1e300})
    assert fmu.role("exit_initialization") == ERROR
    message = fmu.last_message()
    assert f"{angle} = 1e+300 rad is beyond +-1073741824 rad" in message and "ulp" in message, message


def test_an_angle_that_leaves_its_precision_inside_a_step_is_a_discard_naming_it(open_fmu):
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(phi=2.0 ** 30 - 10.0, omega=1000.0, solver="rk4", h=0.001)
    assert fmu.do_step(0.0, 0.005) == OK
    assert fmu.do_step(0.005, 0.02) == DISCARD
    message = fmu.last_message()
    assert "phi = " in message and "rad is beyond +-1073741824 rad" in message, message
    phi, = fmu.get("phi")
    assert abs(phi) <= 2.0 ** 30 and math.isfinite(phi)


@pytest.mark.parametrize("solver,settings", [("rk4", {"h": 0.001}), ("rkf45", {"tol": 1e-8}),
                                             ("gbs", {"tol": 1e-8}), ("taylor", {"tol": 1e-8})])
def test_a_fall_through_the_pivot_is_a_discard_naming_the_coordinate(open_fmu, solver, settings):
    """Released with no angular momentum towards the pivot, the mass reaches it at t = 0.01 s: every method
    ends the step in fmi2Discard (never fmi2OK with a meaningless angle such as -5.8e39), the message names
    the requirement and its coordinate, and the FMU keeps the last good state."""
    fmu = open_fmu("SpringPendulum")
    fmu.initialize(solver=solver, **settings, eps=-0.9, v_eps=-10.0, phi=0.2, omega=0.0, g=0.0, D=1e-9)
    status = fmu.do_step(0.0, 0.05)
    assert status == DISCARD, fmu.get("phi", "eps")
    message = fmu.last_message()
    assert "eps + l0" in message or "eps" in message, message
    phi, eps = fmu.get("phi", "eps")
    assert phi == pytest.approx(0.2) and eps > -1.0


# ---------------------------------------------------------------- singular mass matrix

def test_a_singular_mass_matrix_names_its_parameters(open_fmu):
    """J2 = 0 and s2 = 0: the outer link has neither inertia nor mass away from its joint. The message names
    the coordinate whose pivot vanishes and the parameters of its diagonal entry with their values."""
    fmu = open_fmu("DoublePendulum")
    fmu.enter_initialization(J2=0.0, s2=0.0)
    assert fmu.role("exit_initialization") == ERROR
    message = fmu.last_message()
    assert "of omega2" in message and "J2 + m2*s2**2 = 0 with J2 = 0, m2 = 1, s2 = 0" in message, message


# ---------------------------------------------------------------- crafted serialized states

def _resealed(data: bytearray) -> bytes:
    struct.pack_into("<Q", data, len(data) - 8, _fnv1a64(bytes(data[:-8])))
    return bytes(data)


def test_a_deserialized_state_is_checked_as_start_values_are(open_fmu):
    """omega = 1e200 passes the variable's range but makes E_kin overflow: initialization refuses it, and
    so does deserialization, naming the variable."""
    fmu = open_fmu("SimplePendulum")
    marker = 0.123456789012345
    fmu.initialize(omega=marker)
    data = bytearray(fmu.serialize(fmu.get_state()))
    packed = struct.pack("<d", marker)
    offset = bytes(data).find(packed)
    assert offset > 0 and bytes(data).find(packed, offset + 1) < 0  # omega, once: no history yet
    struct.pack_into("<d", data, offset, 1e200)
    with pytest.raises(Exception):
        fmu.deserialize(_resealed(data))
    message = fmu.last_message()
    assert "the FMU state's states" in message and "make E_kin not finite" in message, message
    assert fmu.do_step(0.0, 0.1) == OK  # nothing was taken over


def test_every_crafted_field_is_refused_by_name_or_runs(open_fmu):
    """Each 8-byte slot of a serialized ab6 state in turn set to NaN, and each to a huge integer: the state
    is either refused with a message that names what is wrong (never a bare "invalid"), or accepted and
    the next step ends in a status with finite outputs. The Adams-Bashforth history is found as the slots
    whose NaN names it: 6 entries per state, in one run."""
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver="ab6", h=0.01)
    for k in range(3):
        assert fmu.do_step(0.1 * k, 0.1) == OK
    original = fmu.serialize(fmu.get_state())
    history_slots = []
    for offset in range(64, len(original) - 8, 8):
        for kind, planted in (("nan", struct.pack("<d", math.nan)), ("huge", struct.pack("<q", 2 ** 62 + 12345))):
            data = bytearray(original)
            data[offset:offset + 8] = planted
            probe = open_fmu("SimplePendulum")
            probe.initialize(solver="ab6", h=0.01)
            try:
                state = probe.deserialize(_resealed(data))
            except Exception:
                message = probe.last_message()
                assert not message.rstrip().endswith("is invalid"), (offset, message)
                assert "FMU state" in message or "allowed" in message or "range" in message, (offset, message)
                if "Adams-Bashforth history holds" in message and kind == "nan":
                    history_slots.append(offset)
                continue
            assert probe.call("fmi2SetFMUstate", state) == OK
            status = probe.do_step(0.3, 0.1)
            assert status in (OK, DISCARD, ERROR)
            if status == OK:
                assert all(math.isfinite(v) for v in probe.get("phi", "omega", "E"))
    nan_slots = sorted(set(history_slots))
    n_states = fmu.model_description.numberOfContinuousStates
    assert len(nan_slots) >= 6 * n_states, nan_slots
    assert nan_slots[-1] - nan_slots[0] == 8 * (len(nan_slots) - 1)  # one contiguous block


# ---------------------------------------------------------------- state round trips

ROUND_TRIP = [(m.name, {"tol": 1e-4} if m.adaptive or m.name == "taylor" else {"h": 0.05}) for m in METHODS]
# memory that decides the continuation at these settings: the step and column proposals, the history
# (taylor takes each step from its coefficients there: nothing of it is kept)
MEMORY = {m.name for m in METHODS if m.adaptive or m.family.startswith("adams")}


@pytest.mark.parametrize("solver,settings", ROUND_TRIP, ids=[name for name, _ in ROUND_TRIP])
def test_a_serialized_state_continues_every_method_bit_for_bit(open_fmu, solver, settings):
    """Three steps of 0.5 s, the state serialized, three more; a new instance that deserializes it takes the
    same three steps to the same bits (states and counters). Where the method keeps memory (proposals,
    history), a new instance that starts from the same states without it continues differently: the test
    would see a field left out of the state."""
    names = ("phi", "omega", "n_steps", "n_rhs")
    fmu = open_fmu("SimplePendulum")
    fmu.initialize(solver=solver, phi=1.0, **settings)
    for k in range(3):
        assert fmu.do_step(0.5 * k, 0.5) == OK
    data = fmu.serialize(fmu.get_state())
    at_save = fmu.get("phi", "omega")
    for k in range(3, 6):
        assert fmu.do_step(0.5 * k, 0.5) == OK
    straight = fmu.get(*names)
    restored = open_fmu("SimplePendulum")
    restored.initialize(solver=solver, **settings)
    assert restored.call("fmi2SetFMUstate", restored.deserialize(data)) == OK
    for k in range(3, 6):
        assert restored.do_step(0.5 * k, 0.5) == OK
    assert restored.get(*names) == straight
    if solver in MEMORY:
        fresh = open_fmu("SimplePendulum")
        fresh.initialize(start_time=1.5, solver=solver, phi=at_save[0], omega=at_save[1], **settings)
        for k in range(3, 6):
            assert fresh.do_step(0.5 * k, 0.5) == OK
        assert fresh.get("phi", "omega") != straight[:2]


# ---------------------------------------------------------------- subnormal numbers

def test_the_importers_float_setting_is_kept_across_a_step_and_its_callbacks(open_fmu):
    """A step flushes subnormal numbers to zero (its cost must not depend on them); the importer's own
    arithmetic keeps its gradual underflow after the step and inside the FMU's logger callback during it."""
    quarter = []

    class Probing(list):
        def append(self, item):  # runs inside the FMU's call, in its logger callback
            quarter.append(sys.float_info.min / 4.0)
            super().append(item)

    fmu = open_fmu("SpringPendulum")
    fmu.initialize(solver="rk4", h=0.001, eps=-0.9, v_eps=-10.0, phi=0.2, omega=0.0, g=0.0, D=1e-9)
    fmu.log.messages = Probing(fmu.log.messages)
    assert fmu.do_step(0.0, 0.05) == DISCARD
    assert quarter and all(value == sys.float_info.min / 4.0 != 0.0 for value in quarter)
    assert sys.float_info.min / 4.0 != 0.0
