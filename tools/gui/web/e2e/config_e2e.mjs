// The Configuration view end to end in headless Chromium (Debian's /usr/bin/chromium,
// driven by playwright-core), against a rack-gui started with --config DIR on a copy
// of configs/two_robots/. Run by tests/integration/gui_config_e2e_test.cpp, or by hand:
//
//   node e2e/config_e2e.mjs --url http://127.0.0.1:8080/ --file robot1_aux.yaml [--live 1] [--padding N] [--shots DIR] [--chromium PATH]
//
// Steps: the deployment graph of the directory is drawn (--live: and with what the
// network says, robot1_aux.yaml's rackd running, and what runs from discovery alone,
// without host files); FILE is opened; its data
// task's priority set to 300 in the form shows rackd --check's error on its line and
// Save stays disabled; 65 makes the file valid; Save writes it; the form sets amplitude,
// written in a one-line flow map (params: {...}), to 1.5 in place; --padding N: N
// comment lines appended make the file larger than one WebSocket message, checked and
// saved in parts (the caller then runs rackd --check on the file). Exit 0 when every
// step passed.
import { chromium } from 'playwright-core';
import { mkdirSync } from 'node:fs';
import { join } from 'node:path';

const args = Object.fromEntries(process.argv.slice(2).reduce((acc, a, i, all) => {
  if (a.startsWith('--')) acc.push([a.slice(2), all[i + 1]]);
  return acc;
}, []));
const url = args.url ?? 'http://127.0.0.1:8080/';
const shots = args.shots ?? 'e2e-shots';
const fileName = args.file ?? 'robot1_aux.yaml';
mkdirSync(shots, { recursive: true });

const t0 = Date.now();
const log = (s) => console.log(`[${((Date.now() - t0) / 1000).toFixed(1)} s] ${s}`);
const browser = await chromium.launch({
  executablePath: args.chromium ?? '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--disable-gpu'],
});
let failed = false;
const page = await browser.newPage({ viewport: { width: 1400, height: 900 } });
page.on('pageerror', (e) => { console.log(`page error: ${e.message}`); failed = true; });
page.on('dialog', (d) => d.accept());
const shot = async (name) => { await page.screenshot({ path: join(shots, name) }); log(`screenshot ${name}`); };
async function until(what, fn, ms = 15000) {
  const end = Date.now() + ms;
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() > end) throw new Error(`timed out after ${ms} ms waiting for ${what}`);
    await new Promise((r) => setTimeout(r, 100));
  }
}
const status = () => page.locator('[data-testid="cfg-status"]').textContent();

try {
  await page.goto(url);
  // Connected to rack-gui (the header is green only once a robot answers: not needed here).
  await until('the connection', async () => {
    const text = (await page.locator('[data-testid="connection"]').textContent()) ?? '';
    return text !== '' && !text.includes('disconnected');
  });
  await page.click('[data-testid="tab-config"]');

  // 1. The graph of the directory: an SVG image drawn by graphviz, and the allocation.
  await until('the deployment graph', () => page.evaluate(() => {
    const img = document.querySelector('img[data-testid="cfg-graph"]');
    return img && img.complete && img.naturalWidth > 100;
  }));
  const deployment = await page.evaluate(() => window.__rackConfig.deployment);
  const hosts = deployment.hosts.map((h) => h.host).sort();
  if (JSON.stringify(hosts) !== JSON.stringify(['base-station', 'robot1-aux', 'robot1-main', 'robot2-main'])) {
    throw new Error(`graph: hosts ${JSON.stringify(hosts)}`);
  }
  const crossing = deployment.flows.find((f) => f.consumer === 'fleet-monitor');
  if (!crossing || crossing.producer !== 'scanner' || crossing.networks.join('>') !== 'robot1>fleet>robot2') {
    throw new Error(`graph: flow to fleet-monitor ${JSON.stringify(crossing)}`);
  }
  const alloc = await page.locator('[data-testid="cfg-alloc"]').textContent();
  if (!alloc.includes('scanner') || !alloc.includes('10 ms')) throw new Error(`allocation: ${alloc}`);
  log('graph: 4 hosts, scanner -> fleet-monitor via robot1 > fleet > robot2');
  await shot('config-graph.png');

  // 1b. Live (--live given: the caller runs robot1_aux.yaml's rackd on rack-gui's
  // network): the allocation shows the scanner's state, utilisation and worst
  // wake-up latency, and the hosts that do not run as STALE.
  if (args.live) {
    await page.check('[data-testid="cfg-live"]');
    const live = await until('the live allocation', async () => {
      const t = await page.locator('[data-testid="cfg-alloc"]').innerText();  // a line per row
      return /scanner +data +10 ms +([0-9.]+ ms|-) +[0-9.]+% +[0-9]+ us +ENABLED/.test(t) && t.includes('STALE') ? t : null;
    }, 30000);
    const stale = live.split('\n').filter((l) => l.includes('STALE')).map((l) => l.split(' ')[0]).sort();
    if (JSON.stringify(stale) !== JSON.stringify(['base-station', 'robot1-main', 'robot2-main'])) {
      throw new Error(`stale hosts: ${JSON.stringify(stale)}\n${live}`);
    }
    log(`live: ${live.split('\n').find((l) => /scanner +data/.test(l)).trim()}; stale: ${stale.join(', ')}`);
    await shot('config-live.png');
    await page.uncheck('[data-testid="cfg-live"]');

    // 1c. What runs, from discovery alone (no host file): robot1_aux.yaml's rackd with
    // its scanner's tasks as they run (GET_TASKS: data task priority 60, every 10 ms).
    const dir = await page.inputValue('[data-testid="cfg-dir"]');
    await page.selectOption('[data-testid="cfg-dir"]', ':discovery');
    const running = await until('the deployment as it runs', () => page.evaluate(() => {
      const d = window.__rackConfig.deployment;
      const h = d?.hosts?.find((x) => x.host === 'robot1-aux');
      const c = h?.components?.find((x) => x.name === 'scanner');
      return d && !d.hosts.some((x) => x.file && !x.file.startsWith('discovery on ')) && c?.data_task?.priority === 60
        ? d : null;
    }), 30000);
    const ranAlloc = await page.locator('[data-testid="cfg-alloc"]').innerText();
    if (!/60 +scanner +data +10 ms/.test(ranAlloc)) throw new Error(`allocation as it runs: ${ranAlloc}`);
    const scanner = running.hosts.find((x) => x.host === 'robot1-aux').components.find((x) => x.name === 'scanner');
    log(`discovery alone: ${running.hosts.length} host(s), scanner data p${scanner.data_task.priority} ` +
        `cmd p${scanner.command_task.priority}, ${scanner.data_task.period_ns / 1e6} ms`);
    await shot('config-running.png');
    await page.selectOption('[data-testid="cfg-dir"]', dir);
  }

  // 2. Open the file; its text and a form for the component under the cursor.
  const file = await page.evaluate((n) => {
    for (const d of window.__rackConfig.dirs) for (const f of d.files) if (f.name === n) return f.file;
    return null;
  }, fileName);
  if (!file) throw new Error(`${fileName} is not listed`);
  await page.selectOption('[data-testid="cfg-file"]', file);
  await until('the file text', async () => (await page.inputValue('[data-testid="cfg-text"]')).includes('class: Generator'));
  await until('valid', async () => (await status()).startsWith('valid'));
  const text = await page.inputValue('[data-testid="cfg-text"]');
  const lines = text.split('\n');
  const prioLine = lines.findIndex((l) => /data_task:.*priority: 60/.test(l)) + 1;
  if (prioLine <= 0) throw new Error('no data_task priority 60 in the file');
  // The cursor into the component: the form appears (built from Generator's description).
  await page.evaluate((line) => {
    const ta = document.querySelector('[data-testid="cfg-text"]');
    const at = ta.value.split('\n').slice(0, line - 1).join('\n').length + 1;
    ta.focus();
    ta.setSelectionRange(at, at);
    ta.dispatchEvent(new MouseEvent('click', { bubbles: true }));
  }, prioLine);
  await until('the form', () => page.locator('[data-testid="cfg-form-param-amplitude"]').count());

  // 3. An invalid priority: rackd --check's error on its line, no saving.
  await page.fill('[data-testid="cfg-form-data_task-priority"]', '300');
  await page.press('[data-testid="cfg-form-data_task-priority"]', 'Enter');
  await page.locator('[data-testid="cfg-form-data_task-priority"]').blur();
  await until('the error on its line', () => page.locator(`[data-testid="cfg-error-line-${prioLine}"]`).count());
  const errors = await page.locator('[data-testid="cfg-errors"]').textContent();
  if (!errors.includes(`line ${prioLine}:`) || !errors.includes('300')) throw new Error(`errors: ${errors}`);
  if (!(await page.locator('[data-testid="cfg-save"]').isDisabled())) throw new Error('Save is enabled for an invalid file');
  const diff = await page.locator('[data-testid="cfg-diff"]').textContent();
  if (!diff.includes('priority: 300')) throw new Error(`diff: ${diff}`);
  log(`priority 300: error on line ${prioLine}: ${errors}`);
  await shot('config-error.png');

  // 4. Fixed: valid, saved.
  await page.fill('[data-testid="cfg-form-data_task-priority"]', '65');
  await page.locator('[data-testid="cfg-form-data_task-priority"]').blur();
  await until('valid again', async () => (await status()).startsWith('valid'));
  if (await page.locator(`[data-testid="cfg-error-line-${prioLine}"]`).count()) throw new Error('the error is still shown');
  await until('Save enabled', async () => !(await page.locator('[data-testid="cfg-save"]').isDisabled()));
  await page.click('[data-testid="cfg-save"]');
  await until('saved', async () => (await status()).startsWith('saved'));
  const after = await page.inputValue('[data-testid="cfg-text"]');
  const changed = after.split('\n').filter((l, i) => l !== lines[i]);
  if (changed.length !== 1 || !/priority: 65/.test(changed[0])) throw new Error(`more than the priority changed: ${JSON.stringify(changed)}`);
  log(`saved ${file}`);
  await shot('config-saved.png');

  // 5. A parameter written on one line (params: {amplitude: 1.0, frequency_hz: 0.5}):
  // the form changes the value in place in the flow map, nothing else on the line.
  const paramsLine = after.split('\n').findIndex((l) => /params: \{.*amplitude/.test(l));
  if (paramsLine < 0) throw new Error('no one-line params with amplitude in the file');
  await page.evaluate((line) => {
    const ta = document.querySelector('[data-testid="cfg-text"]');
    const at = ta.value.split('\n').slice(0, line).join('\n').length + 1;
    ta.focus();
    ta.setSelectionRange(at, at);
    ta.dispatchEvent(new MouseEvent('click', { bubbles: true }));
  }, paramsLine);
  await until('the form', () => page.locator('[data-testid="cfg-form-param-amplitude"]').count());
  if ((await page.inputValue('[data-testid="cfg-form-param-amplitude"]')) !== '1.0') throw new Error('the form does not show amplitude 1.0');
  await page.fill('[data-testid="cfg-form-param-amplitude"]', '1.5');
  await page.locator('[data-testid="cfg-form-param-amplitude"]').blur();
  await until('valid after the one-line edit', async () => (await status()).startsWith('valid'));
  const flowEdited = await page.inputValue('[data-testid="cfg-text"]');
  const flowChanged = flowEdited.split('\n').filter((l, i) => l !== after.split('\n')[i]);
  const expectedLine = after.split('\n')[paramsLine].replace('amplitude: 1.0', 'amplitude: 1.5');
  if (flowChanged.length !== 1 || flowChanged[0] !== expectedLine) {
    throw new Error(`the one-line edit changed ${JSON.stringify(flowChanged)}, expected ${JSON.stringify(expectedLine)}`);
  }
  log(`one-line params: ${flowChanged[0].trim()}`);

  // 6. A file above one WebSocket message (64 KiB): checked and saved in parts.
  if (args.padding) {
    const lines = Number(args.padding);
    await page.evaluate((n) => {
      const ta = document.querySelector('[data-testid="cfg-text"]');
      let pad = '';
      for (let i = 0; i < n; i++) pad += `# padding ${i}: a comment line that makes this host file larger than one WebSocket message\n`;
      ta.value += pad;
      ta.dispatchEvent(new Event('input', { bubbles: true }));
    }, lines);
    const size = (await page.inputValue('[data-testid="cfg-text"]')).length;
    await until('valid (sent in parts)', async () => (await status()).startsWith('valid'), 30000);
    await until('Save enabled', async () => !(await page.locator('[data-testid="cfg-save"]').isDisabled()));
    await page.click('[data-testid="cfg-save"]');
    await until('saved in parts', async () => (await status()).startsWith('saved'), 30000);
    log(`saved ${size} characters in parts`);
  }
} catch (e) {
  console.log(`FAILED: ${e.message}`);
  failed = true;
  await shot('config-failure.png').catch(() => {});
}
await browser.close();
process.exit(failed ? 1 : 0);
