// The simple pendulum's exact motion, released from rest at phi0 without damping or force:
//   phi(t) = 2 asin(k sn(K(m) - w0 t | m)),  omega(t) = -2 k w0 cn(K(m) - w0 t | m),
//   k = sin(phi0 / 2), m = k^2, w0 = sqrt(g / L),
// with the Jacobi elliptic functions by the arithmetic-geometric mean (Abramowitz and Stegun 16.4
// and 17.6), so that the page needs no library.

/** The AGM sequence of (1, sqrt(1 - m)): [a_0..a_n], [c_0..c_n]. */
function agm(m) {
  const a = [1], c = [Math.sqrt(m)];
  let b = Math.sqrt(1 - m);
  while (Math.abs(c.at(-1)) > 1e-17 && a.length < 40) {
    const an = a.at(-1);
    a.push((an + b) / 2);
    c.push((an - b) / 2);
    b = Math.sqrt(an * b);
  }
  return [a, c];
}

/** The complete elliptic integral of the first kind K(m), 0 <= m < 1. */
export function ellipticK(m) {
  return Math.PI / (2 * agm(m)[0].at(-1));
}

/** [sn(u | m), cn(u | m)], 0 <= m < 1. */
export function jacobiSnCn(u, m) {
  const quarter = ellipticK(m);
  u %= 4 * quarter; // sn and cn have the period 4K: keep the angle below small
  const [a, c] = agm(m);
  const n = a.length - 1;
  let phi = 2 ** n * a[n] * u;
  for (let j = n; j > 0; j--) phi = (phi + Math.asin((c[j] / a[j]) * Math.sin(phi))) / 2;
  return [Math.sin(phi), Math.cos(phi)];
}

/** [phi, omega] at t of the pendulum released from rest at phi0 (|phi0| < pi). */
export function exactSimplePendulum(phi0, t, g, L) {
  const k = Math.sin(phi0 / 2), m = k * k, w0 = Math.sqrt(g / L);
  const [sn, cn] = jacobiSnCn(ellipticK(m) - w0 * t, m);
  return [2 * Math.asin(k * sn), -2 * k * w0 * cn];
}
