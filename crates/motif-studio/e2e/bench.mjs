// Frame-time benchmark of the studio (issue 6: above 30 fps end to end on a 100k-vertex model):
// opens a generated model in headless Chromium, places two handles, drags one with the mouse as
// fast as the page takes mouse events, and prints the median of every stage of a frame, from
// the page's clock (performance.now) and the server's timings in each frame's header:
//
//   request    page sends the drag → server receives it (same machine clock: Unix ms)
//   queue      server: received → solve starts
//   solve      server: co-rotated iterations + lifting
//   encode     server: positions → binary message
//   reply      server encoded it → page's message handler runs (socket, browser IPC, page busy)
//   decode     page: header, copy to the CPU shape (for picking)
//   upload     page: bufferSubData of the positions, waited for on the GPU
//   render     page: drawing the scene (mesh, gizmo, overlays), waited for on the GPU
//
// "end to end" is send → drawn per frame; "interval" is the time between two drawn frames while
// the drag runs, i.e. the frame rate the user sees (fps = 1000 / interval).
//
//   node crates/motif-studio/e2e/bench.mjs path/to/motif [--steps 200] [--example windmill_100k]
//        [--width 1280 --height 720]
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
const width = parseInt(opt('--width', '1280'), 10), height = parseInt(opt('--height', '720'), 10);

const root = mkdtempSync(join(tmpdir(), 'motif-bench-studio-'));
const { url, proc } = await startStudio(motif, root, ['--seed', seed]);
const context = await launchBrowser({ width, height });
const page = context.pages()[0] || (await context.newPage());
const quantile = (v, q) => { const s = [...v].sort((a, b) => a - b); return s.length ? s[Math.min(s.length - 1, Math.floor(q * s.length))] : NaN; };
const median = (v) => quantile(v, 0.5);
try {
  const t0 = Date.now();
  await page.goto(`${url}?example=${example}`);
  let st = await until(page, (s, n) => s.name === n && s.meshVersion > 0, example, 600000);
  const load = (Date.now() - t0) / 1000;
  const [lo, hi] = st.bbox;
  const pick = async (p) => {
    const s = await page.evaluate((q) => window.motif.project(q), p);
    await page.mouse.click(s.x, s.y);
  };
  const cx = (lo[0] + hi[0]) / 2;
  // Tower foot (front face) and the top of the upper blade, as in the browser test.
  await pick([cx, lo[1] + 0.05 * (hi[1] - lo[1]) + 0.3, hi[2] - 0.05]);
  await until(page, (s) => s.handles === 1 && s.busy === null, null, 600000);
  const session = await page.evaluate(() => document.getElementById('deform-info').textContent);
  const top = await page.evaluate(() => {
    let best = 0;
    for (let i = 0; i < window.motif.state.vertices; i++) if (window.motif.restVertex(i)[1] > window.motif.restVertex(best)[1]) best = i;
    return window.motif.restVertex(best);
  });
  const t1 = Date.now();
  await pick([top[0], top[1] - 0.4, top[2] - 0.05]);
  st = await until(page, (s) => s.handles === 2 && s.busy === null, null, 600000);
  const handlesSec = (Date.now() - t1) / 1000;
  const before = st.frameLog.length;
  const g = await page.evaluate(() => window.motif.gizmoScreen());
  await page.mouse.move(g.x, g.y);
  await page.mouse.down();
  const d0 = Date.now();
  for (let i = 1; i <= steps; i++) {
    const a = (i / steps) * 2 * Math.PI;
    await page.mouse.move(g.x + 80 * Math.sin(a), g.y + 40 * (1 - Math.cos(a)));
  }
  await page.mouse.up();
  const dragSec = (Date.now() - d0) / 1000;
  st = await until(page, (s) => s.released > 0 && s.symmetryResidual !== null, null, 600000);
  const log = st.frameLog.slice(before);
  const intervals = log.slice(1).map((f, i) => f.drawnAt - log[i].drawnAt);
  const r = st.renderer;
  const canvas = await page.evaluate(() => { const c = document.querySelector('#viewport canvas'); return `${c.width}x${c.height}`; });
  console.log(`motif bench studio: ${example}, ${st.vertices} vertices, ${st.triangles} triangles`);
  console.log(`browser: headless Chromium, window ${width}x${height}, canvas ${canvas}, WebGL ${r.software ? 'software' : 'hardware'} (${r.name}), antialias ${r.antialias ? 'on' : 'off'}`);
  console.log(`model generated and shown in ${load.toFixed(1)} s; first handle (session build + factorisation) in: ${session.split('\n')[1] || '?'}; second handle ${handlesSec.toFixed(1)} s`);
  console.log(`drag: ${steps} mouse moves in ${dragSec.toFixed(1)} s, ${log.length} frames solved and drawn (stale poses dropped)`);
  const row = (name, v, note = '') => console.log(`  ${name.padEnd(26)} ${median(v).toFixed(2).padStart(8)} ms ${quantile(v, 0.9).toFixed(2).padStart(8)} ms  ${note}`);
  console.log(`  ${'stage'.padEnd(26)} ${'median'.padStart(11)} ${'p90'.padStart(11)}`);
  const col = (k) => log.map((f) => f[k]);
  row('request transfer', col('request'), 'page → server');
  row('server queue', col('queue'));
  row('server solve', col('solve'), 'co-rotated iterations + lifting');
  row('server encode', col('encode'), 'binary Float32 positions');
  row('reply transfer', col('reply'), 'server → page handler');
  row('decode', col('decode'), 'header + copy for picking');
  row('GPU upload', col('upload'), 'bufferSubData, waited for');
  row('render', col('render'), `whole scene at ${canvas}, waited for`);
  row('end to end', col('total'), 'page sends the pose → frame drawn');
  row('interval', intervals, 'between drawn frames while dragging');
  const fps = 1000 / median(intervals);
  console.log(`frame rate: ${fps.toFixed(1)} fps (median interval; end-to-end median ${median(col('total')).toFixed(1)} ms = ${(1000 / median(col('total'))).toFixed(1)} fps); target above 30 fps: ${fps > 30 ? 'met' : 'NOT met'}`);
  console.log(`symmetry residual after the drag ${st.symmetryResidual.toExponential(2)} of the diagonal`);
} finally {
  await context.close();
  proc.kill();
}
