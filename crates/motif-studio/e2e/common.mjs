// Shared by the browser tests and the benchmark: start `motif studio`, launch Debian's Chromium.
import { spawn } from 'node:child_process';
import { mkdtempSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { chromium } from 'playwright-core';

/** Starts `motif studio --root ROOT` on a free port; resolves with { url, proc }. */
export function startStudio(motif, root, extra = []) {
  return new Promise((resolve, reject) => {
    const proc = spawn(motif, ['studio', '--root', root, '--quiet', ...extra], { stdio: ['ignore', 'pipe', 'inherit'] });
    let out = '';
    proc.stdout.on('data', (d) => {
      out += d;
      const m = out.match(/http:\/\/\S+/);
      if (m) resolve({ url: m[0], proc });
    });
    proc.on('exit', (code) => reject(new Error(`motif studio exited with ${code}`)));
  });
}

/** Headless Chromium with software WebGL (SwiftShader) and a fresh profile; downloads allowed. */
export async function launchBrowser(viewport = { width: 1280, height: 800 }) {
  return chromium.launchPersistentContext(mkdtempSync(join(tmpdir(), 'motif-studio-chromium-')), {
    executablePath: process.env.MOTIF_CHROMIUM || '/usr/bin/chromium',
    headless: true,
    acceptDownloads: true,
    viewport,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
  });
}

/** Waits until `fn(state)` is true in the page (state = window.motif.state). */
export async function until(page, fn, arg, timeout = 120000) {
  await page.waitForFunction(
    ([src, a]) => window.motif && (0, eval)(`(${src})`)(window.motif.state, a),
    [fn.toString(), arg],
    { timeout, polling: 50 });
  return page.evaluate(() => window.motif.state);
}
