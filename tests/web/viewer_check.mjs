// Loads the radbake viewer page (served by `radbake serve`) in headless
// Chromium, waits for the first frame, fails on any console error, and
// writes the canvas as a PNG:
//
//     node viewer_check.mjs <page url> <out.png>
//
// Prints JSON: { three, cameras, probes, errors } on stdout.

import fs from 'node:fs';
import { execSync } from 'node:child_process';
import puppeteer from 'puppeteer-core';

const [url, out] = process.argv.slice(2);
if (!url || !out) {
  console.error('usage: node viewer_check.mjs <page url> <out.png>');
  process.exit(2);
}
const executablePath = process.env.CHROMIUM || execSync('command -v chromium || command -v chromium-browser').toString().trim();
const browser = await puppeteer.launch({
  executablePath,
  headless: true,
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
const errors = [];
try {
  const tab = await browser.newPage();
  tab.on('pageerror', (e) => errors.push(String(e)));
  tab.on('console', (m) => { if (m.type() === 'error') errors.push(m.text()); });
  tab.on('requestfailed', (r) => errors.push(`request failed: ${r.url()}`));
  tab.on('response', (r) => { if (r.status() >= 400) errors.push(`${r.status()} ${r.url()}`); });
  // Requests in flight, named if the page times out.
  const started = Date.now();
  const pending = new Map();
  tab.on('request', (r) => pending.set(r, Date.now()));
  tab.on('requestfinished', (r) => pending.delete(r));
  tab.on('requestfailed', (r) => pending.delete(r));
  try {
    await tab.goto(url, { waitUntil: 'domcontentloaded', timeout: 120000 });
    await tab.waitForFunction('window.radbake && (window.radbake.ready || window.radbake.error)', { timeout: 120000 });
  } catch (e) {
    const open = [...pending].map(([r, t]) => `${r.url()} (since ${((t - started) / 1000).toFixed(1)} s)`);
    throw new Error(`${e.message}; requests still open: ${open.length ? open.join(', ') : 'none'}`);
  }
  const state = await tab.evaluate(() => ({ ...window.radbake, three: window.__THREE__ }));
  if (state.error) errors.push(state.error);
  const data = await tab.evaluate(() => document.getElementById('view').toDataURL('image/png'));
  fs.writeFileSync(out, Buffer.from(data.split(',')[1], 'base64'));
  console.log(JSON.stringify({ three: state.three, cameras: state.cameras, probes: state.probes, errors }));
} finally {
  await browser.close();
}
