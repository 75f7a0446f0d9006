// The live view's co-simulation master: the harness's master (harness/cosim) over the same FMI
// calls, for the FMUs' WebAssembly modules. Jacobi or Gauss-Seidel over a fixed communication
// step, inputs held or extrapolated linearly. In FMI 2.0 an input and its derivative are values at
// the start of the receiving step: a source that has not stepped yet hands over y(t) and its output
// derivative; in Gauss-Seidel one that has stepped hands over y(t) with the slope
// (y(t + H) - y(t)) / H. At t = 0 connected outputs are copied to inputs inside initialization
// mode until they settle.
import { DISCARD, FmuModule, STATUS_NAMES } from "./fmu.mjs";

export const ALGORITHMS = ["jacobi", "gauss-seidel"];
export const EXTRAPOLATIONS = ["hold", "linear"];

/** A table keyed by names from the scene (components, variables): without a prototype, so that a
 * name such as "__proto__" or "constructor" is a key like any other. */
export function table(entries = []) {
  const made = Object.create(null);
  for (const [key, value] of entries) made[key] = value;
  return made;
}

/** A failed FMI call: the component, the call, its status and the FMU's last message. */
export class FmiError extends Error {}

/** The start values of a component as the FMU takes them: {reals: [vrs, values], integers: ...}. */
export function startCalls(meta, start) {
  const calls = { real: [[], []], integer: [[], []], boolean: [[], []] };
  for (const [name, value] of Object.entries(start)) {
    const [vr, kind] = meta.variables[name];
    calls[kind][0].push(vr);
    calls[kind][1].push(value);
  }
  return calls;
}

/** Sets the start values, then enters initialization mode at time t0 (from a fresh or reset instance). */
export function beginInstance(instance, meta, start, t0, what) {
  const calls = startCalls(meta, start);
  const check = (status, call) => {
    if (status > 1) {
      throw new FmiError(`${what}: ${call} returned ${STATUS_NAMES[status] ?? status}: ` +
                         `${instance.module.messages.at(-1) ?? "no message"}`);
    }
  };
  check(instance.setupExperiment(t0), "fmi2SetupExperiment");
  for (const [kind, call] of [["integer", "fmi2SetInteger"], ["boolean", "fmi2SetBoolean"], ["real", "fmi2SetReal"]]) {
    if (calls[kind][0].length) check(instance.set(kind, ...calls[kind]), call);
  }
  check(instance.enterInitialization(), "fmi2EnterInitializationMode");
  return check;
}

/** One component: its instance, its start values (those of the scene, changed by the person), and
 * its exchange buffers: outputs and their derivatives now (y, dy) and after its step (yNext,
 * dyNext), inputs and their derivatives (u, du). */
export class Unit {
  constructor(name, fmu, meta, start) {
    this.name = name;
    this.meta = meta;
    this.instance = fmu.instantiate(name, meta.guid);
    this.sceneStart = table(Object.entries(start));
    this.start = table(Object.entries(start));
    this.begun = false;
    this.realOutputs = meta.real_outputs;
    this.integerOutputs = meta.integer_outputs;
    this.outputs = this.instance.port(this.realOutputs.map((n) => meta.variables[n][0]));
    this.integerPort = this.integerOutputs.length ? this.instance.port(this.integerOutputs.map((n) => meta.variables[n][0]))
      : null;
    const n = this.realOutputs.length;
    [this.y, this.dy, this.yNext, this.dyNext] = [0, 0, 0, 0].map(() => new Float64Array(n));
    this.inputs = []; // input names, in the order of u
    this.inputPort = null;
    this.energyIndex = meta.energy ? this.realOutputs.indexOf(meta.energy) : -1;
  }

  addInput(name) {
    this.inputs.push(name);
    this.inputPort?.free();
    this.inputPort = this.instance.port(this.inputs.map((n) => this.meta.variables[n][0]));
    this.u = new Float64Array(this.inputs.length);
    this.du = new Float64Array(this.inputs.length);
    return this.inputs.length - 1;
  }

  /** The value of a start value or setting: the one set for this unit, else the FMU's default. */
  setting(name) {
    return name in this.start ? this.start[name] : this.meta.defaults[name];
  }

  check(status, call) {
    if (status > 1 && status !== DISCARD) {
      throw new FmiError(`${this.name}: ${call} returned ${STATUS_NAMES[status] ?? status}: ` +
                         `${this.instance.module.messages.at(-1) ?? "no message"}`);
    }
    return status;
  }

  begin(t0) {
    if (this.begun) this.check(this.instance.reset(), "fmi2Reset");
    this.begun = true;
    this.instance.module.messages.length = 0;
    beginInstance(this.instance, this.meta, this.start, t0, this.name);
  }

  readOutputs(derivatives) {
    const port = this.outputs;
    this.check(port.getReal(), "fmi2GetReal");
    this.yNext.set(port.values);
    if (derivatives) {
      this.check(port.getOutputDerivatives(), "fmi2GetRealOutputDerivatives");
      this.dyNext.set(port.values);
    }
  }

  writeInputs(derivatives) {
    if (!this.inputs.length) return;
    this.check(this.inputPort.setReal(this.u), "fmi2SetReal");
    if (derivatives) this.check(this.inputPort.setInputDerivatives(this.du), "fmi2SetRealInputDerivatives");
  }

  accept(derivatives) {
    this.y.set(this.yNext);
    if (derivatives) this.dy.set(this.dyNext);
  }

  /** Every output's value now, by name (integer outputs read from the FMU). */
  values() {
    const values = table();
    this.realOutputs.forEach((name, k) => { values[name] = this.y[k]; });
    if (this.integerPort) {
      this.check(this.integerPort.getInteger(), "fmi2GetInteger");
      this.integerOutputs.forEach((name, k) => { values[name] = this.integerPort.integers[k]; });
    }
    return values;
  }

  output(name) {
    return this.y[this.realOutputs.indexOf(name)];
  }

  free() {
    for (const port of [this.outputs, this.integerPort, this.inputPort]) port?.free();
    this.instance.free();
  }

  get energy() {
    return this.energyIndex >= 0 ? this.y[this.energyIndex] : NaN;
  }
}

/** C's fmax and fmin (a NaN loses to a number), as harness/cosim/contact_guard.py has them. */
const larger = (a, b) => (Number.isNaN(a) ? b : Number.isNaN(b) ? a : Math.max(a, b));
const smaller = (a, b) => (Number.isNaN(a) ? b : Number.isNaN(b) ? a : Math.min(a, b));

/** The energy check of harness/cosim/contact_guard.py, with its settings from the scene: after each macro step,
 * the scene's energy (each unit's energy output) risen above its lowest by more than `share` of the largest energy
 * in motion seen before (every E_kin and every contact's stored E_pot) stops the run, the contact named. Off where
 * no unit reports E_kin or no unit is a contact (outputs gap and gap_rate). It reads the outputs the step just read
 * (`yNext`), before the units take them: a step that fails it leaves the page at the step's start. */
export class ContactGuard {
  constructor(units, settings) {
    this.settings = settings;
    this.energies = units.filter((u) => u.energyIndex >= 0);
    this.kinetic = units.filter((u) => u.realOutputs.includes("E_kin")).map((u) => [u, u.realOutputs.indexOf("E_kin")]);
    this.watches = units.filter((u) => u.realOutputs.includes("gap") && u.realOutputs.includes("gap_rate"))
      .map((u) => [u, ...["gap", "gap_rate", "E_pot"].map((n) => u.realOutputs.indexOf(n))]);
    this.active = Boolean(settings && this.watches.length && this.kinetic.length && this.energies.length);
    this.before = this.watches.map(() => [0, 0, 0]);
  }

  sums(field) {
    let energy = 0, magnitude = 0, kinetic = 0;
    for (const unit of this.energies) {
      energy += unit[field][unit.energyIndex];
      magnitude += Math.abs(unit[field][unit.energyIndex]);
    }
    for (const [unit, k] of this.kinetic) kinetic += unit[field][k];
    for (const [unit, , , k] of this.watches) if (k >= 0) kinetic += unit[field][k];
    return [energy, kinetic, magnitude];
  }

  remember(field) {
    this.watches.forEach(([unit, gap, rate, stored], w) => {
      this.before[w] = [unit[field][gap], unit[field][rate], stored >= 0 ? unit[field][stored] : 0];
    });
  }

  begin() {
    if (!this.active) return;
    [this.low, this.scale, this.magnitude] = this.sums("y");
    this.remember("y");
  }

  /** After the macro step [t, t + H], its outputs in each unit's yNext: null, or the message that stops the run. */
  check(t, H) {
    if (!this.active) return null;
    const [energy, kinetic, magnitude] = this.sums("yNext");
    this.magnitude = larger(this.magnitude, magnitude);
    const created = energy - this.low;
    if (created > this.settings.share * this.scale + this.settings.floor * this.magnitude) {
      return this.message(t, H, created);
    }
    this.low = smaller(this.low, energy);
    this.scale = larger(this.scale, kinetic);
    this.remember("yNext");
    return null;
  }

  message(t, H, created) {
    const after = (unit, k) => unit.yNext[k];
    const rises = this.watches.map(([unit, , , stored], w) => (stored >= 0 ? after(unit, stored) - this.before[w][2] : 0));
    const rates = this.watches.map(([unit, , rate], w) => Math.abs(after(unit, rate) - this.before[w][1]));
    const pick = (values) => values.reduce((best, value, k) => (value > values[best] ? k : best), 0);
    const w = rises.some((rise) => rise > 0) ? pick(rises) : pick(rates);
    const [unit, gap, rate] = this.watches[w];
    const depth = Math.max(-after(unit, gap), -this.before[w][0], 0) || 0;
    const speed = Math.abs(this.before[w][1]) || Math.abs(after(unit, rate));
    const k = unit.setting("k"), exponent = unit.setting("exponent");
    const { share, steps_per_contact: perContact, hertz_duration: hertz } = this.settings;
    let text = `${unit.name}: the macro step of ${H.toPrecision(3)} s from t = ${t} s took the contact ` +
      `${depth.toPrecision(3)} m deep and created ${created.toPrecision(3)} J, more than ${Math.round(share * 100)}% ` +
      `of the energy the scene had in motion (${this.scale.toPrecision(3)} J)`;
    if (k > 0 && exponent > 0 && speed > 0 && this.scale > 0) {
      const duration = hertz * ((exponent + 1) * this.scale / k) ** (1 / (exponent + 1)) / speed;
      text += `; the contact lasts about ${duration.toPrecision(2)} s: a macro step of at most ` +
        `${(duration / perContact).toPrecision(1)} s would do`;
    }
    return text;
  }
}

/** The scene's units stepped together. `scene` is the page's scene (harness/view/page.py). */
export class Master {
  static async create(scene, options = {}) {
    const modules = table();
    for (const [key, meta] of Object.entries(scene.modules)) {
      modules[key] = await FmuModule.load(decodeBase64(meta.wasm));
    }
    return new Master(scene, modules, options);
  }

  constructor(scene, modules, { algorithm = scene.algorithm, extrapolation = scene.extrapolation } = {}) {
    if (!ALGORITHMS.includes(algorithm)) throw new Error(`algorithm ${algorithm}: choose one of ${ALGORITHMS}`);
    if (!EXTRAPOLATIONS.includes(extrapolation)) {
      throw new Error(`extrapolation ${extrapolation}: choose one of ${EXTRAPOLATIONS}`);
    }
    this.scene = scene;
    this.modules = modules;
    this.algorithm = algorithm;
    this.linear = extrapolation === "linear";
    this.H = scene.step;
    this.units = scene.components.map((c) => new Unit(c.name, modules[c.module], scene.modules[c.module], c.start));
    const index = table(this.units.map((u, k) => [u.name, k]));
    // per receiving unit: [source index, source output indices, input indices]
    this.routes = this.units.map(() => new Map());
    for (const [source, output, target, input] of scene.connections) {
      const j = index[source], k = index[target];
      const slot = this.units[k].addInput(input);
      if (!this.routes[k].has(j)) this.routes[k].set(j, [[], []]);
      const [outs, ins] = this.routes[k].get(j);
      outs.push(this.units[j].realOutputs.indexOf(output));
      ins.push(slot);
    }
    this.routes = this.routes.map((m) => [...m.entries()].map(([j, [outs, ins]]) => [j, outs, ins]));
    this.stepped = this.units.map(() => false);
    this.guard = new ContactGuard(this.units, scene.guard);
    this.restart();
  }

  unit(name) {
    return this.units.find((u) => u.name === name);
  }

  /** Every unit from its start values at t = 0. */
  restart() {
    this.steps = 0;
    this.time = 0;
    for (const unit of this.units) unit.begin(0);
    this.settle();
    for (const unit of this.units) {
      unit.check(unit.instance.exitInitialization(), "fmi2ExitInitializationMode");
      unit.readOutputs(this.linear);
      unit.accept(this.linear);
    }
    this.guard.begin();
  }

  settle(tolerance = 1e-14, passes = 50) {
    for (let pass = 0; pass < passes; pass++) {
      let change = 0;
      for (const unit of this.units) {
        unit.readOutputs(false);
        unit.y.set(unit.yNext);
      }
      this.units.forEach((unit, k) => {
        if (!unit.inputs.length) return;
        for (const [j, outs, ins] of this.routes[k]) {
          outs.forEach((o, i) => {
            change = Math.max(change, Math.abs(this.units[j].y[o] - unit.u[ins[i]]));
            unit.u[ins[i]] = this.units[j].y[o];
          });
        }
        unit.writeInputs(false);
      });
      if (change <= tolerance) return;
    }
  }

  feed(k, H, stepped) {
    const unit = this.units[k];
    if (!unit.inputs.length) return;
    for (const [j, outs, ins] of this.routes[k]) {
      const source = this.units[j];
      outs.forEach((o, i) => {
        const slot = ins[i];
        if (stepped[j]) {
          if (this.linear) {
            unit.u[slot] = source.y[o];
            unit.du[slot] = (source.yNext[o] - source.y[o]) / H;
          } else {
            unit.u[slot] = source.yNext[o];
          }
        } else {
          unit.u[slot] = source.y[o];
          if (this.linear) unit.du[slot] = source.dy[o];
        }
      });
    }
    unit.writeInputs(this.linear);
  }

  /** One macro step from this.time to `end` (by default the next point k H of the grid: points
   * come from their index, never accumulated, as in the harness). Returns null, or what stopped it. */
  step(end = (this.steps + 1) * this.H) {
    const t = this.time, H = end - t, units = this.units, stepped = this.stepped;
    stepped.fill(false);
    if (this.algorithm === "jacobi") {
      units.forEach((_, k) => this.feed(k, H, stepped));
      for (const unit of units) {
        if (unit.check(unit.instance.doStep(t, H), "fmi2DoStep") === DISCARD) return discarded(unit, t);
      }
      for (const unit of units) unit.readOutputs(this.linear);
    } else {
      for (let k = 0; k < units.length; k++) {
        this.feed(k, H, stepped);
        if (units[k].check(units[k].instance.doStep(t, H), "fmi2DoStep") === DISCARD) return discarded(units[k], t);
        units[k].readOutputs(this.linear);
        stepped[k] = true;
      }
    }
    const stopped = this.guard.check(t, H);
    if (stopped) return stopped;
    for (const unit of units) unit.accept(this.linear);
    this.steps += 1;
    this.time = end;
    return null;
  }

  /** Steps to `stop` on the harness's grid: 0, H, 2 H, ..., the last point moved to stop; as the
   * harness, at most the scene's max_points steps. */
  runTo(stop) {
    const n = Math.max(1, Math.ceil(stop / this.H - 1e-9));
    if (!(n <= this.scene.max_points)) {
      throw new Error(`${stop} s in steps of ${this.H} s would be ${n} communication points, more than the ` +
                      `${this.scene.max_points} allowed`);
    }
    while (this.steps < n) {
      const problem = this.step(this.steps + 1 === n ? stop : (this.steps + 1) * this.H);
      if (problem) return problem;
    }
    return null;
  }

  /** {"time", "components": {name: {output: value}}}: every output of every component (the states
   * are outputs in these FMUs). */
  snapshot() {
    const components = table();
    for (const unit of this.units) components[unit.name] = unit.values();
    return { time: this.time, components };
  }

  free() {
    for (const unit of this.units) unit.free();
    this.units = [];
  }
}

/** What stopped a macro step: the unit that discarded it, and the FMU's message. */
function discarded(unit, t) {
  return `${unit.name} could not complete the step from t = ${t}: ${unit.instance.module.messages.at(-1) ?? "no message"}`;
}

export function decodeBase64(text) {
  const binary = atob(text);
  const bytes = new Uint8Array(binary.length);
  for (let k = 0; k < binary.length; k++) bytes[k] = binary.charCodeAt(k);
  return bytes;
}
