// The dashboard end to end in headless Chromium (Debian's /usr/bin/chromium, driven
// by playwright-core: no browser download), against a running rack-gui and a rackd
// with the simulated robot of configs/sim_mcl.yaml. Run by
// tests/integration/gui_e2e_test.cpp, or by hand:
//
//   node e2e/e2e.mjs --url http://127.0.0.1:8080/ [--shots DIR] [--chromium PATH] [--rackd-pid PID]
//
// --rackd-pid: at the end the robot's rackd is killed, and the page must show its
// components as "no reply" (never their last state). Exit 0 when every step passed.
import { chromium } from 'playwright-core';
import { mkdirSync } from 'node:fs';
import http from 'node:http';
import { join } from 'node:path';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) => {
  if (a.startsWith('--')) acc.push([a.slice(2), all[i + 1]]);
  return acc;
}, []));
const url = args.url ?? 'http://127.0.0.1:8080/';
const shots = args.shots ?? 'e2e-shots';
mkdirSync(shots, { recursive: true });

const t0 = Date.now();
const log = (s) => console.log(`[${((Date.now() - t0) / 1000).toFixed(1)} s] ${s}`);
const GREEN = 'rgb(46, 125, 50)', GREY = 'rgb(117, 117, 117)', ORANGE = 'rgb(239, 108, 0)';

const browser = await chromium.launch({
  executablePath: args.chromium ?? '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--disable-gpu'],
});
let failed = false;
const page = await browser.newPage({ viewport: { width: 1400, height: 850 } });
page.on('pageerror', (e) => { console.log(`page error: ${e.message}`); failed = true; });
page.on('dialog', (d) => d.accept());
const shot = async (name) => { await page.screenshot({ path: join(shots, name) }); log(`screenshot ${name}`); };

// Values from the page.
const chassis = () => page.evaluate(() => {
  for (const d of window.__rack.data.values()) if (d.class === 'Chassis' && d.system === 0) return d.data;
  return null;
});
const pilot = () => page.evaluate(() => {
  for (const d of window.__rack.data.values()) if (d.class === 'Pilot' && d.system === 0) return d.data;
  return null;
});
// Read in one step inside the page: the list is redrawn five times a second, and an
// element found a moment earlier may be detached by then.
const toggleColour = (name) => page.evaluate((n) => {
  const el = document.querySelector(`[data-testid="toggle-${n}"]`);
  return el ? getComputedStyle(el).backgroundColor : 'missing';
}, name);
async function until(what, fn, ms = 15000) {
  const end = Date.now() + ms;
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() > end) throw new Error(`timed out after ${ms} ms waiting for ${what}`);
    await new Promise((r) => setTimeout(r, 100));
  }
}
const lastNotice = () => page.evaluate(() => window.__rack.notices.map((n) => `${n.ok ? 'ok' : 'BAD'} ${n.text}`).slice(-5).join('\n'));

// A raw HTTP GET (no URL normalisation, unlike a browser): the status code.
const rawGet = (path) => new Promise((resolve, reject) => {
  const u = new URL(url);
  http.get({ host: u.hostname, port: u.port, path }, (res) => { res.resume(); resolve(res.statusCode); }).on('error', reject);
});

try {
  // 0. The server: files below its web root only.
  for (const [path, want] of [['/', 200], ['/index.html', 200], ['/../../etc/passwd', 400], ['/assets/../../x', 400],
    ['/nothing-here.js', 404]]) {
    const got = await rawGet(path);
    if (got !== want) throw new Error(`GET ${path}: ${got}, expected ${want}`);
  }
  log('HTTP: the page is served, paths outside the web root refused (400), missing files 404');
  await page.goto(url);
  // 1. Every component of the host, grouped under robot 0, with RACK's colours.
  const names = ['chassis', 'ladar', 'odometry', 'scan2d', 'position', 'path', 'mcl', 'pilot', 'evaluator'];
  for (const n of names) {
    await page.locator(`[data-testid="comp-${n}"][data-state="enabled"]`).waitFor({ timeout: 20000 });
  }
  if (await toggleColour('pilot') !== GREEN) throw new Error(`enabled pilot is ${await toggleColour('pilot')}, not green`);
  log(`components listed and enabled: ${names.join(', ')}`);
  await until('the map and MCL particles', () => page.evaluate(() => window.__rack.maps.size > 0 &&
    [...window.__rack.data.values()].some((d) => d.class === 'MCL' && d.data.shown > 0)));
  await page.waitForTimeout(500);
  await shot('map.png');

  // 2. Switch a component off and on: its colour follows.
  await page.locator('[data-testid="toggle-evaluator"]').click();
  await page.locator('[data-testid="comp-evaluator"][data-state="disabled"]').waitFor({ timeout: 5000 });
  if (await toggleColour('evaluator') !== GREY) throw new Error(`disabled evaluator is ${await toggleColour('evaluator')}, not grey`);
  log('evaluator off: grey');
  await shot('components.png');
  await page.locator('[data-testid="toggle-evaluator"]').click();
  await page.locator('[data-testid="comp-evaluator"][data-state="enabled"]').waitFor({ timeout: 8000 });
  if (await toggleColour('evaluator') !== GREEN) throw new Error('re-enabled evaluator is not green');
  log('evaluator on again: green');

  // 3. GDOS: the transitions just made appear in the log.
  await page.locator('#tabs button[data-view="gdos"]').click();
  await page.locator('#gdos .log', { hasText: 'evaluator' }).first().waitFor({ timeout: 8000 });
  log(`GDOS lines shown: ${await page.locator('#gdos .log').count()}`);
  await shot('gdos.png');

  // 4. Bad input: a malformed message and a wrong-typed value are refused visibly.
  await page.evaluate(() => window.__rack.sendRaw('{"op":"joystick","system":0,"vx":"fast","omega":0}'));
  await until('the refusal of a wrong-typed joystick value', async () => (await lastNotice()).includes("refused: joystick: key 'vx': expected a number, got string"));
  await page.evaluate(() => window.__rack.sendRaw('this is not json'));
  await until('the refusal of a non-JSON message', async () => (await lastNotice()).includes('refused: not JSON'));
  log('malformed messages refused');
  // The pilot's parameters: a float parameter given text is refused before sending,
  // and rack-gui refuses a string for it too.
  await page.locator('[data-testid="comp-pilot"] .name').click();
  await page.locator('[data-testid="params"] input[data-p="vx_max"]').waitFor({ timeout: 5000 });
  await page.locator('[data-testid="params"] input[data-p="vx_max"]').fill('fast');
  await page.locator('[data-testid="params"] button[data-set="vx_max"]').click();
  await until('the page refusing a text for a float', async () => (await lastNotice()).includes("vx_max: 'fast' is not a finite number; nothing sent"));
  await page.evaluate(() => window.__rack.ws.send(JSON.stringify({ op: 'set_param', component: 'Pilot(0/0)', name: 'vx_max', value: 'fast' })));
  await until('rack-gui refusing a string for a float parameter', async () => (await lastNotice()).includes('expected a number, got string; nothing was sent'));
  log('parameter type checks: refused in the page and in rack-gui');
  // A valid value is set, and the component's log level changes from the GDOS panel.
  await page.locator('[data-testid="params"] input[data-p="vx_max"]').fill('0.7');
  await page.locator('[data-testid="params"] button[data-set="vx_max"]').click();
  await until('vx_max set to 0.7', async () => (await lastNotice()).includes('Pilot(0/0): vx_max = 0.7'), 5000);
  await shot('details-pilot.png');
  // The GDOS panel's per-component level.
  await page.locator('#tabs button[data-view="gdos"]').click();
  await page.locator('#g-target').selectOption('Evaluator(0/0)');
  await page.locator('#g-newlevel').selectOption('warning');
  await page.locator('#g-setlevel').click();
  await until('the evaluator\'s GDOS level set', async () => (await lastNotice()).includes('gdosLevel = "warning"'), 5000);
  log('parameters set: pilot vx_max 0.7, evaluator gdosLevel warning');
  await page.locator('[data-testid="comp-chassis"] .name').click();
  await page.locator('[data-testid="latency"]').waitFor({ timeout: 5000 });
  // The chassis' data task runs every 10 ms: its histogram (GET_LATENCY through
  // rack-gui) has samples in non-empty buckets that add up, and the canvas drew them.
  const hist = await until('the chassis\' latency histogram drawn with non-empty buckets', () => page.evaluate(() => {
    const cv = document.querySelector('[data-testid="latency"]');
    let c = null;
    for (const x of window.__rack.comps.values()) if (x.class === 'Chassis' && x.system === 0) c = x;
    if (!cv || !c || !c.latency || Number(cv.dataset.nonzero) === 0) return null;
    const sum = c.latency.counts.reduce((a, b) => a + b, 0);
    return { nonzero: Number(cv.dataset.nonzero), drawn: Number(cv.dataset.samples), samples: c.latency.samples, sum,
      buckets: c.latency.counts.length, overruns: c.latency.overruns };
  }), 10000);
  if (hist.sum !== hist.samples || hist.buckets !== 40) throw new Error(`latency histogram inconsistent: ${JSON.stringify(hist)}`);
  log(`latency histogram: ${hist.nonzero} non-empty buckets, ${hist.samples} samples, ${hist.overruns} overruns`);
  await shot('details-chassis.png');
  await page.locator('[data-testid="comp-ladar"] .name').click();
  await page.locator('[data-testid="polar"]').waitFor({ timeout: 5000 });
  await shot('details-ladar.png');
  // 4b. Several robots: robot 1 (the mode-switch demo) in its own group, and its
  // report symbolized by rack-backtrace down to the demo's source line.
  await page.locator('.robot[data-system="1"] [data-testid="comp-demo"]').waitFor({ timeout: 5000 });
  log('robot 1 listed in its own group');
  await page.locator('.robot[data-system="1"] [data-testid="comp-camera"] .name').click();
  await until('a camera image drawn', () => page.evaluate(() => (window.__rack.cameraFramesShown ?? 0) > 0), 15000);
  log(`camera image shown: ${await page.locator('#camera-info').textContent()}`);
  await shot('details-camera.png');
  await page.locator('#tabs button[data-view="reports"]').click();
  await page.locator('[data-testid="report-file"]', { hasText: 'modeswitch_demo.cpp' }).first().waitFor({ timeout: 15000 });
  log('mode-switch report symbolized: modeswitch_demo.cpp line shown');
  await shot('reports.png');

  // 5. Map: wheel zooms about the cursor, dragging pans, Fit restores; then a click
  // sets the pilot's destination and the robot drives there.
  await page.locator('#tabs button[data-view="map"]').click();
  const mapBox = await page.locator('[data-testid="map"]').boundingBox();
  const view = () => page.evaluate(() => ({ ...window.__rack.view }));
  const v0 = await view();
  await page.mouse.move(mapBox.x + mapBox.width / 2, mapBox.y + mapBox.height / 2);
  await page.mouse.wheel(0, -400);
  await until('the wheel to zoom in', async () => (await view()).scale > v0.scale * 1.3, 3000);
  const v1 = await view();
  await page.mouse.down();
  await page.mouse.move(mapBox.x + mapBox.width / 2 + 120, mapBox.y + mapBox.height / 2 + 40, { steps: 5 });
  await page.mouse.up();
  const v2 = await view();
  if (Math.abs(v2.ox - v1.ox - 120) > 2 || Math.abs(v2.oy - v1.oy - 40) > 2) throw new Error(`drag did not pan: ${JSON.stringify([v1, v2])}`);
  log(`map zoomed ${(v1.scale / v0.scale).toFixed(2)}x by the wheel and panned by a drag`);
  await shot('map-zoomed.png');
  await page.locator('#fit').click();
  await until('Fit to restore the view', async () => Math.abs((await view()).scale - v0.scale) < 1e-6, 3000);
  await page.locator('[data-testid="mode-destination"]').check();
  const start = await chassis();
  // In the corridor (y 6..10), 3 m from where the robot is, towards the middle.
  const goal = { x: start.truth_x < 12 ? start.truth_x + 3 : start.truth_x - 3, y: 8.0 };
  const px = await page.evaluate(([x, y]) => window.__rack.toPx(x, y), [goal.x, goal.y]);
  const box = await page.locator('[data-testid="map"]').boundingBox();
  const dpr = await page.evaluate(() => window.devicePixelRatio || 1);
  await page.mouse.click(box.x + px[0] / dpr, box.y + px[1] / dpr);
  await until('the destination to be accepted', async () => (await lastNotice()).includes('destination set'), 5000);
  log(`destination (${goal.x.toFixed(2)}, ${goal.y.toFixed(2)}) set by a click; robot at (${start.truth_x.toFixed(2)}, ${start.truth_y.toFixed(2)})`);
  // The Pilot says it arrived (status 2, REACHED, on its localised pose); the true
  // pose must then be near the click.
  await until('the pilot to reach the destination', async () => {
    const p = await pilot();
    return p && p.mode === 2 && p.status === 2 && Math.hypot(p.target_x - goal.x, p.target_y - goal.y) < 0.01;
  }, 25000);
  const there = await chassis();
  const miss = Math.hypot(there.truth_x - goal.x, there.truth_y - goal.y);
  if (miss > 0.5) throw new Error(`the robot stopped ${miss.toFixed(2)} m from the click`);
  log(`robot reached (${there.truth_x.toFixed(2)}, ${there.truth_y.toFixed(2)}), ${Math.hypot(there.truth_x - goal.x, there.truth_y - goal.y).toFixed(2)} m from the click`);
  await shot('destination.png');

  // 6. Joystick: holding it drives the robot (the dashboard becomes the active
  // pilot); letting go stops it.
  await until('the robot to stand at the destination', async () => Math.abs((await chassis()).vx) < 0.02, 5000);
  const pad = await page.locator('[data-testid="joystick"]').boundingBox();
  const before = await chassis();
  await page.mouse.move(pad.x + pad.width / 2, pad.y + pad.height / 2);
  await page.mouse.down();
  await page.mouse.move(pad.x + pad.width / 2, pad.y + pad.height * 0.2, { steps: 4 });
  await until('the joystick to drive the robot', async () => (await chassis()).vx > 0.1, 5000);
  const active = await page.locator('[data-testid="chassis-box"]').textContent();
  if (!active.includes('this dashboard')) throw new Error(`the chassis' active pilot is not the dashboard: ${active}`);
  await page.waitForTimeout(800);
  await shot('joystick.png');
  await page.mouse.up();
  await until('the robot to stop after the joystick was released', async () => Math.abs((await chassis()).vx) < 0.02, 3000);
  const after = await chassis();
  const driven = Math.hypot(after.truth_x - before.truth_x, after.truth_y - before.truth_y);
  if (driven < 0.2) throw new Error(`the joystick moved the robot only ${driven.toFixed(2)} m`);
  await page.waitForTimeout(500);
  const still = await chassis();
  const creep = Math.hypot(still.truth_x - after.truth_x, still.truth_y - after.truth_y);
  if (creep > 0.02) throw new Error(`the robot kept moving ${creep.toFixed(3)} m after the release`);
  log(`joystick drove ${driven.toFixed(2)} m and the robot stopped on release`);
  // Dead-man in rack-gui: commands that stop coming without a release (a frozen tab,
  // a lost network) stop the robot too.
  await page.evaluate(async () => {
    for (let i = 0; i < 10; i++) {
      window.__rack.ws.send(JSON.stringify({ op: 'joystick', system: 0, vx: 0.4, omega: 0 }));
      await new Promise((r) => setTimeout(r, 100));
    }
  });
  if (!((await chassis()).vx > 0.1)) throw new Error('raw joystick commands did not drive the robot');
  await until('rack-gui to stop the robot when the joystick commands stop', async () => Math.abs((await chassis()).vx) < 0.02, 3000);
  await until('the dead-man notice', async () => (await lastNotice()).includes('joystick silent for 400 ms'), 3000);
  log('joystick commands stopped without a release: rack-gui stopped the robot (dead-man)');
  // Keyboard: the up arrow on the map drives, letting go stops.
  await page.locator('[data-testid="map"]').hover();
  await page.keyboard.down('ArrowUp');
  await until('the arrow key to drive the robot', async () => (await chassis()).vx > 0.1, 5000);
  await page.keyboard.up('ArrowUp');
  await until('the robot to stop after the key was released', async () => Math.abs((await chassis()).vx) < 0.02, 3000);
  log('keyboard joystick drives and stops');

  // 7. Set the robot's position by a click (Position UPDATE + MCL re-initialisation).
  await page.locator('[data-testid="mode-pose"]').check();
  const here = await chassis();
  const hp = await page.evaluate(([x, y]) => window.__rack.toPx(x, y), [here.truth_x, here.truth_y]);
  await page.mouse.click(box.x + hp[0] / dpr, box.y + hp[1] / dpr);
  await until('the position to be set', async () => (await lastNotice()).includes('re-initialised'), 5000);
  log('position set by a click: Position updated, MCL re-initialised');

  // Drawing speed with many particles (reported, not asserted: timing is for bench/).
  const bench = await page.evaluate(() => window.__rack.benchmarkParticles(50000, 30));
  const f = (r) => `p50 ${r.p50.toFixed(1)} ms, p90 ${r.p90.toFixed(1)} ms, max ${r.max.toFixed(1)} ms`;
  log(`map frame draw time: without extra particles ${f(bench.base)}; with ${bench.n} particles ${f(bench.withParticles)}; ` +
      `p50 ratio ${(bench.withParticles.p50 / bench.base.p50).toFixed(1)}x (${bench.withParticles.frames} frames each)`);

  // 8. "all off": every component of robot 0 off (grey), in reverse order.
  await page.locator('[data-testid="all-off-0"]').click();
  await until('every component of robot 0 to be off', () => page.evaluate(() =>
    [...document.querySelectorAll('.robot[data-system="0"] .comp')].every((e) => e.dataset.state === 'disabled')), 10000);
  if (await toggleColour('chassis') !== GREY) throw new Error('chassis is not grey after all off');
  log('all off: every component of robot 0 grey');
  await shot('all-off.png');

  // 9. A robot that stops answering is shown as such.
  if (args['rackd-pid']) {
    process.kill(Number(args['rackd-pid']), 'SIGKILL');
    await page.locator('[data-testid="comp-pilot"][data-state="no_reply"]').waitFor({ timeout: 8000 });
    const colour = await toggleColour('pilot');
    if (colour !== ORANGE) throw new Error(`a component of a dead host is ${colour}, not orange`);
    await page.waitForTimeout(300);
    const states = await page.evaluate(() => [...document.querySelectorAll('.robot[data-system="0"] .comp')].map((e) => e.dataset.state));
    if (states.some((s) => s !== 'no_reply')) throw new Error(`components of a dead host shown as ${states.join(', ')}`);
    await until('the map to mark the dead robot\'s data as stale', () => page.evaluate(() => window.__rack.mapStale === true), 5000);
    const box = await page.locator('[data-testid="chassis-box"]').textContent();
    if (!box.includes('no data')) throw new Error(`the chassis box still shows ${box}`);
    const other = await page.evaluate(() => document.querySelector('.robot[data-system="1"] .comp')?.dataset.state);
    if (other !== 'enabled') throw new Error(`robot 1 (still running) shown as ${other}`);
    log('rackd of robot 0 killed: its components shown as "no reply"; robot 1 still ON');
    await shot('no-reply.png');
  }
  // 10. rack-gui itself gone: the page shows it, and no component keeps a state.
  if (args['gui-pid']) {
    process.kill(Number(args['gui-pid']), 'SIGTERM');
    await page.locator('[data-testid="connection"]', { hasText: 'disconnected' }).waitFor({ timeout: 5000 });
    const states = await page.evaluate(() => [...document.querySelectorAll('.comp')].map((e) => e.dataset.state));
    if (states.length === 0 || states.some((s) => s !== 'no_reply')) throw new Error(`without rack-gui the page shows ${states.join(', ')}`);
    log('rack-gui stopped: the page says disconnected and shows every component as "no reply"');
    await shot('disconnected.png');
  }
} catch (e) {
  console.log(`FAILED: ${e.message}`);
  console.log(`last notices:\n${await lastNotice().catch(() => '?')}`);
  await page.screenshot({ path: join(shots, 'failure.png') }).catch(() => {});
  failed = true;
}
await browser.close();
log(failed ? 'e2e: FAILED' : 'e2e: all steps passed');
process.exit(failed ? 1 : 0);
