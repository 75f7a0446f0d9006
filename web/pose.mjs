// Dragging a mass: the object's pose nearest to where the person holds one of its points. The
// positions come from the FMU itself (a second instance, started from trial coordinates and read
// after initialization), so every object an object file describes can be dragged; the coordinates
// are found by Levenberg-Marquardt from the current pose, which keeps the coordinates the point does
// not need where they were. The start's velocities stay as they were (at rest for a pendulum
// released from rest; a spherical pendulum keeps its spin, without which it would fall through its
// coordinates' pole).
import { beginInstance } from "./master.mjs";

const MAX_ITERATIONS = 60;

export class Poser {
  constructor(fmu, meta, name) {
    this.meta = meta;
    this.name = name;
    this.instance = fmu.instantiate(`${name} (pose)`, meta.guid);
    this.begun = false;
  }

  /** The outputs `names` of the object started from `start` with coordinates q. */
  positions(start, q, names) {
    if (this.begun) this.instance.reset();
    this.begun = true;
    const values = Object.assign(Object.create(null), start);
    this.meta.coordinates.forEach(([coordinate], i) => { values[coordinate] = q[i]; });
    const check = beginInstance(this.instance, this.meta, values, 0, this.name);
    check(this.instance.exitInitialization(), "fmi2ExitInitializationMode");
    const [status, got] = this.instance.getReal(names.map((n) => this.meta.variables[n][0]));
    check(status, "fmi2GetReal");
    return Array.from(got);
  }

  /** Start values that put the point (outputs xName, yName) nearest to target [x, y], from the
   * coordinates q0, the start's velocities kept; {start, distance}. A trial the FMU refuses counts
   * as a worse one. */
  pose(start, q0, xName, yName, target) {
    const names = [xName, yName];
    const residual = (q) => {
      try {
        const [x, y] = this.positions(start, q, names);
        return [x - target[0], y - target[1]];
      } catch (error) {
        return null;
      }
    };
    const norm = (r) => Math.hypot(r[0], r[1]);
    let q = Array.from(q0), r = residual(q), lambda = 1e-3;
    if (r === null) throw new Error(`${this.name}: its present pose cannot be started`);
    for (let iteration = 0; iteration < MAX_ITERATIONS && norm(r) > 1e-12; iteration++) {
      const jacobian = q.map((qi, i) => { // columns d r / d q_i by one-sided differences
        // forward, or backward where the FMU refuses the forward start (a ball touching the next one)
        for (const e of [1e-7 * (1 + Math.abs(qi)), -1e-7 * (1 + Math.abs(qi))]) {
          const shifted = q.slice();
          shifted[i] += e;
          const rs = residual(shifted);
          if (rs !== null) return [(rs[0] - r[0]) / e, (rs[1] - r[1]) / e];
        }
        return [0, 0];
      });
      let improved = false;
      while (lambda < 1e12) {
        const dq = solveDamped(jacobian, r, lambda);
        const trial = q.map((qi, i) => qi + dq[i]);
        const rt = residual(trial);
        if (rt !== null && norm(rt) < norm(r)) {
          q = trial;
          r = rt;
          lambda = Math.max(lambda / 3, 1e-12);
          improved = true;
          break;
        }
        lambda *= 4;
      }
      if (!improved) break; // the nearest pose: the point cannot come closer (out of reach)
    }
    const posed = Object.assign(Object.create(null), start);
    // an angle dragged round and round is the same angle: kept in (-pi, pi]
    const wrapped = (value, angle) => (angle ? value - 2 * Math.PI * Math.ceil((value - Math.PI) / (2 * Math.PI)) : value);
    this.meta.coordinates.forEach(([coordinate, , angle], i) => { posed[coordinate] = wrapped(q[i], angle); });
    return { start: posed, distance: norm(r) };
  }

  free() {
    this.instance.free();
  }
}

/** dq solving (J^T J + lambda diag) dq = -J^T r, J given by columns [dr0/dqi, dr1/dqi]. */
function solveDamped(columns, r, lambda) {
  const n = columns.length;
  const a = columns.map((ci) => columns.map((cj) => ci[0] * cj[0] + ci[1] * cj[1]));
  const b = columns.map((ci) => -(ci[0] * r[0] + ci[1] * r[1]));
  for (let i = 0; i < n; i++) a[i][i] += lambda * (1 + a[i][i]);
  for (let i = 0; i < n; i++) { // Gaussian elimination with partial pivoting: n is a handful
    let pivot = i;
    for (let k = i + 1; k < n; k++) if (Math.abs(a[k][i]) > Math.abs(a[pivot][i])) pivot = k;
    [a[i], a[pivot]] = [a[pivot], a[i]];
    [b[i], b[pivot]] = [b[pivot], b[i]];
    for (let k = i + 1; k < n; k++) {
      const f = a[k][i] / a[i][i];
      for (let j = i; j < n; j++) a[k][j] -= f * a[i][j];
      b[k] -= f * b[i];
    }
  }
  const x = new Array(n).fill(0);
  for (let i = n - 1; i >= 0; i--) {
    let s = b[i];
    for (let j = i + 1; j < n; j++) s -= a[i][j] * x[j];
    x[i] = s / a[i][i];
  }
  return x;
}
