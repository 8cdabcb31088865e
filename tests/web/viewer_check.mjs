// Loads the radbake viewer page (served by `radbake serve`) in headless
// Chromium, waits for the first frame, fails on any console error, and
// writes the canvas as a PNG:
//
//     node viewer_check.mjs <page url> <out.png>
//
// Prints JSON: { three, cameras, probes, layers, live, errors } on stdout.

import fs from 'node:fs';
import { launchChromium } from './chromium.mjs';

const [url, out] = process.argv.slice(2);
if (!url || !out) {
  console.error('usage: node viewer_check.mjs <page url> <out.png>');
  process.exit(2);
}
const browser = await launchChromium();
const errors = [];

// Opens the page in a new tab and waits for the viewer's first frame
// within `timeout` ms; the tab, or an error naming the requests still in
// flight.
async function open(timeout) {
  const tab = await browser.newPage();
  const seen = [];
  tab.on('pageerror', (e) => seen.push(String(e)));
  tab.on('console', (m) => { if (m.type() === 'error') seen.push(m.text()); });
  tab.on('requestfailed', (r) => seen.push(`request failed: ${r.url()}`));
  tab.on('response', (r) => { if (r.status() >= 400) seen.push(`${r.status()} ${r.url()}`); });
  const started = Date.now();
  const pending = new Map();
  tab.on('request', (r) => pending.set(r, Date.now()));
  tab.on('requestfinished', (r) => pending.delete(r));
  tab.on('requestfailed', (r) => pending.delete(r));
  try {
    await tab.goto(url, { waitUntil: 'domcontentloaded', timeout });
    await tab.waitForFunction('window.radbake && (window.radbake.ready || window.radbake.error)', { timeout });
  } catch (e) {
    const open = [...pending].map(([r, t]) => `${r.url()} (since ${((t - started) / 1000).toFixed(1)} s)`);
    await tab.close();
    throw new Error(`${e.message}; requests still open: ${open.length ? open.join(', ') : 'none'}`);
  }
  return { tab, seen };
}

try {
  // A load that stalls fails, naming the requests still open. (Loads
  // stalled here while `radbake serve` ran on tiny_http, whose thread pool
  // could leave a connection unanswered: src/cli/serve.rs. A stalled first
  // load used to be tried once more in a new tab; with the cause gone, a
  // stall is a failure again.)
  const page = await open(120000);
  const { tab, seen } = page;
  errors.push(...seen);
  const state = await tab.evaluate(() => ({ ...window.radbake, three: window.__THREE__ }));
  if (state.error) errors.push(state.error);
  const data = await tab.evaluate(() => document.getElementById('view').toDataURL('image/png'));
  fs.writeFileSync(out, Buffer.from(data.split(',')[1], 'base64'));
  console.log(JSON.stringify({ three: state.three, cameras: state.cameras, probes: state.probes, layers: state.layers, live: state.live, realtime: state.realtime, errors }));
} finally {
  await browser.close();
}
