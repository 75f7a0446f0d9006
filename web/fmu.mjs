// An FMI 2.0 Co-Simulation importer for the FMUs built to WebAssembly (build/wasm/<id>.wasm, one
// module per object): it calls the module's fmi2* functions exactly as a C importer calls a shared
// library's, with strings and arrays in the module's memory. Works in Node and in a browser: the
// module needs only three WASI functions (fd_write, fd_seek, fd_close: its C library's stdio, which
// the FMUs never use), so where no WASI is at hand a stub answering "bad file" serves.

// The return codes of FMI calls, named once for the page's script (the harness's C and Python name them once each:
// tests/framework/test_status_codes.py checks that they agree).
export const STATUS_NAMES = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"];
export const OK = 0, WARNING = 1, DISCARD = 2, ERROR = 3;
const CO_SIMULATION = 1;

/** WASI imports for a module that writes no file: every call answers EBADF (8). */
export function wasiStub() {
  const badFile = () => 8;
  return { wasi_snapshot_preview1: { fd_write: badFile, fd_seek: badFile, fd_close: badFile } };
}

export class FmuModule {
  /** Compiles and instantiates the module's bytes. `wasiImports` (Node's WASI getImportObject(),
   * or wasiStub()) and `initialize` (Node's wasi.initialize, or null: _initialize is then called
   * directly) come from the host. */
  static async load(bytes, { wasiImports = wasiStub(), initialize = null } = {}) {
    const module_ = new FmuModule();
    const imports = { ...wasiImports, env: { fmi_log: (...args) => module_.log(...args) } };
    const { instance } = await WebAssembly.instantiate(bytes, imports);
    if (initialize) initialize(instance);
    else instance.exports._initialize();
    module_.exports = instance.exports;
    module_.messages = [];
    return module_;
  }

  get memory() {
    return this.exports.memory.buffer; // the buffer changes when the memory grows: never keep it
  }

  log(status, instance, category, message) {
    this.messages.push(`[${STATUS_NAMES[status] ?? status}] ${this.string(instance)}: ${this.string(message)}`);
  }

  string(pointer) {
    const bytes = new Uint8Array(this.memory, pointer);
    return new TextDecoder().decode(bytes.subarray(0, bytes.indexOf(0)));
  }

  /** A NUL-terminated copy of text in the module's memory (freed by the caller). */
  cString(text) {
    const encoded = new TextEncoder().encode(text);
    const pointer = this.exports.malloc(encoded.length + 1);
    new Uint8Array(this.memory, pointer, encoded.length + 1).set([...encoded, 0]);
    return pointer;
  }

  /** An instance of the model (fmi2Instantiate), or throws with the FMU's message. */
  instantiate(name, guid, loggingOn = false) {
    const namePointer = this.cString(name), guidPointer = this.cString(guid), resources = this.cString("");
    const component = this.exports.fmi2Instantiate(namePointer, CO_SIMULATION, guidPointer, resources,
                                                   this.exports.importer_callbacks(), 0, loggingOn ? 1 : 0);
    [namePointer, guidPointer, resources].forEach((p) => this.exports.free(p));
    if (!component) throw new Error(`fmi2Instantiate failed: ${this.messages.at(-1) ?? "no message"}`);
    return new FmuInstance(this, component);
  }
}

/** One fmi2Component. Values go in and out through ports (below): a master keeps one per set of
 * variables it exchanges every step; a single call borrows one for its duration. */
export class FmuInstance {
  constructor(module_, component) {
    this.module = module_;
    this.fmi = module_.exports;
    this.component = component;
  }

  call(name, ...args) {
    return this.fmi[name](this.component, ...args);
  }

  /** A fixed set of variables with its own buffers in the module's memory: no allocation per call. */
  port(vrs) {
    return new Port(this, vrs);
  }

  /** use(port) for the variables vrs, the port freed afterwards. */
  withPort(vrs, use) {
    const port = new Port(this, vrs);
    try {
      return use(port);
    } finally {
      port.free();
    }
  }

  set(kind, vrs, values) { // kind: real, integer or boolean
    return this.withPort(vrs, (port) => port.set(kind, values));
  }

  setReal(vrs, values) { return this.set("real", vrs, values); }
  setInteger(vrs, values) { return this.set("integer", vrs, values); }

  getReal(vrs) { // [status, Float64Array copy]
    return this.withPort(vrs, (port) => [port.getReal(), port.values.slice()]);
  }

  setupExperiment(start = 0) {
    return this.call("fmi2SetupExperiment", 0, 0.0, start, 0, 0.0);
  }

  enterInitialization() { return this.call("fmi2EnterInitializationMode"); }
  exitInitialization() { return this.call("fmi2ExitInitializationMode"); }
  doStep(t, h) { return this.call("fmi2DoStep", t, h, 1); }
  reset() { return this.call("fmi2Reset"); }
  free() { return this.call("fmi2FreeInstance"); }
}

/** The value references of a port and room for their values, orders and integers, allocated once;
 * the typed-array views on them are made again only when the module's memory has grown. */
export class Port {
  constructor(instance, vrs) {
    this.instance = instance;
    this.fmi = instance.fmi;
    this.component = instance.component;
    this.n = vrs.length;
    const n = Math.max(this.n, 1);
    [this.vrs, this.doubles, this.ints, this.orders] = [4, 8, 4, 4].map((size) => this.fmi.malloc(size * n));
    this.buffer = null;
    this.views();
    this.vrView.set(vrs);
    this.orderView.fill(1);
  }

  views() {
    const buffer = this.instance.module.memory;
    if (buffer !== this.buffer) {
      this.buffer = buffer;
      this.vrView = new Uint32Array(buffer, this.vrs, this.n);
      this.values = new Float64Array(buffer, this.doubles, this.n); // what the last get read, or the next set hands over
      this.integers = new Int32Array(buffer, this.ints, this.n);
      this.orderView = new Int32Array(buffer, this.orders, this.n);
    }
    return this;
  }

  setReal(values) {
    this.views().values.set(values);
    return this.fmi.fmi2SetReal(this.component, this.vrs, this.n, this.doubles);
  }

  getReal() { // into this.values
    const status = this.fmi.fmi2GetReal(this.component, this.vrs, this.n, this.doubles);
    this.views();
    return status;
  }

  /** Hands values over by fmi2Set<Kind>: kind real (floats), integer or boolean (ints). */
  set(kind, values) {
    if (kind === "real") return this.setReal(values);
    this.views().integers.set(values);
    return this.fmi[kind === "integer" ? "fmi2SetInteger" : "fmi2SetBoolean"](this.component, this.vrs, this.n, this.ints);
  }

  getOutputDerivatives() { // first-order, into this.values
    const status = this.fmi.fmi2GetRealOutputDerivatives(this.component, this.vrs, this.n, this.orders, this.doubles);
    this.views();
    return status;
  }

  setInputDerivatives(values) { // first-order
    this.views().values.set(values);
    return this.fmi.fmi2SetRealInputDerivatives(this.component, this.vrs, this.n, this.orders, this.doubles);
  }

  getInteger() { // into this.integers
    const status = this.fmi.fmi2GetInteger(this.component, this.vrs, this.n, this.ints);
    this.views();
    return status;
  }

  free() {
    [this.vrs, this.doubles, this.ints, this.orders].forEach((pointer) => this.fmi.free(pointer));
  }
}
