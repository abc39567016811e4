// The dashboard's panels of issue 21 item 4 in headless Chromium (Debian's, driven by
// playwright-core): live plots, the class-command panel, numbers for people, the map's
// legend / layer toggles / scale bar / cursor coordinates / follow mode / particles /
// refit, the joystick beside (not over) the map, a phone's viewport, and honest empty
// and stale states, and a live trace in the Timeline tab. Run by tests/integration/gui_e2e_test.cpp
// (GuiE2eTest.DashboardPanelsInChromium), or by hand:
//
//   node e2e/panels.mjs --url URL --empty-url URL2 --stop-pid PID [--shots DIR] [--chromium PATH]
//
// URL: a rack-gui with configs/sim_mcl.yaml's robot 0 and a robot 2 (one Generator,
// one Counter of a plug-in: tests/integration/plugin/counter_plugin.cpp) whose rackd
// is PID; it is stopped cleanly (SIGTERM) at the end and must leave the list
// (rack-gui --forget-s). URL2: a rack-gui on a network where no robot runs.
import { chromium } from 'playwright-core';
import { mkdirSync } from 'node:fs';
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

const browser = await chromium.launch({
  executablePath: args.chromium ?? '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--disable-gpu'],
});
let failed = false;
let page = null;
async function until(what, fn, ms = 15000) {
  const end = Date.now() + ms;
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() > end) throw new Error(`timed out after ${ms} ms waiting for ${what}`);
    await new Promise((r) => setTimeout(r, 100));
  }
}
async function open(u, viewport, extra = {}) {
  const ctx = await browser.newContext({ viewport, ...extra });
  const p = await ctx.newPage();
  p.on('pageerror', (e) => { console.log(`page error: ${e.message}`); failed = true; });
  p.on('dialog', (d) => d.accept());
  await p.goto(u);
  return p;
}
const shot = async (p, name) => { await p.screenshot({ path: join(shots, name) }); log(`screenshot ${name}`); };
const overlap = (a, b) => a.x < b.x + b.width && b.x < a.x + a.width && a.y < b.y + b.height && b.y < a.y + a.height;

try {
  // 1. Nothing answers: the page says so, and nothing is green.
  if (args['empty-url']) {
    const empty = await open(args['empty-url'], { width: 1200, height: 700 });
    await empty.locator('[data-testid="no-robots"]').waitFor({ timeout: 10000 });
    await until('the header to say that no robot was found', async () =>
      (await empty.locator('[data-testid="connection"]').textContent()).includes('no robot found'), 10000);
    const state = await empty.locator('[data-testid="connection"]').getAttribute('data-state');
    if (state === 'up') throw new Error('green "connected" over a network where no robot answers');
    const text = await empty.locator('[data-testid="no-robots"]').textContent();
    if (!text.includes('No robot answers on udpm://')) throw new Error(`empty state says: ${text}`);
    log(`no robot: header "${await empty.locator('[data-testid="connection"]').textContent()}" (${state}), list says why`);
    await shot(empty, 'panels-empty.png');
    await empty.context().close();
  }

  page = await open(url, { width: 1400, height: 850 });
  for (const n of ['chassis', 'mcl', 'pilot', 'generator']) {
    await page.locator(`[data-testid="comp-${n}"][data-state="enabled"]`).waitFor({ timeout: 20000 });
  }
  await until('the header to count two robots answering', async () =>
    /2 robots answering/.test(await page.locator('[data-testid="connection"]').textContent()), 10000);
  log(`header: ${await page.locator('[data-testid="connection"]').textContent()}`);

  // 2. Plots: fields from the class description; a live series that grows.
  await page.locator('[data-testid="tab-plots"]').click();
  // (A component is listed as Class0xNN(s/i) until rack-gui has its class description:
  // under load that can be a few rounds after it answers.)
  const addr = (cls, sys = 0) => until(`a ${cls} of robot ${sys} listed by its class name`, () => page.evaluate(([c, s]) =>
    [...window.__rack.comps.values()].find((x) => x.class === c && x.system === s)?.address, [cls, sys]), 10000);
  const chassisAddr = await addr('Chassis');
  await page.locator('[data-testid="plot-component"]').selectOption(chassisAddr);
  await until('the chassis\' numeric fields from its class description', () => page.evaluate(() =>
    [...document.querySelectorAll('#pl-field option')].some((o) => o.value === 'truth_x')), 10000);
  const offered = await page.evaluate(() => [...document.querySelectorAll('#pl-field option')].map((o) => o.value));
  if (offered.includes('pad_') || !offered.includes('battery')) throw new Error(`chassis fields offered: ${offered.join(', ')}`);
  await page.locator('[data-testid="plot-field"]').selectOption('battery');
  await page.locator('[data-testid="plot-add"]').click();
  await page.locator('[data-testid="plot-component"]').selectOption(await addr('Generator', 2));
  await until('the generator\'s fields', () => page.evaluate(() => document.querySelectorAll('#pl-field option').length > 0 && document.querySelector('#pl-field').value !== ''), 10000);
  const genField = await page.evaluate(() => document.querySelector('#pl-field').value);
  await page.locator('[data-testid="plot-add"]').click();
  const points = await until('two live plots with at least 5 samples each', () => page.evaluate(() => {
    const p = window.__rack.plots;
    return p.length === 2 && p.every((x) => x.xs.length >= 5) ? p.map((x) => `${x.field}: ${x.xs.length}`) : null;
  }), 15000);
  const canvases = await page.locator('[data-testid="plots"] canvas').count();
  if (canvases < 2) throw new Error(`${canvases} plot canvases drawn`);
  log(`plots (uPlot): ${points.join(', ')} samples; generator field '${genField}'`);
  await shot(page, 'panels-plots.png');

  // 3. The class-command panel: Pilot's SET_DESTINATION by name with a form; a field
  // that does not fit is refused with nothing sent; then the real command is answered.
  await page.locator('[data-testid="comp-pilot"] .name').click();
  const setDest = page.locator('[data-testid="cmd-SET_DESTINATION"]');
  await setDest.waitFor({ timeout: 10000 });
  const cmdNames = await page.evaluate(() => [...document.querySelectorAll('form.cmd')].map((f) => f.dataset.cmd));
  await setDest.locator('input[name="x"]').fill('east');
  await setDest.locator('button[type="submit"]').click();
  await until('the refusal of a text for a number field', async () =>
    /failed: .*field 'x'.*nothing was sent/.test(await setDest.locator('[data-testid="cmd-result"]').textContent()), 5000);
  log(`command panel: ${cmdNames.join(', ')}; x=east refused: ${await setDest.locator('[data-testid="cmd-result"]').textContent()}`);
  const chassis = await page.evaluate((a) => window.__rack.data.get(a).data, chassisAddr);
  const goal = { x: chassis.truth_x < 12 ? chassis.truth_x + 2 : chassis.truth_x - 2, y: 8 };
  await setDest.locator('input[name="x"]').fill(String(goal.x.toFixed(2)));
  await setDest.locator('input[name="y"]').fill(String(goal.y));
  await setDest.locator('button[type="submit"]').click();
  await until('SET_DESTINATION answered OK', async () =>
    /answered: .*SET_DESTINATION.*OK/.test(await setDest.locator('[data-testid="cmd-result"]').textContent()), 8000);
  await until('the pilot to take the destination', () => page.evaluate((g) => {
    const d = [...window.__rack.data.values()].find((x) => x.class === 'Pilot' && x.system === 0);
    return d && Math.abs(d.data.target_x - g.x) < 0.01 && Math.abs(d.data.target_y - g.y) < 0.01;
  }, goal), 5000);
  log(`SET_DESTINATION x=${goal.x.toFixed(2)} y=${goal.y} sent from the form: ${await setDest.locator('[data-testid="cmd-result"]').textContent()}`);
  // Numbers for people: the pilot's enums by name, lengths in metres.
  const status = await until('the pilot\'s status by name', async () => {
    const t = await page.locator('[data-testid="data-table"] [data-field="status"]').textContent().catch(() => '');
    return /^[A-Z_]+ \(\d+\)$/.test(t) ? t : null;
  }, 5000);
  const dist = await page.locator('[data-testid="data-table"] [data-field="distance_to_target"]').textContent();
  if (!/^-?\d+(\.\d{1,3})? m$/.test(dist)) throw new Error(`distance_to_target shown as '${dist}'`);
  log(`numbers: pilot status '${status}', distance_to_target '${dist}'`);
  await setDest.scrollIntoViewIfNeeded();
  await shot(page, 'panels-commands.png');
  await page.locator('[data-testid="comp-chassis"] .name').click();
  const pilotText = await until('the chassis\' active pilot by name', async () => {
    const t = await page.locator('[data-testid="data-table"] [data-field="active_pilot"]').textContent().catch(() => '');
    return /^Pilot\(0\/0\) \(\d+\)$/.test(t) ? t : null;
  }, 5000);
  log(`numbers: chassis active_pilot '${pilotText}'`);

  // 3b. A plug-in class (robot 2's Counter: neither rack-gui nor this page is built
  // with it, nor with any class): its address by its class name, its data table by
  // field name and its commands' forms, all from its class description.
  await page.locator('[data-testid="comp-counter"] .name').click();
  const count = await until('the plug-in\'s data table', async () => {
    const t = await page.locator('[data-testid="data-table"] [data-field="count"]').textContent().catch(() => '');
    return t !== '' ? t : null;
  }, 10000);
  const label = await page.locator('[data-testid="data-table"] [data-field="label"]').textContent();
  const head = await page.locator('#d-head').textContent();
  if (!head.includes('Counter(2/0)')) throw new Error(`the plug-in's heading reads '${head}'`);
  if (!label.includes('plug-in')) throw new Error(`the plug-in's label field reads '${label}'`);
  await page.locator('[data-testid="cmd-RESET"]').waitFor({ timeout: 10000 });
  log(`plug-in: ${head.trim()}; count ${count}, label '${label}'; command RESET offered`);
  await shot(page, 'panels-plugin.png');

  // 4. The map: legend with a toggle per layer, scale bar, cursor coordinates,
  // visible particles, follow mode, refit on resize, and the joystick beside it.
  await page.locator('#tabs button[data-view="map"]').click();
  await until('MCL particles drawn', () => page.evaluate(() => (window.__rack.particleSizePx ?? 0) > 0), 10000);
  const layers = await page.locator('[data-testid="map-legend"] label').count();
  if (layers < 8) throw new Error(`${layers} layers in the legend`);
  await page.locator('[data-testid="layer-particles"] input').uncheck();
  if (await page.evaluate(() => window.__rack.layers.particles) !== false) throw new Error('the particles layer did not switch off');
  await shot(page, 'panels-map-no-particles.png');
  await page.locator('[data-testid="layer-particles"] input').check();
  const size = await page.evaluate(() => window.__rack.particleSizePx);
  if (size < 4) throw new Error(`particles drawn ${size} px wide`);
  const bar = await page.evaluate(() => window.__rack.scaleBar);
  const mant = bar.metres / 10 ** Math.floor(Math.log10(bar.metres) + 1e-9);
  if (![1, 2, 5].some((k) => Math.abs(mant - k) < 1e-6) || bar.px < 40 || bar.px > 250) throw new Error(`scale bar ${JSON.stringify(bar)}`);
  const box = await page.locator('[data-testid="map"]').boundingBox();
  const dpr = await page.evaluate(() => window.devicePixelRatio || 1);
  const px = await page.evaluate(() => window.__rack.toPx(5, 4));
  await page.mouse.move(box.x + px[0] / dpr, box.y + px[1] / dpr);
  const cur = await until('cursor coordinates', async () => {
    const m = /cursor x (-?[\d.]+) m, y (-?[\d.]+) m/.exec(await page.locator('[data-testid="map-cursor"]').textContent());
    return m ? [Number(m[1]), Number(m[2])] : null;
  }, 3000);
  if (Math.hypot(cur[0] - 5, cur[1] - 4) > 0.1) throw new Error(`cursor at map (5, 4) reads ${cur}`);
  log(`map: ${layers} layers in the legend (particles toggled off and on), particles ${size} px, scale bar ${bar.metres} m = ${bar.px.toFixed(0)} px, cursor at (5, 4) reads (${cur.join(', ')})`);
  const joy = await page.locator('[data-testid="joystick-box"]').boundingBox();
  if (overlap(joy, box)) throw new Error(`the joystick ${JSON.stringify(joy)} covers the map ${JSON.stringify(box)}`);
  // Follow: zoom in, then the view's centre stays on the robot while it drives.
  await page.mouse.wheel(0, -500);
  await page.locator('[data-testid="follow-robot"]').check();
  const off = await until('the view to centre on the robot', () => page.evaluate(() => {
    const st = window.__rack;
    const d = [...st.data.values()].find((x) => x.class === 'Position' && x.system === 0) ?? [...st.data.values()].find((x) => x.class === 'MCL' && x.system === 0);
    const cv = document.querySelector('[data-testid="map"]');
    const [cx, cy] = [(cv.width / 2 - st.view.ox) / st.view.scale, (st.view.oy - cv.height / 2) / st.view.scale];
    const e = Math.hypot(cx - d.data.x, cy - d.data.y);
    return e < 0.3 ? e + 1e-9 : null;
  }), 5000);
  log(`follow mode: the view's centre ${(off * 100).toFixed(1)} cm from the robot's pose; joystick beside the map, not over it`);
  await shot(page, 'panels-map-follow.png');
  await page.locator('[data-testid="follow-robot"]').uncheck();
  // Refit on resize: a smaller window fits the whole map again.
  const before = await page.evaluate(() => window.__rack.view.scale);
  await page.setViewportSize({ width: 900, height: 600 });
  await until('the map to refit the smaller window', () => page.evaluate((s0) => {
    const st = window.__rack;
    const m = st.maps.get(st.view.system);
    const cv = document.querySelector('[data-testid="map"]');
    if (!st.view.fitted || Math.abs(st.view.scale - s0) < 1e-9) return false;
    const [x0, y0] = st.toPx(m.meta.origin_x, m.meta.origin_y + m.meta.height * m.meta.resolution);
    const [x1, y1] = st.toPx(m.meta.origin_x + m.meta.width * m.meta.resolution, m.meta.origin_y);
    return x0 >= -1 && y0 >= -1 && x1 <= cv.width + 1 && y1 <= cv.height + 1;
  }, before), 5000);
  log('map refitted after the window shrank (the whole map inside the canvas)');
  await shot(page, 'panels-map-resized.png');

  // 5. A phone: one column, nothing wider than the screen, the map usable and the
  // joystick below it.
  const phone = await open(url, { width: 390, height: 844 }, { isMobile: true, hasTouch: true, deviceScaleFactor: 2 });
  await phone.locator('[data-testid="comp-pilot"][data-state="enabled"]').waitFor({ timeout: 15000 });
  const layout = await phone.evaluate(() => {
    const r = (sel) => document.querySelector(sel).getBoundingClientRect().toJSON();
    return { width: document.documentElement.scrollWidth, map: r('[data-testid="map"]'), joy: r('[data-testid="joystick-box"]'),
      list: r('[data-testid="components"]'), tabs: r('#tabs') };
  });
  if (layout.width > 391) throw new Error(`the page is ${layout.width} px wide on a 390 px phone`);
  if (layout.map.width < 350 || layout.map.height < 250) throw new Error(`map on a phone: ${JSON.stringify(layout.map)}`);
  if (overlap(layout.joy, layout.map) || layout.joy.y < layout.map.y) throw new Error(`phone: joystick ${JSON.stringify(layout.joy)} vs map ${JSON.stringify(layout.map)}`);
  if (layout.list.y > layout.map.y || layout.list.height < 100) throw new Error(`phone: the component list ${JSON.stringify(layout.list)} is not shown above the map`);
  const legendShown = await phone.evaluate(() => !document.querySelector('[data-testid="map-legend"]').classList.contains('collapsed'));
  if (legendShown) throw new Error('phone: the legend covers the map before it is asked for');
  await until('particles on the phone', () => phone.evaluate(() => (window.__rack.particleSizePx ?? 0) > 0), 10000);
  log(`phone 390x844: page ${layout.width} px wide, map ${layout.map.width.toFixed(0)}x${layout.map.height.toFixed(0)}, joystick below it`);
  await shot(phone, 'panels-phone-map.png');
  await phone.locator('#tabs button[data-view="plots"]').tap();
  await phone.locator('[data-testid="plot-component"]').selectOption(chassisAddr);
  await until('fields on the phone', () => phone.evaluate(() => [...document.querySelectorAll('#pl-field option')].some((o) => o.value === 'vx')), 10000);
  await phone.locator('[data-testid="plot-field"]').selectOption('vx');
  await phone.locator('[data-testid="plot-add"]').tap();
  await until('a plot on the phone', () => phone.evaluate(() => window.__rack.plots.length === 1 && window.__rack.plots[0].xs.length >= 3), 10000);
  const plotW = await phone.evaluate(() => document.querySelector('.plotbox').getBoundingClientRect().width);
  if (plotW > 390) throw new Error(`a plot ${plotW} px wide on a 390 px phone`);
  await shot(phone, 'panels-phone-plots.png');
  log('phone: plots tab usable');
  await phone.context().close();

  // 5b. A live trace in the Timeline tab (issue 20), as `rackctl trace`; a robot with
  // no host is refused with the reason.
  await page.setViewportSize({ width: 1400, height: 850 });
  await page.locator('#tabs button[data-view="timeline"]').click();
  await page.locator('[data-testid="timeline-system"]').fill('9');
  await page.locator('[data-testid="timeline-record"]').click();
  await until('a trace of a robot with no host refused', async () =>
    /trace: robot 9: no host/.test(await page.locator('[data-testid="timeline-info"]').textContent()), 5000);
  await page.locator('[data-testid="timeline-system"]').fill('0');
  await page.locator('[data-testid="timeline-seconds"]').fill('0.5');
  await page.locator('[data-testid="timeline-record"]').click();
  const traced = await until('the live trace drawn', async () => {
    const t = await page.locator('[data-testid="timeline-info"]').textContent();
    const m = /live trace of host sim-mcl: (\d+) tasks, (\d+) cycles/.exec(t);
    return m && Number(m[1]) > 0 && Number(m[2]) > 0 ? t : null;
  }, 15000);
  log(`timeline: ${traced}`);
  await shot(page, 'panels-timeline-live.png');

  // 6. Robot 2's rackd stops cleanly: its host shows as not answering, then leaves
  // the list after rack-gui's --forget-s.
  if (args['stop-pid']) {
    process.kill(Number(args['stop-pid']), 'SIGTERM');
    const stopped = Date.now();
    await until('robot 2 shown as not answering', () => page.evaluate(() =>
      /NOT ANSWERING for \d+ s \(leaves the list after 3 s\)/.test(document.querySelector('.robot[data-system="2"] h4')?.textContent ?? '')), 10000);
    await shot(page, 'panels-host-silent.png');
    await until('robot 2 to leave the list', () => page.evaluate(() => document.querySelector('.robot[data-system="2"]') === null), 15000);
    await until('the header to count one robot', async () => /^1 robot answering/.test(await page.locator('[data-testid="connection"]').textContent()), 5000);
    const stale = await page.evaluate(() => window.__rack.plots.find((p) => p.component.includes('(2/'))?.el.classList.contains('stale'));
    if (stale !== true) throw new Error('the stopped robot\'s plot is not marked stale');
    log(`robot 2 stopped (SIGTERM): not answering, then left the list ${((Date.now() - stopped) / 1000).toFixed(1)} s later; its plot marked stale`);
    await shot(page, 'panels-host-gone.png');
  }
} catch (e) {
  console.log(`FAILED: ${e.message}`);
  if (page) await page.screenshot({ path: join(shots, 'panels-failure.png') }).catch(() => {});
  failed = true;
}
await browser.close();
log(failed ? 'panels: FAILED' : 'panels: all steps passed');
process.exit(failed ? 1 : 0);
