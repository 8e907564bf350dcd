// Open a replay.html in Debian's headless Chromium (software WebGL), play it,
// and take two screenshots a few seconds apart; write what the page reported
// (console errors, requests, times, P/M cursor, frame rate) to result.json.
// .ci/check_replay.py judges the screenshots and the result.
//
//   node .ci/browser/replay.mjs REPLAY.html OUT_DIR [--measure SECONDS]
//
// --measure: after the screenshots, count the frames drawn over SECONDS of
// playback (how `deepfoids replay`'s README frame rate was measured).
//
// Chromium runs as on the shared CI machine: as root (so --no-sandbox),
// without network services (--disable-background-networking and friends:
// without them its connections are refused and logged as errors), with a
// fresh profile, and WebGL on SwiftShader (no GPU). playwright-core never
// downloads a browser: it drives /usr/bin/chromium.
import { chromium } from 'playwright-core';
import { mkdtempSync, mkdirSync, writeFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, resolve } from 'node:path';
import { pathToFileURL } from 'node:url';

const [html, outDir, ...rest] = process.argv.slice(2);
if (!html || !outDir) {
  console.error('usage: node replay.mjs REPLAY.html OUT_DIR [--measure SECONDS]');
  process.exit(2);
}
const measure = rest[0] === '--measure' ? Number(rest[1]) : 0;
mkdirSync(outDir, { recursive: true });
const profile = mkdtempSync(join(tmpdir(), 'deepfoids-chromium-'));
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

const browser = await chromium.launchPersistentContext(profile, {
  executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
  headless: true,
  viewport: { width: 1280, height: 800 },
  args: [
    '--no-sandbox',
    '--disable-gpu',
    '--disable-quic',
    '--no-first-run',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
    '--use-angle=swiftshader',
    '--enable-unsafe-swiftshader',
  ],
});
const result = { file: resolve(html), console_errors: [], page_errors: [], requests: [] };
try {
  const page = browser.pages()[0] ?? (await browser.newPage());
  page.on('console', (m) => {
    if (m.type() === 'error') result.console_errors.push(m.text());
  });
  page.on('pageerror', (e) => result.page_errors.push(String(e)));
  page.on('request', (r) => result.requests.push(r.url().slice(0, 80)));
  const url = pathToFileURL(resolve(html)).href + '#view=free&speed=4';
  const t0 = Date.now();
  await page.goto(url, { waitUntil: 'load', timeout: 120_000 });
  await page.waitForFunction(() => window.deepfoidsReplay?.ready || window.deepfoidsReplay?.error, null, {
    timeout: 120_000,
    polling: 100,
  });
  result.first_frame_seconds = (Date.now() - t0) / 1000;
  result.software_gl = await page.evaluate(() => window.deepfoidsReplay.softwareGL);
  const state = () =>
    page.evaluate(() => {
      const r = window.deepfoidsReplay;
      const rect = (id) => {
        const b = document.getElementById(id).getBoundingClientRect();
        return { x: b.x, y: b.y, width: b.width, height: b.height };
      };
      return {
        error: r.error, time: r.time, frame: r.frame, cursor_x: r.cursorX, frames_drawn: r.framesDrawn,
        fps: r.fps, update_ms: r.updateMs, duration: r.duration, fish: r.fish, frames: r.frames,
        view: rect('view'), chart: rect('chart'), legend: rect('legend'),
      };
    });
  // Two shots of the playing replay a few seconds apart, each taken paused
  // so the page's state and the pixels belong to the same instant.
  const shot = async (name) => {
    await page.evaluate(() => window.deepfoidsReplay.pause());
    await sleep(400); // a few frames: the camera damping settles
    result[name] = await state();
    await page.screenshot({ path: join(outDir, `${name}.png`) });
    await page.evaluate(() => window.deepfoidsReplay.play());
  };
  await sleep(1500);
  await shot('a');
  await sleep(4000);
  await shot('b');
  // Click a fish in the top view: the viewer must follow the fish under the pointer.
  await page.evaluate(() => { window.deepfoidsReplay.pause(); window.deepfoidsReplay.setView('top'); });
  await sleep(800);
  await page.screenshot({ path: join(outDir, 'top.png') });
  const target = await page.evaluate(() => {
    const r = window.deepfoidsReplay;
    const v = document.getElementById('view').getBoundingClientRect();
    for (let i = 0; i < r.fish; i++) {
      const [x, y] = r.screenOf(i);
      if (x > v.left + v.width * 0.3 && x < v.right - v.width * 0.3 && y > v.top + 40 && y < v.bottom - 40) {
        // The fish drawn near the click point (any of them may be the one on top).
        const near = [];
        for (let j = 0; j < r.fish; j++) {
          const [a, b] = r.screenOf(j);
          if (Math.hypot(a - x, b - y) < 25) near.push(j);
        }
        return { i, x, y, near };
      }
    }
    return null;
  });
  if (target) {
    await page.mouse.click(target.x, target.y);
    await sleep(500);
    result.click = await page.evaluate((t) => {
      const r = window.deepfoidsReplay;
      const sel = r.selected;
      return {
        target: t,
        selected: sel,
        info_shown: !document.getElementById('fish-info').hidden,
        info_text: document.getElementById('fish-info').textContent.slice(0, 300),
      };
    }, target);
    await page.screenshot({ path: join(outDir, 'top-follow.png') });
    await page.evaluate(() => window.deepfoidsReplay.setView('side'));
    await sleep(800);
    await page.screenshot({ path: join(outDir, 'side-follow.png') });
    await page.keyboard.press('Escape');
    await sleep(300);
    result.click.after_escape = await page.evaluate(() => window.deepfoidsReplay.selected);
  }
  if (measure > 0) {
    await page.evaluate(() => { window.deepfoidsReplay.select(null); window.deepfoidsReplay.setView('free'); window.deepfoidsReplay.play(); });
    await sleep(1000);
    const s0 = await state();
    const w0 = Date.now();
    await sleep(measure * 1000);
    const s1 = await state();
    const wall = (Date.now() - w0) / 1000;
    result.measure = {
      seconds: wall,
      frames: s1.frames_drawn - s0.frames_drawn,
      fps: (s1.frames_drawn - s0.frames_drawn) / wall,
      update_ms: s1.update_ms,
    };
  }
} catch (e) {
  result.driver_error = String(e);
} finally {
  await browser.close();
  rmSync(profile, { recursive: true, force: true });
}
writeFileSync(join(outDir, 'result.json'), JSON.stringify(result, null, 2));
console.log(JSON.stringify({ ...result, requests: result.requests.length }, null, 2));
