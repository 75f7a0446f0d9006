// Runs an FMU's WebAssembly module under Node's WASI as an importer would, for the tests:
//   node web/run_fmu.mjs MODULE.wasm REQUEST.json
// REQUEST: {"guid": ..., "runs": [{"reals": {vr: value}, "integers": {vr: value}, "stop": s,
//           "step": H, "record": [vr, ...]}, ...]}
// Prints one JSON object per run: {"outcome": "ok" | "refused" (a start value or the
// initialization failed) | "step status N", "rows": [[values of `record`] per communication point],
// "messages": [...]}. A run stops at the first step that is not OK; its rows so far are kept.
import { readFileSync } from "node:fs";
import { WASI } from "node:wasi";
import { FmuModule } from "./fmu.mjs";

const [modulePath, requestPath] = process.argv.slice(2);
const request = JSON.parse(readFileSync(requestPath, "utf8"));
const wasi = new WASI({ version: "preview1", args: [], env: {} });
const fmu = await FmuModule.load(readFileSync(modulePath), {
  wasiImports: wasi.getImportObject(), initialize: (instance) => wasi.initialize(instance) });

for (const run of request.runs) {
  fmu.messages = [];
  const instance = fmu.instantiate("wasm", request.guid);
  const rows = [];
  const entries = (values) => Object.entries(values ?? {}).map(([vr, v]) => [Number(vr), v]);
  const integers = entries(run.integers), reals = entries(run.reals);
  const setup = [instance.setupExperiment(0)];
  if (integers.length) setup.push(instance.setInteger(integers.map((e) => e[0]), integers.map((e) => e[1])));
  if (reals.length) setup.push(instance.setReal(reals.map((e) => e[0]), reals.map((e) => e[1])));
  setup.push(instance.enterInitialization(), instance.exitInitialization());
  let outcome = setup.every((s) => s === 0) ? "ok" : "refused";
  if (outcome === "ok") {
    rows.push(Array.from(instance.getReal(run.record)[1]));
    const steps = Math.round(run.stop / run.step);
    for (let k = 0; k < steps; k++) {
      const status = instance.doStep(k * run.step, run.step);
      if (status !== 0) {
        outcome = `step status ${status}`;
        break;
      }
      rows.push(Array.from(instance.getReal(run.record)[1]));
    }
  }
  instance.free();
  process.stdout.write(JSON.stringify({ outcome, rows, messages: fmu.messages }) + "\n");
}
