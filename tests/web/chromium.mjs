// Headless Chromium for the browser tests (puppeteer-core): `CHROMIUM`,
// or `chromium` / `chromium-browser` on PATH. `gl`: WebGL through ANGLE's
// SwiftShader (the pages that render).
import { execSync } from 'node:child_process';
import puppeteer from 'puppeteer-core';

export function launchChromium({ gl = true } = {}) {
  const executablePath = process.env.CHROMIUM
    || execSync('command -v chromium || command -v chromium-browser').toString().trim();
  const args = gl ? ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'] : ['--no-sandbox'];
  return puppeteer.launch({ executablePath, headless: true, args });
}
