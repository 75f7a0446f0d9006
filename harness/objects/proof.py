"""The proof of any FMU made from an object file, with nothing specific to one object.

Every FMU built from an object file carries that file as `sources/<identifier>.toml`; from it:

* accelerations and energies against the independent numeric route (harness.objects.numeric_route:
  plain evaluation of T, U and the points, high-precision finite differences, never the symbolic
  derivation or the generated C), at random parameters, states, inputs and times;
* every fixed-step method converges at its order, measured on the differences of runs at halved
  steps (no reference solution needed), and, where T and U do not depend on time, the energy error
  falls at least at that order; so do taylor and gbs with their fixed step at order 4;
* rkf45 and gbs keep their global error within a small multiple of their tolerance;
* Model Exchange with fmpy's CVode ends where the Co-Simulation FMU does.

The time scale of every run is the object's own default step `h`: the object file's author chose it.
"""
from __future__ import annotations

import ctypes
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sympy as sp

from harness.archives import extract_fmu, remove_folder
from harness.errors import HarnessError
from harness.fmi.fmu_instance import OK, FmuInstance, accepted_methods, read_description
from harness.fmi.methods import ADAPTIVE, COUNTER_NAMES, METHODS, VARIABLE_ORDER, fixed_step_settings
from harness.objects.numeric_route import NumericLagrangian
from harness.objects.object_file import FRAMEWORK_PARAMETERS, ObjectFileError, ObjectSpec, read_object_file

STEP_RATIOS = [2.0 ** (3 - k) for k in range(9)]  # run steps: 8 h ... h / 32 of the object's default h
RUN_STEPS = 128                                     # run length in default steps
SLOW_RUN_FACTOR = 4                                 # the longer run of a method whose order the first cannot show
ROUNDING_FLOOR = 1e-12                       # differences below this are rounding, not truncation
# taylor and gbs with their fixed step at order 4: at order 6 taylor's error constant (1/7!) puts a slow
# object (a 10 m pendulum at its default step) at rounding from the coarsest step on, with no order to see
VARIABLE_ORDER_PROVEN = 4


@dataclass
class Proof:
    name: str
    passed: bool
    detail: str


def object_file_in(fmu: str | Path) -> ObjectSpec | None:
    """The object file an FMU carries, or None for an FMU not made from one."""
    fmu = Path(fmu)
    md = read_description(fmu)
    interface = md.coSimulation or md.modelExchange
    member = f"sources/{interface.modelIdentifier}.toml"
    with zipfile.ZipFile(fmu) as archive:
        if member not in archive.namelist():
            return None
        text = archive.read(member).decode("utf-8", errors="replace")
    try:
        spec = read_object_file(f"{fmu.name}:{member}", text)
    except ObjectFileError as error:
        raise HarnessError(str(error)) from None
    described = {v.name for v in md.modelVariables}
    missing = [name for name in _names_of(spec) if name not in described]
    if missing:  # an edited model description: what the object file promises is not in the FMU
        raise HarnessError(f"{fmu}: its model description lacks {missing[0]!r}, which its object file {member} "
                           "defines; the FMU does not match its sources")
    return spec


def _names_of(spec: ObjectSpec) -> list[str]:
    """The variables every FMU made from this object file has (harness.objects.model_description)."""
    names = [p.name for p in spec.parameters]
    for c in spec.coordinates:
        names += [c.name, c.velocity, f"der({c.name})", f"der({c.velocity})"]
    names += [name for force in spec.forces for name in force.inputs.values()]
    names += [name for point in spec.points for name in point.outputs.values()]
    names += [output.name for output in spec.outputs]
    return names + ["E_kin", "E_pot", "E", "solver", *COUNTER_NAMES]


def prove(fmu: str | Path, spec: ObjectSpec, samples: int = 6) -> list[Proof]:
    fmu = Path(fmu)
    return [numeric_route_agreement(fmu, spec, samples), *method_orders(fmu, spec),
            model_exchange_with_cvode(fmu, spec)]


# ---- the equations against the numeric route

def random_values(spec: ObjectSpec, rng: np.random.Generator) -> dict[str, float]:
    """Parameters within 20 % of their defaults (and in range; those in a rigid constraint's gap stay, so that
    the start still respects it), coordinates within 0.3 and velocities within 1 of their starts, force
    inputs up to 2 N, damping up to 0.3, time up to 1 s if it matters."""
    values: dict[str, float] = {}
    fixed = {str(s) for c in spec.constraints if not c.compliant for s in c.gap.free_symbols}
    for p in spec.parameters:
        if p.name in FRAMEWORK_PARAMETERS:
            continue
        value = p.start * (rng.uniform(0.8, 1.2) if p.name not in fixed else 1.0)
        values[p.name] = float(np.clip(value, -np.inf if p.min is None else p.min, np.inf if p.max is None else p.max))
    values["d"] = rng.uniform(0.0, 0.3)
    for c in spec.coordinates:
        values[c.name] = c.start + rng.uniform(-0.3, 0.3)
        values[c.velocity] = c.velocity_start + rng.uniform(-1.0, 1.0)
    for force in spec.forces:
        values.update({name: rng.uniform(-2.0, 2.0) for name in force.inputs.values()})
    values["t"] = rng.uniform(0.0, 1.0) if spec.rheonomic else 0.0
    return values


def numeric_route_agreement(fmu: Path, spec: ObjectSpec, samples: int, seed: int = 7,
                            tolerance: float = 1e-9) -> Proof:
    """Largest relative deviation of the FMU's accelerations (Model Exchange) from the numeric route,
    and its E_kin, E_pot against T and U evaluated plainly."""
    route = NumericLagrangian(spec)
    rng = np.random.default_rng(seed)
    n = len(spec.coordinates)
    inputs = [name for force in spec.forces for name in force.inputs.values()]
    parameters = [p.name for p in spec.parameters if p.name not in FRAMEWORK_PARAMETERS] + ["d"]
    worst = worst_energy = 0.0
    problems: list[str] = []
    done = tries = 0
    with FmuInstance(fmu, kind="ME") as instance:
        while done < samples and tries < 10 * samples:
            tries += 1
            values = random_values(spec, rng)
            instance.reset()
            instance.initialize(start_time=values["t"], **{name: values[name] for name in parameters})
            states = [values[c.name] for c in spec.coordinates] + [values[c.velocity] for c in spec.coordinates]
            derivatives = (ctypes.c_double * (2 * n))()
            status = max(instance.role("continuous_time_mode"), instance.role("set_time", values["t"]),
                         instance.role("set_states", (ctypes.c_double * (2 * n))(*states), 2 * n),
                         instance.set(**{name: values[name] for name in inputs}))
            if status != OK:
                problems.append(f"setting a state returned {status}: {instance.last_message()}")
                break
            if instance.role("derivatives", derivatives, 2 * n) != OK:
                continue  # a singular sample (outside `require`): the FMU said so; draw another
            # the rigid constraints resting at the start (default coordinates) act at every state set after it
            start = {**values, **{c.name: c.start for c in spec.coordinates},
                     **{c.velocity: c.velocity_start for c in spec.coordinates}}
            active = route.resting(start, values["t"])
            expected = route.accelerations(values, values["t"], active)
            got = np.array(derivatives[n:])
            if list(derivatives[:n]) != states[n:]:
                problems.append("dq/dt is not the velocity state")
            worst = max(worst, float(np.max(np.abs(got - expected)) / max(1.0, float(np.max(np.abs(expected))))))
            if spec.constraints:  # the constraint forces, and the gaps
                forces = route.forces(values, values["t"], active)
                got = np.array(instance.get(*[c.outputs[1] for c in spec.constraints]))
                worst = max(worst, float(np.max(np.abs(got - forces)) / max(1.0, float(np.max(np.abs(forces))))))
                gaps, _ = route.gaps(values, values["t"])
                got = np.array(instance.get(*[c.outputs[0] for c in spec.constraints]))
                worst = max(worst, float(np.max(np.abs(got - gaps))))
            T, U = route.energies(values, values["t"])
            E_kin, E_pot = instance.get("E_kin", "E_pot")
            worst_energy = max(worst_energy, abs(E_kin - T) / max(1.0, abs(T)), abs(E_pot - U) / max(1.0, abs(U)))
            done += 1
    if done < samples and not problems:
        problems.append(f"only {done} of {samples} random states were regular")
    passed = not problems and worst < tolerance and worst_energy < 1e-12
    detail = (f"largest relative deviation of the accelerations"
              f"{' (constraint forces and gaps)' if spec.constraints else ''} "
              f"{worst:.1e}, of E_kin and E_pot {worst_energy:.1e} "
              f"at {done} random parameters, states, inputs{' and times' if spec.rheonomic else ''}")
    return Proof("equations = numeric route (finite differences of plain T, U)", passed,
                 detail + ("; " + "; ".join(problems) if problems else ""))


# ---- orders of the methods

def default_step(fmu: FmuInstance) -> float:
    return float(fmu.variables["h"].start)


def _states_and_energy(instance: FmuInstance, spec: ObjectSpec) -> tuple[np.ndarray, float]:
    names = [c.name for c in spec.coordinates] + [c.velocity for c in spec.coordinates]
    return np.array(instance.get(*names)), instance.get("E")[0]


def _run(instance: FmuInstance, spec: ObjectSpec, duration: float, **settings) -> tuple[np.ndarray, float, float]:
    """States and energy at `duration`, and the energy at the start; d = 0, no forces. A run the FMU
    discards (a coarse step may leave the method's stability region) gives NaN."""
    instance.reset()
    instance.initialize(d=0.0, **settings)
    _, start_energy = _states_and_energy(instance, spec)
    if instance.do_step(0.0, duration) != OK:
        return np.full(2 * len(spec.coordinates), np.nan), math.nan, start_energy
    states, energy = _states_and_energy(instance, spec)
    return states, energy, start_energy


def observed_order(steps: list[float], errors: list[float], order: int, at_least: bool) -> tuple[bool, str]:
    """Passes where three consecutive errors above rounding fall with the order (within 0.5, or at
    least at the order less 0.5 when `at_least`), or where every error is at rounding level (the
    method is exact on this object): a pre-asymptotic start and a rounding floor are
    allowed, so the best such window counts. 0.5 separates neighbouring orders and leaves room for a
    chaotic object's approach to its asymptotic range."""
    def closeness(measured: float) -> tuple[float, float]:
        return (max(0.0, order - measured) if at_least else 0.0), abs(measured - order)

    def windows_of(size: int) -> list[tuple[float, int]]:
        return [(float(np.polyfit(np.log(steps[k:k + size]), np.log(errors[k:k + size]), 1)[0]), k)
                for k in range(len(errors) - size + 1)
                if min(errors[k:k + size]) > ROUNDING_FLOOR and max(errors[k:k + size]) < 1.0]
    # three points where the errors allow, else two (a high order reaches rounding within a few halvings)
    windows = windows_of(3) or windows_of(2)
    if not windows:
        if all(math.isfinite(e) and e <= ROUNDING_FLOOR for e in errors):
            # exact to rounding at every step (a free particle, a slow or linear object): nothing to
            # measure and nothing wrong; that the FMU moves at all the numeric route's check shows
            return True, f"exact to rounding at every step (differences <= {ROUNDING_FLOOR:g}; no order to measure)"
        if not all(math.isfinite(e) for e in errors):
            return False, "some runs were discarded and no three steps give an order"
        return False, "no two consecutive steps between rounding and 1 to measure an order"
    measured, k = min(windows, key=lambda window: closeness(window[0]))
    passed = measured >= order - 0.5 if at_least else abs(measured - order) <= 0.5
    last = min(k + 2, len(errors) - 1) if windows_of(3) else k + 1
    return passed, f"{measured:.2f} at h = {steps[k]:.3g} ... {steps[last]:.3g}"


def _order_check(instance: FmuInstance, spec: ObjectSpec, method: str, order: int, steps: list[float],
                 duration: float) -> tuple[bool, str, list]:
    settings = fixed_step_settings(method, order) if method in VARIABLE_ORDER else {"solver": method}
    runs = [_run(instance, spec, duration, h=step, **settings) for step in steps]
    differences = [float(np.max(np.abs(a[0] - b[0]))) for a, b in zip(runs, runs[1:])]
    passed, detail = observed_order(steps[:-1], differences, order, at_least=False)
    text = f"states {detail}"
    if conserves_energy(spec):
        drift = [abs(energy - start) / max(1.0, abs(start)) for _, energy, start in runs]
        energy_passed, energy_detail = observed_order(steps, drift, order, at_least=True)
        passed = passed and energy_passed
        text += f"; energy error {energy_detail}"
    return passed, f"{text}, over {duration:g} s", runs


def method_orders(fmu: Path, spec: ObjectSpec) -> list[Proof]:
    proofs = []
    with FmuInstance(fmu) as instance:
        h = default_step(instance)
        duration = RUN_STEPS * h
        steps = [h * r for r in STEP_RATIOS]
        finest = None
        accepted = accepted_methods(str(fmu))
        for method in METHODS:
            if not (method.fixed_step or method.name in VARIABLE_ORDER) or method.name not in accepted:
                continue
            order = method.order if method.fixed_step else VARIABLE_ORDER_PROVEN
            passed, text, runs = _order_check(instance, spec, method.name, order, steps, duration)
            if not passed:
                # an object slow for its default step: a high order reaches rounding within a halving
                # or two of a start still short of its asymptotic range; a longer run shows the order
                longer_passed, longer_text, _ = _order_check(instance, spec, method.name, order, steps,
                                                             SLOW_RUN_FACTOR * duration)
                if longer_passed:
                    passed, text = True, f"{longer_text} (over {duration:g} s: {text})"
            fixed = "" if method.fixed_step else " with its fixed step"
            proofs.append(Proof(f"order of {method.name}{fixed} (theory {order})", passed, text))
            if method.name == "nystrom5":
                finest = runs[-1][0]
        if finest is not None:
            proofs += [_tolerance_kept(instance, spec, duration, finest, method) for method in ADAPTIVE
                       if method in accepted]
    if spec.rheonomic:
        proofs.append(Proof("energy", True, "T or U depends on time: the energy is not conserved, not checked"))
    elif not conserves_energy(spec):
        proofs.append(Proof("energy", True, "impacts with restitution below 1 or damped contacts take energy: "
                                            "it is not conserved, not checked"))
    return proofs


def conserves_energy(spec: ObjectSpec) -> bool:
    """Whether the object's energy is conserved at its defaults (d = 0): not where T or U depends on time,
    nor where a rigid unilateral constraint has a restitution below 1 or a compliant one a damping."""
    if spec.rheonomic:
        return False
    defaults = {sp.Symbol(p.name, real=True): p.start for p in spec.parameters}
    for constraint in spec.constraints:
        if constraint.compliant:
            if float(constraint.damping.subs(defaults)) != 0.0:
                return False
        elif not constraint.bilateral and float(constraint.restitution.subs(defaults)) != 1.0:
            return False
    return True


def _tolerance_kept(instance: FmuInstance, spec: ObjectSpec, duration: float, reference: np.ndarray,
                    method: str) -> Proof:
    scale = 1.0 + float(np.max(np.abs(reference)))
    errors = {}
    for tol in (1e-5, 1e-8):
        states, _, _ = _run(instance, spec, duration, solver=method, tol=tol)
        errors[tol] = float(np.max(np.abs(states - reference))) / scale
    passed = all(error <= 100 * tol for tol, error in errors.items())
    return Proof(f"{method} keeps its tolerance", passed,
                 ", ".join(f"global error {error:.1e} at tol {tol:g}" for tol, error in errors.items())
                 + f" over {duration:g} s (limit 100 tol)")


# ---- Model Exchange

def model_exchange_with_cvode(fmu: Path, spec: ObjectSpec) -> Proof:
    from fmpy import simulate_fmu
    names = [c.name for c in spec.coordinates] + [c.velocity for c in spec.coordinates]
    with FmuInstance(fmu) as instance:
        h = default_step(instance)
        duration = RUN_STEPS * h
        reference, _, _ = _run(instance, spec, duration, solver="nystrom5", h=h / 16)
    unzipped = extract_fmu(Path(fmu))  # fmpy's own extraction stays behind where the run raises
    try:
        result = simulate_fmu(str(unzipped), fmi_type="ModelExchange", solver="CVode", stop_time=duration,
                              relative_tolerance=1e-10, output_interval=duration / 16, start_values={"d": 0.0},
                              output=names)
    except Exception as error:  # fmpy raises plain exceptions for a failing FMU call
        return Proof("Model Exchange with CVode", False, f"fmpy's CVode failed: {str(error).splitlines()[0]}")
    finally:
        remove_folder(unzipped)
    final = np.array([result[name][-1] for name in names])
    deviation = float(np.max(np.abs(final - reference))) / (1.0 + float(np.max(np.abs(reference))))
    passed = bool(np.all(np.isfinite(final))) and math.isclose(result["time"][-1], duration) and deviation < 1e-6
    return Proof("Model Exchange with CVode", passed,
                 f"fmpy's CVode (rtol 1e-10) ends {deviation:.1e} (relative) from Co-Simulation nystrom5 "
                 f"after {duration:g} s")
