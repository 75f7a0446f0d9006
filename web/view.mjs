// The live page: the scene's objects move at the scene's frame rate with their traces; a person
// pauses, steps, restarts, drags a mass to a new start and chooses each object's method and step.
// index.html?check=T runs the scene to T without drawing and writes the final state as JSON into
// <pre id="check">. Optional parameters: algorithm=jacobi|gauss-seidel, extrapolation=hold|linear.
import { ALGORITHMS, EXTRAPOLATIONS, FmiError, Master, table } from "./master.mjs";
import { Poser } from "./pose.mjs";
import { exactSimplePendulum } from "./exact.mjs";

const COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2"];
const TRACE_POINTS = 4000; // per trace: the oldest are dropped
const GRAB_PIXELS = 18;
const PREVIEW_SECONDS = 10; // the camera frames what the scene covers in its first seconds

const scene = JSON.parse(document.getElementById("scene").textContent);
const parameters = new URLSearchParams(location.search);
const $ = (id) => document.getElementById(id);

function options() {
  return { algorithm: parameters.get("algorithm") ?? scene.algorithm,
           extrapolation: parameters.get("extrapolation") ?? scene.extrapolation };
}

/** Runs to T without drawing; the result (or the problem) goes into <pre id="check">. */
async function check(T) {
  const out = $("check");
  try {
    if (!(T > 0 && Number.isFinite(T))) throw new Error(`check=${parameters.get("check")}: give a positive time`);
    const master = await Master.create(scene, options());
    const begin = performance.now();
    const problem = master.runTo(T);
    const wall = (performance.now() - begin) / 1000;
    if (problem) throw new Error(problem);
    out.textContent = JSON.stringify({ ...master.snapshot(), wall_per_second: wall / T, steps: master.steps });
  } catch (error) {
    out.textContent = JSON.stringify({ error: String(error.message ?? error) });
  }
  out.dataset.done = "true";
}

/** Groups of coupled components (joined by connections, either way). */
function groups() {
  const names = scene.components.map((c) => c.name);
  const group = table(names.map((n) => [n, n]));
  const find = (n) => (group[n] === n ? n : (group[n] = find(group[n])));
  for (const [source, , target] of scene.connections) group[find(source)] = find(target);
  const found = new Map();
  for (const n of names) {
    const root = find(n);
    if (!found.has(root)) found.set(root, []);
    found.get(root).push(n);
  }
  return scene.layout === "side by side" ? [...found.values()] : [names];
}

class LiveView {
  constructor(master) {
    this.master = master;
    this.canvas = $("scene-canvas");
    this.context = this.canvas.getContext("2d");
    this.running = true;
    this.speed = 1;
    this.frameTime = 1 / scene.frame_rate;
    this.frameCost = 0; // milliseconds of computation per frame, smoothed
    this.spec = table(scene.components.map((c) => [c.name, c])); // each component as the scene gives it
    this.posers = table();
    this.planes = table();
    this.sources = this.inputSources();
    this.colours = table();
    scene.components.forEach((c, k) => { this.colours[c.name] = COLOURS[k % COLOURS.length]; });
    this.layout();
    this.controls();
    this.restart();
    requestAnimationFrame((now) => this.tick(now));
  }

  /** For each unit: input name -> [source unit, output], to draw elements between their ends. */
  inputSources() {
    const sources = table();
    for (const [source, output, target, input] of scene.connections) {
      (sources[target] ??= table())[input] = [source, output];
    }
    return sources;
  }

  /** The two axes a unit is drawn in: those of its first trace (a 3-D object traced from above is
   * drawn from above), else x and y. */
  plane(unit) {
    const trace = this.spec[unit.name].traces[0];
    for (const point of trace ? unit.meta.points : []) {
      const axis = (name) => Object.keys(point.axes).find((a) => point.axes[a] === name);
      if (axis(trace[0]) && axis(trace[1])) return [axis(trace[0]), axis(trace[1])];
    }
    return ["x", "y"];
  }

  /** The points drawn for a unit, [horizontal, vertical] each: its anchor, then its object's points
   * in file order; an element (the Spring) between the points feeding its ends. A point the
   * coordinates move can be grabbed (by its two position outputs). */
  figure(unit) {
    const meta = unit.meta, points = [], [a, b] = (this.planes[unit.name] ??= this.plane(unit));
    if (meta.anchor?.[a] && meta.anchor?.[b]) {
      points.push({ at: [unit.setting(meta.anchor[a]), unit.setting(meta.anchor[b])], mass: false });
    }
    const shapes = this.spec[unit.name].shapes ?? [];
    meta.points.forEach((point, k) => {
      const [h, v] = [point.axes[a], point.axes[b]];
      if (!h || !v) return;
      const { link, radius } = shapes[k] ?? {};
      points.push({ at: [unit.output(h), unit.output(v)], mass: point.moves && point.mass,
                    grab: point.moves ? [h, v] : null, radius,
                    link: link ? [link["xyz".indexOf(a)], link["xyz".indexOf(b)]] : null });
    });
    for (const [xIn, yIn] of meta.spring_ends) {
      const [sx, ox] = this.sources[unit.name]?.[xIn] ?? [], [sy, oy] = this.sources[unit.name]?.[yIn] ?? [];
      if (sx && sy) points.push({ at: [this.master.unit(sx).output(ox), this.master.unit(sy).output(oy)], spring: true });
    }
    return points;
  }

  tracePoints(unit) {
    return this.spec[unit.name].traces.map(([x, y]) => [unit.output(x), unit.output(y)]);
  }

  /** Panels (one per group when the scene lays them side by side) framed around what the scene
   * covers in its first seconds, at the camera's scale where that fits the window. */
  layout(keep = false) {
    const panels = groups().map((names) => ({ names, box: [Infinity, Infinity, -Infinity, -Infinity] }));
    const grow = () => {
      for (const panel of panels) {
        for (const name of panel.names) {
          const unit = this.master.unit(name);
          for (const [x, y] of [...this.figure(unit).flatMap((p) => (p.link ? [p.at, p.link] : [p.at])), ...this.tracePoints(unit)]) {
            if (!Number.isFinite(x) || !Number.isFinite(y)) continue;
            const b = panel.box;
            [b[0], b[1], b[2], b[3]] = [Math.min(b[0], x), Math.min(b[1], y), Math.max(b[2], x), Math.max(b[3], y)];
          }
        }
      }
    };
    grow();
    const end = Math.min(scene.stop ?? PREVIEW_SECONDS, PREVIEW_SECONDS);
    try {
      while (this.master.time < end - 1e-9 && !this.master.step()) grow();
    } catch (error) {
      // framed by what ran; the restart that follows shows the problem if it persists
    }
    const fits = (panel, k) => {
      const old = this.panels?.[k]?.box, b = panel.box;
      return old && b[0] >= old[0] && b[1] >= old[1] && b[2] <= old[2] && b[3] <= old[3];
    };
    if (keep && panels.every(fits)) return; // the frame stays where it still shows the scene
    for (const panel of panels) {
      const b = panel.box, size = Math.max(b[2] - b[0], b[3] - b[1], 0.5);
      const pad = 0.12 * size, widen = Math.max(0, 0.6 * (b[3] - b[1]) - (b[2] - b[0])) / 2; // no sliver of a panel
      panel.box = [b[0] - pad - widen, b[1] - pad, b[2] + pad + widen, b[3] + pad];
    }
    const width = panels.reduce((s, p) => s + p.box[2] - p.box[0], 0);
    const height = Math.max(...panels.map((p) => p.box[3] - p.box[1]));
    const room = Math.max(320, Math.min(window.innerWidth - 50, 1600));
    const fit = Math.min(room / width, 640 / height);
    this.scale = scene.scale ? Math.min(scene.scale, fit) : fit;
    let left = 0;
    for (const panel of panels) {
      panel.left = left;
      panel.width = (panel.box[2] - panel.box[0]) * this.scale;
      left += panel.width;
    }
    this.panels = panels;
    this.canvas.width = Math.ceil(left);
    this.canvas.height = Math.ceil(height * this.scale);
    this.panelOf = table();
    for (const panel of panels) for (const name of panel.names) this.panelOf[name] = panel;
  }

  /** World point of a unit's panel to canvas pixels, and back. */
  toCanvas(name, [x, y]) {
    const p = this.panelOf[name];
    return [p.left + (x - p.box[0]) * this.scale, (p.box[3] - y) * this.scale];
  }

  toWorld(name, [cx, cy]) {
    const p = this.panelOf[name];
    return [p.box[0] + (cx - p.left) / this.scale, p.box[3] - cy / this.scale];
  }

  controls() {
    $("about").textContent = scene.description ?? "";
    $("play").onclick = () => this.setRunning(!this.running);
    $("step").onclick = () => {
      this.setRunning(false);
      this.advance((this.master.steps + 1) * this.master.H);
      this.draw();
    };
    $("restart").onclick = () => this.restart();
    $("original").onclick = () => {
      for (const unit of this.master.units) unit.start = table(Object.entries(unit.sceneStart));
      this.rebuildTable();
      this.restart();
    };
    $("speed").onchange = (e) => { this.speed = Number(e.target.value); };
    const coupled = scene.connections.length > 0;
    for (const [id, values, chosen] of [["algorithm", ALGORITHMS, this.master.algorithm],
                                        ["extrapolation", EXTRAPOLATIONS, this.master.linear ? "linear" : "hold"]]) {
      $(`${id}-choice`).hidden = !coupled;
      $(id).replaceChildren(...values.map((v) => new Option(v, v, v === chosen, v === chosen)));
      $(id).onchange = () => {
        this.master.algorithm = $("algorithm").value;
        this.master.linear = $("extrapolation").value === "linear";
        this.restart();
      };
    }
    this.rebuildTable();
    this.canvas.addEventListener("pointerdown", (e) => this.grab(e));
    this.canvas.addEventListener("pointermove", (e) => this.drag(e));
    for (const end of ["pointerup", "pointercancel"]) this.canvas.addEventListener(end, (e) => this.release(e));
  }

  rebuildTable() {
    const body = $("components").tBodies[0];
    body.replaceChildren();
    this.cells = table();
    for (const unit of this.master.units) {
      const row = body.insertRow(), meta = unit.meta;
      const nameCell = row.insertCell();
      const swatch = document.createElement("span");
      swatch.className = "swatch";
      swatch.style.background = this.colours[unit.name];
      nameCell.append(swatch, unit.name);
      row.insertCell().textContent = meta.identifier;
      const method = row.insertCell();
      if (meta.solvers.length) {
        const select = document.createElement("select");
        Object.assign(select.dataset, { component: unit.name, setting: "solver" });
        for (const [name, value, description] of meta.solvers) {
          const option = new Option(name, value, false, value === unit.setting("solver"));
          option.title = description;
          select.add(option);
        }
        select.onchange = () => {
          this.change(unit, "solver", Number(select.value));
          this.rebuildTable();  // the order field follows the method
          this.report();
        };
        method.append(select);
      } else method.textContent = "-";
      // the order field: taylor_order for taylor, gbs_columns for gbs, none for the other methods
      const solver = meta.solvers.find(([, value]) => value === unit.setting("solver"))?.[0];
      const order = meta.order_settings?.[solver];
      for (const name of ["h", "tol", order]) {
        const cell = row.insertCell();
        if (name === undefined || !(name in meta.defaults)) { cell.textContent = "-"; continue; }
        // an Integer goes to the FMU as 32 bits: a fraction or a larger number would arrive as another value
        const integer = meta.variables[name][1] === "integer";
        const input = document.createElement("input");
        input.type = "number";
        input.step = integer ? "1" : "any";
        input.title = name;
        input.value = unit.setting(name);
        Object.assign(input.dataset, { component: unit.name, setting: name });
        input.onchange = () => {
          const value = input.value.trim() === "" ? NaN : Number(input.value);
          if (integer ? Number.isInteger(value) && Math.abs(value) < 2 ** 31 : Number.isFinite(value)) {
            return this.change(unit, name, value, input);
          }
          $("problem").textContent = `${unit.name}: ${name} = '${input.value}' is not ${integer ? "a 32-bit integer" : "a number"}; ` +
            `kept ${unit.setting(name)}`;
          input.value = unit.setting(name);
        };
        cell.append(input);
      }
      this.cells[unit.name] = { energy: row.insertCell(), change: row.insertCell(), error: row.insertCell() };
    }
  }

  /** A method setting changed: the scene restarts with it, or the FMU's refusal is shown. */
  change(unit, name, value, input) {
    const before = unit.start[name];
    unit.start[name] = value;
    if (!this.restart()) {
      if (before === undefined) delete unit.start[name];
      else unit.start[name] = before;
      if (input) input.value = unit.setting(name);
      this.restart(false);
    }
  }

  /** Every unit from its start at t = 0, traces cleared; false (and the problem shown) on failure. */
  restart(report = true) {
    try {
      this.master.restart();
      if (report) $("problem").textContent = "";
    } catch (error) {
      if (report) $("problem").textContent = String(error.message ?? error);
      return false;
    }
    this.traces = table();
    this.energy0 = table(this.master.units.map((u) => [u.name, u.energy]));
    this.recordTraces();
    this.simTarget = 0;
    this.draw();
    return true;
  }

  setRunning(running) {
    this.running = running;
    $("play").textContent = running ? "Pause" : "Play";
    this.report();
    this.nextFrame = undefined;
  }

  recordTraces() {
    for (const unit of this.master.units) {
      this.tracePoints(unit).forEach((point, k) => {
        const trace = ((this.traces[unit.name] ??= [])[k] ??= []);
        trace.push(point);
        if (trace.length > TRACE_POINTS) trace.splice(0, trace.length - TRACE_POINTS);
      });
    }
  }

  /** Macro steps up to the simulated time `target`; the computation's cost is kept per frame. */
  advance(target) {
    const begin = performance.now();
    try {
      while ((this.master.steps + 1) * this.master.H <= target + 1e-9) {
        const problem = this.master.step();
        if (problem) throw new FmiError(problem);
        this.recordTraces();
      }
    } catch (error) {
      $("problem").textContent = `stopped at t = ${this.master.time.toFixed(3)} s: ${error.message ?? error}`;
      this.setRunning(false);
    }
    const cost = performance.now() - begin;
    this.frameCost = this.frameCost ? 0.9 * this.frameCost + 0.1 * cost : cost;
  }

  tick(now) {
    if (this.running && !this.dragging) {
      const frameMs = 1000 * this.frameTime;
      if (this.nextFrame === undefined || now - this.nextFrame > frameMs) this.nextFrame = now; // start, or a stall
      if (now >= this.nextFrame - 1) { // frames at the scene's rate on average, whatever the display's
        this.nextFrame += frameMs;
        this.simTarget = Math.max(this.simTarget, this.master.time) + this.speed * this.frameTime;
        this.advance(this.simTarget);
        // what a slow frame could not reach is dropped, not owed: the scene slows down instead of freezing
        this.simTarget = Math.min(this.simTarget, this.master.time + this.master.H);
        this.draw();
      }
    }
    requestAnimationFrame((t) => this.tick(t));
  }

  /** The exact solution's distance from the FMU's bob, where the object has one and its start
   * allows it: released from rest, no damping, no force. */
  exactError(unit) {
    const meta = unit.meta;
    if (meta.exact !== "simple pendulum" || this.sources[unit.name]) return null;
    const s = (n) => unit.setting(n);
    if (s("omega") !== 0 || s("d") !== 0 || ["F_x", "F_y", "F2_x", "F2_y"].some((n) => (s(n) ?? 0) !== 0)) return null;
    if (!(Math.abs(s("phi")) < Math.PI)) return null;
    const [phi] = exactSimplePendulum(s("phi"), this.master.time, s("g"), s("L"));
    const x = s("anchor_x") + s("L") * Math.sin(phi), y = s("anchor_y") - s("L") * Math.cos(phi);
    return Math.hypot(unit.output("x") - x, unit.output("y") - y);
  }

  draw() {
    const c = this.context, master = this.master;
    c.clearRect(0, 0, this.canvas.width, this.canvas.height);
    c.strokeStyle = "#e4e4e4";
    for (const panel of this.panels.slice(1)) {
      c.beginPath();
      c.moveTo(panel.left, 0);
      c.lineTo(panel.left, this.canvas.height);
      c.stroke();
    }
    for (const unit of master.units) {
      const colour = this.colours[unit.name];
      c.lineWidth = 1;
      c.strokeStyle = colour;
      c.globalAlpha = 0.45;
      for (const trace of this.traces[unit.name] ?? []) {
        c.beginPath();
        trace.forEach((point, k) => {
          const [px, py] = this.toCanvas(unit.name, point);
          if (k) c.lineTo(px, py); else c.moveTo(px, py);
        });
        c.stroke();
      }
      c.globalAlpha = 1;
      const figure = this.figure(unit).map((p) => ({ ...p, px: this.toCanvas(unit.name, p.at) }));
      c.strokeStyle = "#444";
      c.lineWidth = 2;
      if (figure.some((p) => p.spring)) drawSpring(c, figure.map((p) => p.px));
      else if (figure.some((p) => p.link)) { // each ball on its own string (a cradle), not a chain
        c.beginPath();
        for (const p of figure.filter((p) => p.link)) {
          c.moveTo(...this.toCanvas(unit.name, p.link));
          c.lineTo(...p.px);
        }
        c.stroke();
      } else {
        c.beginPath();
        figure.forEach((p, k) => (k ? c.lineTo(...p.px) : c.moveTo(...p.px)));
        c.stroke();
      }
      for (const p of figure) {
        if (p.spring) continue;
        c.beginPath();
        // a ball at its size where the object file gives its radius (touching balls touch on screen)
        c.arc(p.px[0], p.px[1], p.radius ? Math.max(p.radius * this.scale, 2) : p.mass ? 7 : 3.5, 0, 2 * Math.PI);
        c.fillStyle = p.mass ? colour : "#444";
        c.fill();
      }
    }
    c.fillStyle = "#333";
    c.font = "13px system-ui, sans-serif";
    if (this.panels.length > 1) for (const panel of this.panels) c.fillText(panel.names.join(", "), panel.left + 6, 16);
    this.report();
  }

  report() {
    const master = this.master, format = (v, digits = 4) => (Number.isFinite(v) ? v.toPrecision(digits) : "-");
    const total = master.units.reduce((s, u) => s + (Number.isFinite(u.energy) ? u.energy : 0), 0);
    const total0 = Object.values(this.energy0).reduce((s, e) => s + (Number.isFinite(e) ? e : 0), 0);
    $("status").textContent = `${this.running ? "" : "paused   "}t = ${master.time.toFixed(2)} s   energy ${format(total, 6)} J ` +
      `(change ${format(total - total0, 3)} J)   ${scene.frame_rate} frames/s   ` +
      `computation ${this.frameCost.toFixed(3)} ms per frame   scale ${this.scale.toFixed(0)} px/m`;
    for (const unit of master.units) {
      const cells = this.cells[unit.name];
      cells.energy.textContent = format(unit.energy, 6);
      cells.change.textContent = format(unit.energy - this.energy0[unit.name], 3);
      const error = this.exactError(unit);
      cells.error.textContent = error === null ? "-" : format(error, 3);
    }
  }

  // ---- dragging a mass
  /** Canvas pixels of a pointer event (inside the canvas's border), and page pixels of canvas ones. */
  pointer(e) {
    const r = this.canvas.getBoundingClientRect(), c = this.canvas;
    return [(e.clientX - r.left - c.clientLeft) * (c.width / c.clientWidth),
            (e.clientY - r.top - c.clientTop) * (c.height / c.clientHeight)];
  }

  pagePoint([cx, cy]) {
    const r = this.canvas.getBoundingClientRect(), c = this.canvas;
    return [r.left + c.clientLeft + cx * (c.clientWidth / c.width), r.top + c.clientTop + cy * (c.clientHeight / c.height)];
  }

  grab(e) {
    const at = this.pointer(e);
    let best = null;
    for (const unit of this.master.units) {
      if (!unit.meta.coordinates.length) continue;
      for (const p of this.figure(unit)) {
        if (!p.grab) continue;
        const [px, py] = this.toCanvas(unit.name, p.at), distance = Math.hypot(px - at[0], py - at[1]);
        if (distance <= GRAB_PIXELS && (!best || distance < best.distance)) best = { unit, grab: p.grab, distance };
      }
    }
    if (!best) return;
    e.preventDefault();
    this.canvas.setPointerCapture(e.pointerId);
    this.canvas.classList.add("dragging");
    this.dragging = { ...best, origin: at, moved: false };
  }

  drag(e) {
    const held = this.dragging;
    if (!held) return;
    const at = this.pointer(e);
    if (!held.moved && Math.hypot(at[0] - held.origin[0], at[1] - held.origin[1]) < 3) return; // a click
    held.moved = true;
    const unit = held.unit, meta = unit.meta;
    const poser = (this.posers[unit.name] ??= new Poser(this.master.modules[this.spec[unit.name].module], meta,
                                                        unit.name));
    const q0 = meta.coordinates.map(([q]) => unit.output(q));
    try {
      const { start } = poser.pose(unit.start, q0, ...held.grab, this.toWorld(unit.name, at));
      const before = unit.start;
      unit.start = start;
      if (!this.restart()) {
        unit.start = before;
        this.restart(false);
      }
    } catch (error) {
      $("problem").textContent = String(error.message ?? error);
    }
  }

  release() {
    const held = this.dragging;
    if (!held) return;
    this.dragging = null;
    this.canvas.classList.remove("dragging");
    if (held.moved) {
      this.layout(true); // framed anew only where the new start leaves the frame
      this.restart();
    }
    this.nextFrame = undefined;
  }
}

/** A zigzag through the canvas points (a spring between its ends). */
function drawSpring(c, points) {
  for (let k = 0; k + 1 < points.length; k++) {
    const [ax, ay] = points[k], [bx, by] = points[k + 1];
    const length = Math.hypot(bx - ax, by - ay) || 1, nx = -(by - ay) / length, ny = (bx - ax) / length;
    c.beginPath();
    c.moveTo(ax, ay);
    const turns = 12;
    for (let i = 1; i < turns; i++) {
      const f = i / turns, side = i % 2 ? 6 : -6;
      c.lineTo(ax + (bx - ax) * f + nx * side, ay + (by - ay) * f + ny * side);
    }
    c.lineTo(bx, by);
    c.stroke();
  }
}

async function main() {
  const T = parameters.get("check");
  if (T !== null) return check(Number(T));
  try {
    const master = await Master.create(scene, options());
    const view = new LiveView(master);
    // for scripts and tests: the running view and the world-to-page mapping of a unit's point
    window.pendulumView = {
      view, master,
      snapshot: () => master.snapshot(),
      pause: () => view.setRunning(false),
      play: () => view.setRunning(true),
      pagePoint: (name, point) => view.pagePoint(view.toCanvas(name, point)),
      scale: () => view.scale * (view.canvas.clientWidth / view.canvas.width),
    };
  } catch (error) {
    $("problem").textContent = String(error.message ?? error);
  }
}

main();
