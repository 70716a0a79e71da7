// Frame-time benchmark of the studio (issue 6: above 30 fps end to end on a 100k-vertex model):
// opens a generated model in headless Chromium, places two handles, drags one with the mouse and
// prints the median of each frame's server solve, transfer and upload + draw (software WebGL).
//
//   node crates/motif-studio/e2e/bench.mjs path/to/motif [--steps 200] [--example windmill_100k]
import { mkdtempSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { launchBrowser, startStudio, until } from './common.mjs';

const args = process.argv.slice(2);
const motif = args[0];
const opt = (name, dflt) => { const i = args.indexOf(name); return i >= 0 ? args[i + 1] : dflt; };
const steps = parseInt(opt('--steps', '200'), 10);
const example = opt('--example', 'windmill_100k');
const seed = opt('--seed', '1');

const root = mkdtempSync(join(tmpdir(), 'motif-bench-studio-'));
const { url, proc } = await startStudio(motif, root, ['--seed', seed]);
const context = await launchBrowser();
const page = context.pages()[0] || (await context.newPage());
const median = (v) => { const s = [...v].sort((a, b) => a - b); return s.length ? s[Math.floor(s.length / 2)] : NaN; };
try {
  const t0 = Date.now();
  await page.goto(`${url}?example=${example}`);
  let st = await until(page, (s, n) => s.name === n && s.vertices > 0, example, 600000);
  const load = (Date.now() - t0) / 1000;
  const [lo, hi] = st.bbox;
  const pick = async (p) => {
    const s = await page.evaluate((q) => window.motif.project(q), p);
    await page.mouse.click(s.x, s.y);
  };
  const cx = (lo[0] + hi[0]) / 2;
  // Tower foot (front face) and the top of the upper blade, as in the browser test.
  await pick([cx, lo[1] + 0.05 * (hi[1] - lo[1]) + 0.3, hi[2] - 0.05]);
  await until(page, (s) => s.handles === 1, null, 600000);
  const top = await page.evaluate(() => {
    let best = 0;
    for (let i = 0; i < window.motif.state.vertices; i++) if (window.motif.restVertex(i)[1] > window.motif.restVertex(best)[1]) best = i;
    return window.motif.restVertex(best);
  });
  const t1 = Date.now();
  await pick([top[0], top[1] - 0.4, top[2] - 0.05]);
  st = await until(page, (s) => s.handles === 2 && s.framesReceived > 0, null, 600000);
  const handlesSec = (Date.now() - t1) / 1000;
  const before = st.framesReceived;
  const g = await page.evaluate(() => window.motif.gizmoScreen());
  await page.mouse.move(g.x, g.y);
  await page.mouse.down();
  const d0 = Date.now();
  for (let i = 1; i <= steps; i++) {
    const a = (i / steps) * 2 * Math.PI;
    await page.mouse.move(g.x + 80 * Math.sin(a), g.y + 40 * (1 - Math.cos(a)));
    await page.waitForTimeout(5);
  }
  await page.mouse.up();
  const dragSec = (Date.now() - d0) / 1000;
  st = await until(page, (s) => s.released > 0 && s.symmetryResidual !== null, null, 600000);
  const log = st.frameLog.slice(before);
  const row = (name, key) => `${name.padEnd(22)} ${median(log.map((f) => f[key])).toFixed(1).padStart(8)} ms`;
  console.log(`motif bench studio: ${example}, ${st.vertices} vertices, ${st.triangles} triangles, headless Chromium (SwiftShader software WebGL)`);
  console.log(`model generated and shown in ${load.toFixed(1)} s; handles (session + factorisation) in ${handlesSec.toFixed(1)} s`);
  console.log(`drag: ${steps} mouse moves in ${dragSec.toFixed(1)} s, ${log.length} frames solved and drawn (stale ones dropped)`);
  console.log('median per frame');
  console.log(row('server solve', 'solve'));
  console.log(row('transfer', 'transfer'));
  console.log(row('upload + draw', 'draw'));
  const total = median(log.map((f) => f.total));
  console.log(`${'end to end'.padEnd(22)} ${total.toFixed(1).padStart(8)} ms  (${(1000 / total).toFixed(1)} fps; target above 30 fps)`);
  console.log(`symmetry residual after the drag ${st.symmetryResidual.toExponential(2)} of the diagonal`);
} finally {
  await context.close();
  proc.kill();
}
