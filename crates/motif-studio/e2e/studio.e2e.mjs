// End-to-end test of the studio in a real browser (playwright-core driving /usr/bin/chromium):
// deform a generated windmill with the mouse, add a handle after the drag (the shape stays),
// undo / redo, export it (a browser download) and load the download back through the file
// picker, reopen the export with its annotation, resize a generated shelf by a step, show
// detections on a generated facade scan from a file and from the Detect button (with progress),
// detect the symmetries of a fan. Screenshots of every step go to target/studio-e2e/.
//
//   node crates/motif-studio/e2e/studio.e2e.mjs [path/to/motif]
import { execFileSync } from 'node:child_process';
import { existsSync, mkdirSync, readFileSync, rmSync, statSync, writeFileSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { launchBrowser, startStudio, until } from './common.mjs';

const repo = resolve(dirname(fileURLToPath(import.meta.url)), '../../..');
const target = process.env.CARGO_TARGET_DIR || join(repo, 'target');
const motif = resolve(process.argv[2] || join(target, 'debug/motif'));
const out = join(repo, 'target/studio-e2e');
const root = join(out, 'root');
rmSync(root, { recursive: true, force: true });
mkdirSync(root, { recursive: true });

// Inputs made by the CLI: a facade, its ground truth as a detection RESULT.json, and a scan of it.
execFileSync(motif, ['example', 'facade', join(root, 'facade.obj'), '--structure', join(root, 'facade.structure.json'), '--quiet']);
execFileSync(motif, ['sample', join(root, 'facade.obj'), join(root, 'facade_scan.ply'), '--count', '30000', '--quiet']);
execFileSync(motif, ['convert', join(root, 'facade.obj'), join(root, 'facade.stl'), '--quiet']);
const structure = JSON.parse(readFileSync(join(root, 'facade.structure.json'), 'utf8'));
writeFileSync(join(root, 'RESULT.json'), JSON.stringify({ scene: 'facade_scan.ply', classes: structure.instances }));

const { url, proc } = await startStudio(motif, root);
const context = await launchBrowser();
const page = context.pages()[0] || (await context.newPage());
const pageErrors = [];
page.on('pageerror', (e) => pageErrors.push(e.message));

let passed = 0, failed = 0;
function check(cond, what) {
  if (cond) { passed++; console.log(`ok   ${what}`); } else { failed++; console.log(`FAIL ${what}`); }
}
async function shot(name) { await page.waitForTimeout(300); await page.screenshot({ path: join(out, name) }); }
async function clickWorld(p, opts = {}) {
  const s = await page.evaluate((q) => window.motif.project(q), p);
  await page.mouse.click(s.x, s.y, opts);
}

try {
  // 1. Windmill: two handles (tower foot fixed, top blade tip moved), dragged with the gizmo.
  await page.goto(`${url}?example=windmill`);
  let st = await until(page, (s) => s.vertices > 0 && s.name === 'windmill');
  check(st.annotation && st.annotation.mirrors > 0 && st.annotation.axes > 0, `windmill opened with its annotation (${JSON.stringify(st.annotation)})`);
  await shot('01-windmill.png');
  const [lo, hi] = st.bbox;
  const cx = (lo[0] + hi[0]) / 2, cz = (lo[2] + hi[2]) / 2;
  // Front of the tower near its foot, and the top blade near its tip (both on the surface seen).
  const foot = await page.evaluate(([y, z]) => {
    // The rest vertex nearest to the front of the tower foot.
    let best = 0, bd = Infinity;
    for (let i = 0; i < window.motif.state.vertices; i++) {
      const v = window.motif.restVertex(i);
      const d = Math.abs(v[1] - y) + Math.abs(v[2] - z) + Math.abs(v[0]);
      if (d < bd) { bd = d; best = i; }
    }
    return window.motif.restVertex(best);
  }, [lo[1] + 0.05 * (hi[1] - lo[1]), hi[2]]);
  await clickWorld([cx, foot[1] + 0.3, foot[2] - 0.05]);
  st = await until(page, (s) => s.handles === 1);
  const tip = await page.evaluate((ymax) => {
    let best = 0;
    for (let i = 0; i < window.motif.state.vertices; i++) if (window.motif.restVertex(i)[1] > window.motif.restVertex(best)[1]) best = i;
    return window.motif.restVertex(best);
  }, hi[1]);
  await clickWorld([tip[0], tip[1] - 0.4, tip[2] - 0.05]);
  st = await until(page, (s) => s.handles === 2 && s.busy === null);
  check(st.handleSamples.every((k) => k > 0), `two handles picked by clicking (samples ${st.handleSamples})`);
  const g = await page.evaluate(() => window.motif.gizmoScreen());
  await page.mouse.move(g.x, g.y);
  await page.mouse.down();
  for (let i = 1; i <= 12; i++) {
    await page.mouse.move(g.x + 7 * i, g.y + 3 * i);
    await page.waitForTimeout(30);
  }
  await page.mouse.up();
  st = await until(page, (s) => s.released > 0 && s.symmetryResidual !== null);
  check(st.maxDisplacement > 0.01, `dragging the gizmo deformed the mesh (largest move ${(100 * st.maxDisplacement).toFixed(1)}% of the diagonal, ${st.framesReceived} frames)`);
  check(st.symmetryResidual < 1e-6, `symmetry residual after the drag ${st.symmetryResidual} (~0)`);
  check(st.medianFrameMs > 0, `frame time shown (median ${st.medianFrameMs && st.medianFrameMs.toFixed(1)} ms)`);
  await shot('02-windmill-deformed.png');
  const dragged = await page.evaluate(() => window.motif.positions());
  const rest = await page.evaluate(() => { const n = window.motif.state.vertices; const v = []; for (let i = 0; i < n; i++) v.push(...window.motif.restVertex(i)); return v; });
  const maxDiff = (a, b) => a.reduce((m, x, i) => Math.max(m, Math.abs(x - b[i])), 0);
  const dragMove = maxDiff(dragged, rest);

  // 1b. A third handle on a part the drag moved (another blade: the symmetric copies follow):
  // the shape must stay as it is, not snap back.
  const third = await page.evaluate(([moved, restPos, h2]) => {
    const n = moved.length / 3;
    let best = null;
    for (let i = 0; i < n; i++) {
      const d = Math.hypot(moved[3 * i] - restPos[3 * i], moved[3 * i + 1] - restPos[3 * i + 1], moved[3 * i + 2] - restPos[3 * i + 2]);
      const far = Math.hypot(restPos[3 * i] - h2[0], restPos[3 * i + 1] - h2[1], restPos[3 * i + 2] - h2[2]);
      if (far < 1.0) continue;
      const p = [moved[3 * i], moved[3 * i + 1], moved[3 * i + 2]];
      const s = window.motif.project(p);
      const g = window.motif.gizmoScreen();
      if (Math.hypot(s.x - g.x, s.y - g.y) < 150) continue; // a click there would grab the gizmo
      if (document.elementFromPoint(s.x, s.y) !== document.querySelector('#viewport canvas')) continue; // under the HUD
      // Visible, and not on a silhouette: the surface around it is hit too.
      const near = (x, y) => { const hit = window.motif.surfaceAt(x, y); return hit && Math.hypot(hit[0] - p[0], hit[1] - p[1], hit[2] - p[2]) < 0.3; };
      if (![[0, 0], [4, 0], [-4, 0], [0, 4], [0, -4]].every(([dx, dy]) => near(s.x + dx, s.y + dy))) continue;
      if (!best || d > best.d) best = { d, s };
    }
    return best;
  }, [dragged, rest, tip]);
  check(third && third.d > 0.3 * dragMove, `a visible vertex moved by the drag to put a third handle on (moved ${third && third.d.toFixed(3)} of ${dragMove.toFixed(3)})`);
  let version = (await page.evaluate(() => window.motif.state)).meshVersion;
  await page.mouse.click(third.s.x, third.s.y);
  st = await until(page, (s, v) => s.handles === 3 && s.busy === null && s.meshVersion > v, version);
  const kept = await page.evaluate(() => window.motif.positions());
  const drift = maxDiff(kept, dragged);
  check(drift < 0.15 * dragMove, `adding a handle after the drag kept the shape (changed by ${drift.toFixed(4)}, the drag moved ${dragMove.toFixed(3)})`);
  await shot('02b-windmill-third-handle.png');

  // 1c. Undo: back to two handles with the drag, then to the rest pose; redo: the drag again.
  check(st.undo === 4 && st.redo === 0, `undo stack after picks, drag and pick: ${st.undo} / ${st.redo}`);
  await page.click('#undo');
  st = await until(page, (s) => s.handles === 2 && s.busy === null && s.redo === 1 && s.symmetryResidual !== null);
  check(maxDiff(await page.evaluate(() => window.motif.positions()), dragged) < 0.15 * dragMove, 'undo removed the third handle and kept the drag');
  await page.click('#undo');
  st = await until(page, (s) => s.handles === 2 && s.busy === null && s.redo === 2 && s.symmetryResidual !== null);
  const undone = maxDiff(await page.evaluate(() => window.motif.positions()), rest);
  check(undone < 1e-4, `undo again: back to the rest pose (max distance ${undone.toExponential(1)})`);
  await shot('02c-windmill-undone.png');
  await page.click('#redo');
  st = await until(page, (s) => s.handles === 2 && s.busy === null && s.redo === 1 && s.released > 1 && s.symmetryResidual !== null);
  const redone = maxDiff(await page.evaluate(() => window.motif.positions()), dragged);
  check(redone < 1e-4 && st.symmetryResidual < 1e-6, `redo: the drag is back (max distance ${redone.toExponential(1)}, residual ${st.symmetryResidual})`);

  // 1d. Select the first handle by clicking its ball, remove it with Delete, and bring it back
  // with Ctrl+Z: the drag is kept throughout.
  await page.keyboard.press('Escape');
  const ball = await page.evaluate(() => window.motif.handleScreen(0));
  await page.mouse.click(ball.x, ball.y);
  const selected = await page.evaluate(() => window.motif.activeHandle());
  await page.keyboard.press('Delete');
  st = await until(page, (s) => s.handles === 1 && s.busy === null);
  const afterDelete = await page.evaluate(() => window.motif.state.undo);
  await page.keyboard.press('Control+z');
  st = await until(page, (s) => s.handles === 2 && s.busy === null && s.symmetryResidual !== null);
  const back = maxDiff(await page.evaluate(() => window.motif.positions()), dragged);
  check(selected === 0 && afterDelete === st.undo + 1 && back < 1e-4,
    `a click on a handle selects it (${selected}), Delete removes it, Ctrl+Z brings it back with the drag (max distance ${back.toExponential(1)})`);

  // 1e. Leaving the page with a deformation asks first; so does detecting symmetry (a new
  // deformation from the undeformed model), and "no" keeps the deformation.
  const leaveAsks = () => page.evaluate(() => { const e = new Event('beforeunload', { cancelable: true }); window.dispatchEvent(e); return e.defaultPrevented; });
  check(await leaveAsks(), 'leaving the page with a deformation asks first');
  let asked = null;
  page.once('dialog', (d) => { asked = d.message(); d.dismiss(); });
  await page.click('#detect-symmetry');
  await page.waitForTimeout(300);
  st = await page.evaluate(() => window.motif.state);
  const keptAfterNo = maxDiff(await page.evaluate(() => window.motif.positions()), dragged);
  check(asked && /discarded/.test(asked) && st.busy === null && st.handles === 2 && keptAfterNo < 1e-4,
    `detecting symmetry on a deformed model asks first ("${asked && asked.split('\n')[0]}"); "no" keeps the deformation (max distance ${keptAfterNo.toExponential(1)})`);

  // 2. Export the deformed windmill with its annotation: written under the root and downloaded
  // by the browser; the download loads back through the file picker; the export opens again.
  await page.fill('#export-path', 'windmill-deformed.obj');
  const downloaded = page.waitForEvent('download', { timeout: 60000 });
  await page.click('#export');
  const download = await downloaded;
  const savedAs = join(out, `download-${download.suggestedFilename()}`);
  await download.saveAs(savedAs);
  st = await until(page, (s) => s.saved.includes('windmill-deformed.obj'));
  check(st.saved.includes('windmill-deformed.sym.json'), `exported ${st.saved.join(', ')}`);
  check(download.suggestedFilename() === 'windmill-deformed.obj' && existsSync(savedAs) && statSync(savedAs).size === statSync(join(root, 'windmill-deformed.obj')).size,
    `the browser downloaded ${download.suggestedFilename()} (${existsSync(savedAs) ? statSync(savedAs).size : 0} bytes)`);
  // The same name again is refused until "replace existing files" is ticked (the page had no
  // way to allow it).
  const errorsBefore = st.errors.length;
  await page.click('#export');
  st = await until(page, (s, n) => s.errors.length > n && s.busy === null, errorsBefore);
  check(/already exists/.test(st.errors[st.errors.length - 1]), `exporting onto the same name is refused: ${st.errors[st.errors.length - 1]}`);
  await page.check('#overwrite');
  const savedBefore = st.saved.length;
  const again = page.waitForEvent('download', { timeout: 60000 });
  await page.click('#export');
  await again;
  st = await until(page, (s, n) => s.saved.length > n && s.busy === null, savedBefore);
  check(st.saved.slice(savedBefore).includes('windmill-deformed.obj'), `with "replace existing files" ticked the export is written again: ${st.saved.slice(savedBefore).join(', ')}`);
  await page.uncheck('#overwrite');
  // 2b. "Yes" discards the deformation: the page shows the undeformed model, as the server
  // (and so an export) now holds it, and the old handles leave the undo history.
  page.once('dialog', (d) => d.accept());
  await page.click('#detect-symmetry');
  st = await until(page, (s) => s.busy === null && s.handles === 0 && s.annotation && s.annotation.maxResidual !== null);
  const restAgain = maxDiff(await page.evaluate(() => window.motif.positions()), rest);
  check(restAgain < 1e-6 && st.undo === 0 && !(await leaveAsks()),
    `after "yes" the page shows the undeformed windmill (max distance ${restAgain.toExponential(1)}), undo ${st.undo}, leaving no longer asks`);
  await page.setInputFiles('#upload', savedAs);
  st = await until(page, (s) => s.name === 'download-windmill-deformed.obj' && s.meshVersion > 0);
  const uploaded = maxDiff(await page.evaluate(() => window.motif.positions()), dragged);
  check(st.vertices === 1064 && uploaded < 1e-4, `the download loads back through the file picker: ${st.vertices} vertices, the deformed shape (max distance ${uploaded.toExponential(1)})`);
  await shot('03a-download-uploaded.png');
  await page.fill('#open-path', 'windmill-deformed.obj');
  await page.click('#open-btn');
  st = await until(page, (s) => s.name === 'windmill-deformed.obj');
  check(st.vertices === 1064 && st.annotation && st.annotation.symmetries === 6, `reloaded the export: ${st.vertices} vertices, annotation with ${st.annotation && st.annotation.symmetries} symmetries`);
  await shot('03-export-reloaded.png');

  // 3. Shelf: principal offsets, one more cell along the first.
  await page.selectOption('#example-select', 'shelf');
  await page.click('#example-open');
  st = await until(page, (s) => s.name === 'shelf');
  await page.click('#find-offsets');
  st = await until(page, (s) => s.offsets !== null);
  // Export before any resize says so (it used to say the default name "already exists").
  const errorsBefore3 = st.errors.length;
  await page.click('#export-resized');
  st = await until(page, (s, n) => s.errors.length > n && s.busy === null, errorsBefore3);
  check(/nothing resized yet/.test(st.errors[st.errors.length - 1]), `exporting before a resize: ${st.errors[st.errors.length - 1]}`);
  check(st.offsets.principal === 2 && st.totalCells === 12, `shelf: ${st.offsets.principal} principal offsets, cells ${st.cells.join(' x ')}`);
  // A slider moved and released ('change'): one step of the undo history.
  await page.$eval('#step-0', (el) => { el.value = '1'; el.dispatchEvent(new Event('input')); el.dispatchEvent(new Event('change')); });
  st = await until(page, (s) => s.retargetVersion > 0 && s.undo === 1);
  check(st.totalCells === 15 && st.cells[0] === 5, `one step along offset 0: cells ${st.cells.join(' x ')} = ${st.totalCells}`);
  await shot('04-shelf-resized.png');
  // The sliders stop at the fewest cells a resize keeps (the server's bound), and that step
  // resizes without an error.
  const min1 = await page.$eval('#step-1', (el) => Number(el.min));
  const v3 = st.retargetVersion, e3 = st.errors.length;
  await page.$eval('#step-1', (el) => { el.value = el.min; el.dispatchEvent(new Event('input')); el.dispatchEvent(new Event('change')); });
  st = await until(page, (s, v) => s.retargetVersion > v && s.undo === 2, v3);
  check(min1 < 0 && min1 === st.offsets.minSteps[1] && st.errors.length === e3 && st.cells[1] >= 1,
    `offset 1's slider starts at ${min1} steps, which resizes to ${st.cells.join(' x ')} cells without an error`);
  // Sizes are in the undo history with the handles: undo goes back to one step along offset 0,
  // then to the original size (no resized model, sliders at 0); redo resizes again.
  const sizeAfter = st.totalCells;
  await page.click('#undo');
  st = await until(page, (s) => s.undo === 1 && s.resizedSteps && s.resizedSteps[1] === 0 && s.busy === null);
  const slider1 = await page.$eval('#step-1', (el) => Number(el.value));
  check(st.totalCells === 15 && slider1 === 0, `undo: back to steps ${st.resizedSteps} (${st.totalCells} cells, offset 1's slider at ${slider1})`);
  await page.click('#undo');
  st = await until(page, (s) => s.undo === 0 && s.resizedSteps === null);
  const shown = await page.evaluate(() => window.motif.resizedShown());
  check(st.totalCells === 12 && !shown.resized && shown.original, `undo again: the original size (${st.totalCells} cells), resized model gone: ${JSON.stringify(shown)}`);
  await page.click('#redo');
  st = await until(page, (s) => s.redo === 1 && s.resizedSteps && s.resizedSteps[0] === 1);
  await page.click('#redo');
  st = await until(page, (s, m) => s.redo === 0 && s.resizedSteps && s.resizedSteps[1] === m, min1);
  check(st.totalCells === sizeAfter, `redo twice: steps ${st.resizedSteps}, ${st.totalCells} cells as before the undos`);
  check(await leaveAsks(), 'leaving the page with a resized model asks first');
  // Offsets found again remove the resized model; a size set then, undone, gives the
  // original back (the history's older steps no longer name a size).
  await page.click('#find-offsets');
  st = await until(page, (s) => s.busy === null && s.resizedSteps === null);
  await page.$eval('#step-0', (el) => { el.value = '2'; el.dispatchEvent(new Event('input')); el.dispatchEvent(new Event('change')); });
  st = await until(page, (s) => s.resizedSteps && s.resizedSteps[0] === 2 && s.undo === 3);
  await page.click('#undo');
  st = await until(page, (s) => s.undo === 2 && s.busy === null);
  const afterFind = await page.evaluate(() => window.motif.resizedShown());
  check(!afterFind.resized && afterFind.original && st.resizedSteps === null, `offsets found again, a size, undo: the original (${JSON.stringify(afterFind)})`);
  await page.click('#redo');
  st = await until(page, (s) => s.resizedSteps && s.resizedSteps[0] === 2 && s.redo === 0);
  // Detections of another scan shown on the shelf come with a warning.
  await page.fill('#detections-path', 'RESULT.json');
  await page.click('#load-detections');
  st = await until(page, (s) => s.detections !== null && s.busy === null);
  check(st.detections.otherScene && /not on shelf/.test(st.errors[st.errors.length - 1]), `detections of another scan are shown with a warning: ${st.errors[st.errors.length - 1]}`);

  // 3b. An STL (a CAD format) opens Z-up, as Blender shows it; other formats Y-up.
  await page.fill('#open-path', 'facade.stl');
  await page.press('#open-path', 'Enter'); // Enter in a path field does what its button does
  st = await until(page, (s) => s.name === 'facade.stl' && s.busy === null);
  const upStl = await page.evaluate(() => [window.motif.state.upAxis, document.getElementById('z-up').checked]);
  check(upStl[0] === 'z' && upStl[1], `an STL opens Z-up (${upStl})`);
  await shot('04b-stl-z-up.png');

  // 4. Facade scan with detections from a RESULT.json.
  await page.fill('#open-path', 'facade_scan.ply');
  await page.click('#open-btn');
  st = await until(page, (s) => s.name === 'facade_scan.ply' && s.busy === null);
  check((await page.evaluate(() => window.motif.state.upAxis)) === 'y', 'a PLY opens Y-up');
  const meshOnly = await page.evaluate(() => ['find-offsets', 'export-resized', 'undo', 'export'].map((id) => document.getElementById(id).disabled));
  check(meshOnly[0] && meshOnly[1] && meshOnly[2] && !meshOnly[3],
    `a point cloud leaves the mesh-only buttons off (Find offsets, resize Export, Undo: ${meshOnly.slice(0, 3)}) and Export on (${!meshOnly[3]}: a cloud can be written in another format)`);
  await page.fill('#detections-path', 'RESULT.json');
  await page.click('#load-detections');
  st = await until(page, (s) => s.detections !== null);
  check(st.detections.classes === structure.instances.length && st.detections.coloured > 0 && !st.detections.otherScene,
    `detections shown: ${st.detections.classes} classes, ${st.detections.instances} boxes, ${st.detections.coloured} coloured points`);
  await shot('05-facade-detections.png');

  // 4b. Building-block detection from the Detect button, with progress, classes drawn.
  await page.evaluate(() => { window.motif.state.detections = null; window.motif.state.progressLog = []; });
  await page.click('#detect');
  st = await until(page, (s) => s.busy === null && s.detections !== null, null, 600000);
  const stages = [...new Set(st.progressLog.filter((p) => p.job === 'detect').map((p) => p.stage))];
  check(stages.length > 0, `detection progress shown (stages: ${stages.join(', ')})`);
  check(st.detections.classes > 0 && st.detections.instances > 0 && st.detections.coloured > 0,
    `detected: ${st.detections.classes} classes, ${st.detections.instances} boxes, ${st.detections.coloured} coloured points`);
  await shot('05b-facade-detected.png');
  // Saved as a detection result, the same classes and boxes as shown.
  const savedBefore2 = st.saved.length;
  await page.fill('#detections-path', 'facade.detect.json');
  await page.click('#save-detections');
  st = await until(page, (s, n) => s.saved.length > n && s.busy === null, savedBefore2);
  const savedResult = JSON.parse(readFileSync(join(root, 'facade.detect.json'), 'utf8'));
  const savedBoxes = savedResult.classes.reduce((a, c) => a + c.instances.length, 0);
  check(savedResult.classes.length === st.detections.classes && savedBoxes === st.detections.instances,
    `detections saved: ${savedResult.classes.length} classes, ${savedBoxes} boxes in facade.detect.json`);
  // The path fields offer the files under the root, the one just saved among them.
  st = await until(page, (s) => s.files !== null && s.files.json.includes('facade.detect.json'));
  const offered = await page.evaluate(() => [...document.querySelectorAll('#model-files option')].map((o) => o.value));
  check(offered.includes('facade.obj') && offered.includes('facade_scan.ply'),
    `the path fields offer the files under the root (${offered.length} models, ${st.files.json.length} JSON documents)`);

  // 5. Symmetry detection on the fan, shown as planes and axes.
  await page.selectOption('#example-select', 'fan');
  await page.click('#example-open');
  st = await until(page, (s) => s.name === 'fan' && s.symmetryCentre);
  // Its planes and axes are placed about the fan's own centre (they used the previous model's,
  // the facade scan's, while the fan's geometry was on its way).
  const fanCentre = st.bbox[0].map((v, k) => (v + st.bbox[1][k]) / 2);
  check(maxDiff(st.symmetryCentre, fanCentre) < 1e-9, `the fan's symmetry elements are drawn about its own centre (${st.symmetryCentre.map((v) => v.toFixed(3))})`);
  await page.click('#show-symmetry'); // hide the generator's own annotation ...
  await page.click('#show-symmetry'); // ... and show again: the checkbox works both ways
  await page.click('#detect-symmetry');
  st = await until(page, (s) => s.busy === null && s.annotation !== null && s.annotation.maxResidual !== null);
  check(st.annotation.mirrors > 0 && st.annotation.axes > 0 && st.annotation.ok, `fan symmetry detected: ${JSON.stringify(st.annotation)}`);
  await shot('06-fan-symmetry.png');
  check(pageErrors.length === 0, `no page errors ${pageErrors.join('; ')}`);
} catch (e) {
  failed++;
  console.log(`FAIL ${e.message}`);
  const last = await page.evaluate(() => { const s = window.motif.state; return { name: s.name, handles: s.handles, busy: s.busy, errors: s.errors, undo: s.undo, redo: s.redo, meshVersion: s.meshVersion, saved: s.saved, downloads: s.downloads }; }).catch(() => null);
  console.log(`page state: ${JSON.stringify(last)}`);
  if (pageErrors.length) console.log(`page errors: ${pageErrors.join('; ')}`);
  await page.screenshot({ path: join(out, 'failure.png') }).catch(() => {});
} finally {
  await context.close();
  proc.kill();
}
console.log(`screenshots in ${out}`);
console.log(`${passed} passed, ${failed} failed`);
process.exit(failed ? 1 : 0);
