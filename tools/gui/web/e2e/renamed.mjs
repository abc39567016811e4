// A component chosen while rack-gui lists it under its class number (Class0x91(2/0):
// its class description has not come yet) stays chosen once it is listed under its
// class name (Counter(2/0)): its view follows, and its command panel appears. Run by
// tests/integration/gui_e2e_test.cpp (GuiE2eTest.ComponentChosenBeforeItsClassIsDescribedKeepsItsView)
// against a rack-gui polling every 10 s (--poll-ms 10000), so that the host's first
// listing, under class numbers, stays for a whole round; or by hand:
//
//   node e2e/renamed.mjs --url URL [--chromium PATH]
//
// URL: that rack-gui, with a robot whose component `counter` is of the plug-in class
// Counter (tests/integration/plugin/counter_plugin.cpp: command RESET).
import { chromium } from 'playwright-core';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) => {
  if (a.startsWith('--')) acc.push([a.slice(2), all[i + 1]]);
  return acc;
}, []));
const t0 = Date.now();
const log = (s) => console.log(`[${((Date.now() - t0) / 1000).toFixed(1)} s] ${s}`);
const browser = await chromium.launch({
  executablePath: args.chromium ?? '/usr/bin/chromium', headless: true, args: ['--no-sandbox', '--disable-gpu'],
});
let failed = false;
try {
  const page = await (await browser.newContext({ viewport: { width: 1400, height: 850 } })).newPage();
  page.on('pageerror', (e) => { console.log(`page error: ${e.message}`); failed = true; });
  await page.goto(args.url);
  const row = page.locator('[data-testid="comp-counter"]');
  await row.waitFor({ timeout: 30000 });
  const first = await row.getAttribute('data-address');
  log(`counter listed as ${first}`);
  if (!first.startsWith('Class0x')) throw new Error(`the counter was listed as ${first} first, not under its class number: nothing to check`);
  await row.locator('.name').click();
  await page.locator('[data-testid="cmd-RESET"]').waitFor({ timeout: 30000 });
  const selected = await page.evaluate(() => window.__rack.selected);
  const head = await page.locator('#d-head').textContent();
  log(`command panel shown; the view is of ${selected}: ${head.trim()}`);
  if (selected !== 'Counter(2/0)' || !head.includes('Counter(2/0)')) throw new Error(`the view is of ${selected} (${head})`);
} catch (e) {
  console.log(`FAILED: ${e.message}`);
  failed = true;
}
await browser.close();
if (failed) process.exit(1);
console.log('all checks passed');
