// The run's timeline page (`x10 sim --html`, `x10 monitor --html`: x10-sim/src/timeline) in a
// real headless browser (Chromium, driven over the DevTools protocol; no npm package):
//
//   node --experimental-websocket x10-cli/tests/browser/check-page.mjs PAGE.html [PAGE.html…]
//
// For each page: no script error and no console error; the time axis is drawn by the page's
// script (ticks in seconds); "zoom in", the mouse wheel, a drag and "whole run" change the view
// as they say; a view opened as PAGE.html#t=1.0-1.5 shows 1.0 s to 1.5 s; the labels the
// script places never overlap in a row and stay inside the plot; on an arena page, the slider
// moves the robot and the time cursor. Exits 1 with the reason on the first failure.
//
// Chromium: $CHROMIUM, else `chromium`, `chromium-browser` or `google-chrome` on the PATH.

import { spawn, execFileSync } from 'node:child_process';
import { mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, resolve } from 'node:path';
import { pathToFileURL } from 'node:url';

function findChromium() {
  const names = [process.env.CHROMIUM, 'chromium', 'chromium-browser', 'google-chrome'].filter(Boolean);
  for (const n of names) {
    try {
      execFileSync('sh', ['-c', `command -v "${n}"`], { stdio: 'pipe' });
      return n;
    } catch { /* next */ }
  }
  throw new Error('no Chromium: install it (Debian/Ubuntu: apt-get install chromium) or set CHROMIUM');
}

class Fail extends Error {}
const check = (ok, what) => {
  if (!ok) throw new Fail(what);
};

/** Starts the browser; resolves with it and the DevTools WebSocket URL it prints. */
function launch() {
  const profile = mkdtempSync(join(tmpdir(), 'x10-chromium-'));
  const proc = spawn(findChromium(), [
    '--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--no-default-browser-check',
    '--disable-dev-shm-usage', '--remote-debugging-port=0', `--user-data-dir=${profile}`,
    '--window-size=1400,1000', 'about:blank',
  ], { stdio: ['ignore', 'ignore', 'pipe'] });
  return new Promise((res, rej) => {
    let err = '';
    const timer = setTimeout(() => rej(new Error(`Chromium did not start: ${err}`)), 30000);
    proc.stderr.on('data', (d) => {
      err += d;
      const m = /DevTools listening on (ws:\/\/\S+)/.exec(err);
      if (m) {
        clearTimeout(timer);
        res({ proc, url: m[1], profile });
      }
    });
    proc.on('exit', (code) => rej(new Error(`Chromium exited (${code}): ${err}`)));
  });
}

/** A DevTools connection: `send(method, params, session)`; events to `on`. */
function connect(url) {
  const ws = new WebSocket(url);
  let next = 1;
  const waiting = new Map();
  const listeners = [];
  ws.onmessage = (m) => {
    const msg = JSON.parse(m.data);
    if (msg.id && waiting.has(msg.id)) {
      const { res, rej } = waiting.get(msg.id);
      waiting.delete(msg.id);
      if (msg.error) rej(new Error(`${msg.error.message}`));
      else res(msg.result);
    } else if (msg.method) {
      for (const l of listeners) l(msg);
    }
  };
  const send = (method, params = {}, sessionId) => new Promise((res, rej) => {
    const id = next++;
    waiting.set(id, { res, rej });
    ws.send(JSON.stringify({ id, method, params, sessionId }));
  });
  return new Promise((res, rej) => {
    ws.onopen = () => res({ send, on: (f) => listeners.push(f), close: () => ws.close() });
    ws.onerror = (e) => rej(new Error(`DevTools connection: ${e.message}`));
  });
}

/** Opens `url` in a new tab; returns helpers bound to it. */
async function open(cdp, url) {
  const { targetId } = await cdp.send('Target.createTarget', { url: 'about:blank' });
  const { sessionId } = await cdp.send('Target.attachToTarget', { targetId, flatten: true });
  const s = (m, p) => cdp.send(m, p, sessionId);
  const errors = [];
  let loaded = null;
  cdp.on((msg) => {
    if (msg.sessionId !== sessionId) return;
    if (msg.method === 'Runtime.exceptionThrown') {
      errors.push(`script error: ${msg.params.exceptionDetails.exception?.description ?? msg.params.exceptionDetails.text}`);
    } else if (msg.method === 'Runtime.consoleAPICalled' && ['error', 'assert'].includes(msg.params.type)) {
      errors.push(`console.${msg.params.type}: ${msg.params.args.map((a) => a.value ?? a.description).join(' ')}`);
    } else if (msg.method === 'Log.entryAdded' && msg.params.entry.level === 'error') {
      errors.push(`log: ${msg.params.entry.text}`);
    } else if (msg.method === 'Page.loadEventFired' && loaded) {
      loaded();
    }
  });
  await s('Runtime.enable');
  await s('Log.enable');
  await s('Page.enable');
  const eval_ = async (expr) => {
    const r = await s('Runtime.evaluate', { expression: expr, returnByValue: true, awaitPromise: true });
    if (r.exceptionDetails) throw new Fail(`evaluating ${expr}: ${r.exceptionDetails.exception?.description ?? r.exceptionDetails.text}`);
    return r.result.value;
  };
  const go = async (u) => {
    const done = new Promise((res) => { loaded = res; });
    await s('Page.navigate', { url: u });
    await Promise.race([done, new Promise((_, rej) => setTimeout(() => rej(new Fail(`${u} did not load`)), 30000))]);
  };
  await go(url);
  return { s, eval: eval_, errors, go, close: () => cdp.send('Target.closeTarget', { targetId }) };
}

/** What the page shows now: the zoom label, the zoom transform, the tick texts, the labels. */
const VIEW = `(() => {
  const svg = document.getElementById('x10-timeline');
  const L = +svg.getAttribute('data-left'), R = +svg.getAttribute('data-right');
  const ticks = [...document.querySelectorAll('#x10-ticks text')].map((t) => t.textContent);
  const g = document.querySelector('g.zoom');
  const labels = [...svg.querySelectorAll('text.label')]
    .filter((t) => t.getAttribute('visibility') !== 'hidden')
    .map((t) => { const b = t.getBBox(); return { x: b.x, w: b.width, y: +t.getAttribute('y'), row: t.parentNode.getAttribute('data-y') }; });
  const r = svg.getBoundingClientRect();
  return { zoom: document.getElementById('x10-zoom')?.textContent, transform: g ? g.getAttribute('transform') : null,
           ticks, labels, L, R, end: +svg.getAttribute('data-end-s'),
           box: { x: r.left, y: r.top, w: r.width, h: r.height }, width: +svg.getAttribute('width') };
})()`;

const seconds = (t) => Number(t.replace(/ s$/, ''));

function labelsFit(v, when) {
  const rows = new Map();
  for (const l of v.labels) {
    check(l.x >= v.L - 1 && l.x + l.w <= v.R + 1, `${when}: a label outside the plot (${l.x.toFixed(1)}..${(l.x + l.w).toFixed(1)}, plot ${v.L}..${v.R})`);
    const key = `${l.row}/${l.y}`;
    if (!rows.has(key)) rows.set(key, []);
    rows.get(key).push(l);
  }
  for (const [key, ls] of rows) {
    ls.sort((a, b) => a.x - b.x);
    for (let i = 1; i < ls.length; i++) {
      check(ls[i].x >= ls[i - 1].x + ls[i - 1].w - 0.5, `${when}: two labels overlap in row ${key} at x ${ls[i].x.toFixed(1)}`);
    }
  }
}

async function checkPage(cdp, file) {
  const url = pathToFileURL(resolve(file)).href;
  const page = await open(cdp, url);
  try {
    const v0 = await page.eval(VIEW);
    check(v0.end > 0, 'the page has a timeline with a duration');
    check(v0.zoom === '1.0×', `the script sets the zoom label to 1.0× (${v0.zoom})`);
    check(v0.ticks.length >= 2 && v0.ticks.every((t) => / s$/.test(t)), `the script drew the time axis (${v0.ticks})`);
    check(seconds(v0.ticks[0]) === 0, `the whole run starts at 0 s (${v0.ticks[0]})`);
    check(seconds(v0.ticks[v0.ticks.length - 1]) <= v0.end + 1e-9, 'no tick after the end of the run');
    labelsFit(v0, 'whole run');

    await page.eval(`document.getElementById('x10-in').click()`);
    const v1 = await page.eval(VIEW);
    check(v1.zoom === '2.0×', `"zoom in" doubles the zoom (${v1.zoom})`);
    check(/scale\(2 1\)/.test(v1.transform), `the plot is scaled by 2 (${v1.transform})`);
    const span = (v) => seconds(v.ticks[v.ticks.length - 1]) - seconds(v.ticks[0]);
    check(span(v1) < span(v0), `zoomed in, the axis shows less time (${v0.ticks} → ${v1.ticks})`);
    labelsFit(v1, 'zoomed in');

    // The wheel over the plot: 1.25 times more.
    const sx = v1.box.x + (v1.L + v1.R) / 2 * (v1.box.w / v1.width);
    const sy = v1.box.y + v1.box.h / 2;
    await page.s('Input.dispatchMouseEvent', { type: 'mouseWheel', x: sx, y: sy, deltaX: 0, deltaY: -100 });
    const v2 = await page.eval(VIEW);
    check(v2.zoom === '2.5×', `the wheel zooms by 1.25 (${v2.zoom})`);

    // A drag to the right shows earlier times.
    await page.s('Input.dispatchMouseEvent', { type: 'mousePressed', x: sx, y: sy, button: 'left', clickCount: 1 });
    await page.s('Input.dispatchMouseEvent', { type: 'mouseMoved', x: sx + 200, y: sy, button: 'left' });
    await page.s('Input.dispatchMouseEvent', { type: 'mouseReleased', x: sx + 200, y: sy, button: 'left', clickCount: 1 });
    const v3 = await page.eval(VIEW);
    check(v3.transform !== v2.transform, 'a drag pans the plot');
    check(seconds(v3.ticks[0]) <= seconds(v2.ticks[0]), `dragged right, the axis starts earlier (${v2.ticks[0]} → ${v3.ticks[0]})`);
    labelsFit(v3, 'panned');

    await page.eval(`document.getElementById('x10-reset').click()`);
    const v4 = await page.eval(VIEW);
    check(v4.zoom === '1.0×' && v4.transform === v0.transform, `"whole run" is the first view again (${v4.zoom}, ${v4.transform})`);

    // A view opened from the address: the middle fifth of the run.
    const a = Number((v0.end * 0.4).toFixed(3));
    const b = Number((v0.end * 0.6).toFixed(3));
    // (A new load: a change of the hash alone does not run the page's script again.)
    await page.go('about:blank');
    await page.go(`${url}#t=${a}-${b}`);
    const v5 = await page.eval(VIEW);
    const t5 = v5.ticks.map(seconds);
    check(t5.length >= 2 && t5[0] >= a - 1e-9 && t5[t5.length - 1] <= b + 1e-9, `#t=${a}-${b} shows ${a} s to ${b} s (${v5.ticks})`);
    labelsFit(v5, `#t=${a}-${b}`);

    // An arena page: the slider moves the robot and the time cursor.
    const arena = await page.eval(`!!document.getElementById('x10-scrub')`);
    if (arena) {
      const move = async (frac) => page.eval(`(() => {
        const s = document.getElementById('x10-scrub');
        s.value = Math.round(+s.max * ${frac});
        s.dispatchEvent(new Event('input'));
        const c = [...document.querySelectorAll('#x10-timeline > line')].pop();
        return { robot: document.getElementById('x10-robot').getAttribute('transform'),
                 t: document.getElementById('x10-scrub-t').textContent, x: c ? +c.getAttribute('x1') : null };
      })()`);
      const early = await move(0.1);
      const late = await move(0.9);
      check(early.robot !== late.robot, 'the slider moves the robot');
      check(early.x !== null && late.x > early.x, `the slider moves the time cursor (${early.x} → ${late.x})`);
      check(seconds(early.t) < seconds(late.t), `the slider's time follows it (${early.t} → ${late.t})`);
    }
    check(page.errors.length === 0, page.errors.join('; '));
    return `${file}: ok (${v0.ticks.length} ticks, ${v0.labels.length} labels${arena ? ', arena slider' : ''})`;
  } finally {
    await page.close().catch(() => {});
  }
}

const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node --experimental-websocket check-page.mjs PAGE.html [PAGE.html…]');
  process.exit(2);
}
let browser;
let code = 0;
try {
  browser = await launch();
  const cdp = await connect(browser.url);
  for (const f of files) {
    try {
      console.log(await checkPage(cdp, f));
    } catch (e) {
      console.error(`${f}: FAILED: ${e.message}`);
      code = 1;
    }
  }
  cdp.close();
} catch (e) {
  console.error(`check-page: ${e.message}`);
  code = 1;
} finally {
  if (browser) {
    const gone = new Promise((res) => browser.proc.on('exit', res));
    browser.proc.kill();
    await gone;
    rmSync(browser.profile, { recursive: true, force: true });
  }
}
process.exit(code);
