// A mutation fuzzer for what rack-foxglove decodes from Foxglove clients: the
// WebSocket protocol's client messages (@foxglove/ws-protocol's FoxgloveServer parses
// them; rack-foxglove's Bridge carries out subscribe, unsubscribe, getParameters,
// setParameters and service calls). Any program can connect to the bridge's port, so
// every message is outside input. No harness of tests/fuzz/ reaches JavaScript, so this
// one runs the real rack-foxglove (its own process, --port 0) over a stand-in rack-gui
// (a WebSocket server here that lists one robot with one component and answers every
// request), connects as a client and sends mutants of well-formed client messages:
// values replaced by others of any JSON type, keys dropped, texts cut or bytes changed,
// binary service calls with their length fields set to extremes.
//
// What must hold: after every batch of mutants the bridge still answers a well-formed
// getParameters (a probe) within --probe-ms, and its process is alive. A batch that
// breaks this is saved to OUT/ (a JSON array: strings are sent as text messages,
// {"binary": BASE64} as binary ones) with rack-foxglove's last output, and the run
// exits 1. Every file of tests/fuzz/regressions/foxglove_ws/ is sent first, one batch
// each (regressions).
//
// usage: node ws_client_fuzz.mjs [--seconds N] [--seed N] [--batch N] [--out DIR] [--probe-ms MS] [FILE...]
// (FILE: a batch to send, as saved.) Exit 0 when the bridge kept the rules, 1 when it
// did not, 77 without the npm packages (ctest: fuzz_foxglove_ws, 10 s, skipped then).
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { seededRandom } from './fuzz_random.mjs';

let WebSocket;
let WebSocketServer;
try {
  ({ WebSocket, WebSocketServer } = await import('ws'));
  await import('@foxglove/ws-protocol');  // rack-foxglove's own packages
  await import('../lib/exact_json.mjs');
} catch (e) {
  console.error(`ws_client_fuzz: ${e.message} (run npm ci in tools/foxglove; scripts/setup.sh does)`);
  process.exit(77);
}

const here = path.dirname(fileURLToPath(import.meta.url));
const tool = path.join(here, '..', 'rack-foxglove.mjs');
const regressions = path.join(here, '..', '..', '..', 'tests', 'fuzz', 'regressions', 'foxglove_ws');

const args = process.argv.slice(2);
const o = { seconds: 10, seed: 1, batch: 16, out: '', probeMs: 5000, files: [] };
for (let i = 0; i < args.length; i += 1) {
  const a = args[i];
  const v = () => {
    if (i + 1 >= args.length) throw new Error(`${a} needs a value`);
    return args[++i];
  };
  if (a === '--seconds') o.seconds = Number(v());
  else if (a === '--seed') o.seed = Number(v());
  else if (a === '--batch') o.batch = Number(v());
  else if (a === '--out') o.out = v();
  else if (a === '--probe-ms') o.probeMs = Number(v());
  else if (a === '-h' || a === '--help') {
    console.log(fs.readFileSync(fileURLToPath(import.meta.url), 'utf8').split('\nimport ')[0]);
    process.exit(0);
  } else if (a.startsWith('-')) {
    console.error(`ws_client_fuzz: unknown option ${a}`);
    process.exit(2);
  } else o.files.push(a);
}
const out = o.out || fs.mkdtempSync(path.join(os.tmpdir(), 'foxglove-ws-fuzz-'));
fs.mkdirSync(out, { recursive: true });

const { rand, below, pick } = seededRandom(o.seed);  // a seed repeats a run

// The stand-in rack-gui: one robot, one enabled component, every request answered.
const kComponent = 'Pilot(0/0)';
const gui = new WebSocketServer({ host: '127.0.0.1', port: 0 });
await new Promise((resolve) => gui.on('listening', resolve));
gui.on('connection', (ws) => {
  // As rack-gui, the component list again every round (the bridge may join after the first).
  const describe = () => {
    ws.send(JSON.stringify({ type: 'class', system: 0, class_id: 20, class: 'Pilot', commands: [], parameters: [], data: null }));
    ws.send(JSON.stringify({ type: 'components', robots: [{ system: 0, hosts: [{ components: [
      { address: kComponent, name: 'pilot', class: 'Pilot', impl: 'Pilot', state: 'enabled' }] }] }] }));
  };
  describe();
  const round = setInterval(describe, 500);
  ws.on('close', () => clearInterval(round));
  ws.on('message', (data) => {
    let m;
    try { m = JSON.parse(data.toString('utf8')); } catch { return; }
    if (m?.op === 'get_params') {
      ws.send(JSON.stringify({ type: 'params', component: m.component, params: [{ name: 'vx_max', kind: 'float', value: 0.5 }] }));
    }
    if (m?.id !== undefined) ws.send(JSON.stringify({ type: 'result', id: m.id, ok: true, text: 'stand-in rack-gui' }));
  });
});

// rack-foxglove itself.
let log = '';
let exited = null;
const child = spawn(process.execPath, [tool, '--gui', `ws://127.0.0.1:${gui.address().port}`, '--port', '0', '--polled'],
                    { stdio: ['ignore', 'pipe', 'pipe'] });
const keep = (d) => { log = (log + d.toString()).slice(-8000); };
child.stdout.on('data', keep);
child.stderr.on('data', keep);
child.on('exit', (code, signal) => { exited = `exit ${code}${signal ? ` (${signal})` : ''}`; });
const port = await new Promise((resolve, reject) => {
  const t = setTimeout(() => reject(new Error(`rack-foxglove did not start in 20 s:\n${log}`)), 20000);
  const look = () => {
    const m = log.match(/serving ws:\/\/[^:]+:(\d+)/);
    if (m) {
      clearTimeout(t);
      resolve(Number(m[1]));
    } else if (exited) {
      clearTimeout(t);
      reject(new Error(`rack-foxglove ended (${exited}):\n${log}`));
    } else setTimeout(look, 20);
  };
  look();
}).catch((e) => {
  console.error(`ws_client_fuzz: ${e.message}`);
  process.exit(1);
});

// The client.
const client = new WebSocket(`ws://127.0.0.1:${port}`, ['foxglove.websocket.v1']);
const answers = new Map();  // probe id -> resolve
let serviceIds = [1];
client.on('message', (data, binary) => {
  if (binary) return;
  let m;
  try { m = JSON.parse(data.toString('utf8')); } catch { return; }
  if (m.op === 'advertiseServices' && Array.isArray(m.services)) serviceIds = m.services.map((s) => s.id);
  if (m.op === 'parameterValues' && answers.has(m.id)) answers.get(m.id)();
});
await new Promise((resolve, reject) => {
  client.on('open', resolve);
  client.on('error', reject);
});
client.on('error', () => {});

// Well-formed client messages (the protocol's and rack-foxglove's parameter names).
const seeds = () => [
  { op: 'subscribe', subscriptions: [{ id: 1, channelId: 1 }, { id: 2, channelId: 2 }] },
  { op: 'unsubscribe', subscriptionIds: [1, 2] },
  { op: 'getParameters', parameterNames: [`${kComponent}.vx_max`, 'nodot'], id: 'g' },
  { op: 'getParameters', parameterNames: [] },
  { op: 'setParameters', parameters: [{ name: `${kComponent}.vx_max`, value: 0.3 }], id: 's' },
  { op: 'setParameters', parameters: [{ name: `${kComponent}.mode`, value: 'fast' }] },
  { op: 'subscribeParameterUpdates', parameterNames: [`${kComponent}.vx_max`] },
  { op: 'unsubscribeParameterUpdates', parameterNames: [`${kComponent}.vx_max`] },
  { op: 'advertise', channels: [{ id: 1, topic: '/x', encoding: 'json', schemaName: 'x' }] },
  { op: 'unadvertise', channelIds: [1] },
  { op: 'fetchAsset', uri: 'package://x', requestId: 1 },
  { op: 'subscribeConnectionGraph' },
];
const kValues = () => [null, true, false, 0, -1, 1.5, 2 ** 31, -(2 ** 53), 1e308, '', 'x', '.', 'a.b.c', `${kComponent}.`,
                       '\u0000', 'x'.repeat(1000), [], [null], [1, 'a'], {}, { name: 1 }, { name: null, value: {} },
                       [{}], [{ name: 'Pilot(0/0).vx_max' }], [{ id: 'x', channelId: null }]];

// Replaces, drops or adds one value somewhere in a JSON value (in place where it can).
function mutateValue(v, depth = 0) {
  if (v === null || typeof v !== 'object' || depth > 4 || rand() < 0.25) return pick(kValues());
  const keys = Array.isArray(v) ? [...v.keys()] : Object.keys(v);
  if (keys.length === 0 || rand() < 0.1) {
    if (Array.isArray(v)) v.push(pick(kValues()));
    else v[pick(['op', 'id', 'name', 'value', 'parameterNames', 'parameters', 'subscriptions', 'x'])] = pick(kValues());
    return v;
  }
  const k = pick(keys);
  if (rand() < 0.15) {
    if (Array.isArray(v)) v.splice(k, 1);
    else delete v[k];
  } else {
    v[k] = mutateValue(v[k], depth + 1);
  }
  return v;
}

function mutateText(t) {
  const b = Buffer.from(t, 'utf8');
  const at = below(Math.max(1, b.length));
  switch (below(3)) {
    case 0: return b.subarray(0, at).toString('latin1');
    case 1:
      b[at] = below(256);
      return b.toString('latin1');
    default: return t.slice(0, at) + pick(['"', '{', '}', '[', ']', ',', ':', '\\', '1e999', 'null']) + t.slice(at);
  }
}

// A SERVICE_CALL_REQUEST (op 2): service id, call id, encoding length, encoding, data.
function serviceCall() {
  const body = JSON.stringify(mutateValue(pick([{ on: true }, { x: 1, y: 2 }, { x: 1, y: 2, phi: 0 }, {}])));
  const encoding = rand() < 0.8 ? 'json' : pick(['', 'cdr', 'x'.repeat(300)]);
  const b = Buffer.alloc(13 + encoding.length + Buffer.byteLength(body));
  b[0] = rand() < 0.9 ? 2 : below(256);
  b.writeUInt32LE(rand() < 0.8 ? pick(serviceIds) : pick([0, 0xffffffff, below(1000)]), 1);
  b.writeUInt32LE(below(1000), 5);
  b.writeUInt32LE(rand() < 0.8 ? encoding.length : pick([0xffffffff, 0x7fffffff, b.length, b.length + 1]), 9);
  b.write(encoding, 13, 'latin1');
  b.write(body, 13 + encoding.length, 'utf8');
  return rand() < 0.2 ? b.subarray(0, below(b.length)) : b;
}

function mutant() {
  if (rand() < 0.25) return serviceCall();
  let m = pick(seeds());
  const n = 1 + below(3);
  for (let k = 0; k < n; k += 1) m = mutateValue(m);
  const text = JSON.stringify(m) ?? 'null';
  return rand() < 0.2 ? mutateText(text) : text;
}

const encode = (batch) => batch.map((m) => (typeof m === 'string' ? m : { binary: Buffer.from(m).toString('base64') }));
const decode = (batch) => batch.map((m) => (typeof m === 'string' ? m : Buffer.from(m.binary, 'base64')));

let probes = 0;
// Sends a batch, then a well-formed getParameters; true when it is answered in time.
async function run(batch) {
  for (const m of batch) client.send(m, { binary: typeof m !== 'string' });
  const id = `probe-${probes++}`;
  const answered = new Promise((resolve) => {
    answers.set(id, () => resolve(true));
    setTimeout(() => resolve(false), o.probeMs);
  });
  client.send(JSON.stringify({ op: 'getParameters', parameterNames: [`${kComponent}.vx_max`], id }));
  const ok = await answered;
  answers.delete(id);
  return ok && exited === null && client.readyState === WebSocket.OPEN;
}

let failed = null;
const batches = [];
if (fs.existsSync(regressions)) {
  for (const f of fs.readdirSync(regressions).sort()) batches.push([`regression ${f}`, decode(JSON.parse(fs.readFileSync(path.join(regressions, f), 'utf8')))]);
}
for (const f of o.files) batches.push([f, decode(JSON.parse(fs.readFileSync(f, 'utf8')))]);
let sent = 0;
for (const [name, batch] of batches) {
  if (!(await run(batch))) {
    failed = { name, batch };
    break;
  }
  sent += batch.length;
}
const end = Date.now() + o.seconds * 1000;
let mutants = 0;
while (!failed && Date.now() < end) {
  const batch = Array.from({ length: o.batch }, mutant);
  if (!(await run(batch))) failed = { name: `mutants ${mutants}..${mutants + batch.length - 1}`, batch };
  mutants += batch.length;
  sent += batch.length;
}

client.close();
child.kill('SIGTERM');
await new Promise((resolve) => {
  if (exited) resolve();
  else child.on('exit', resolve);
  setTimeout(resolve, 3000);
});
gui.close();
if (failed) {
  const file = path.join(out, `failed-${o.seed}.json`);
  fs.writeFileSync(file, `${JSON.stringify(encode(failed.batch), null, 1)}\n`);
  console.log(`FAILED ${failed.name}: the bridge ${exited ? `ended (${exited})` : `did not answer a probe in ${o.probeMs} ms`}; ` +
              `the batch is in ${file}\n--- rack-foxglove's last output:\n${log}`);
  process.exit(1);
}
const refused = log.match(/(\d+) malformed Foxglove client message\(s\) refused/);
console.log(`ok ${sent} messages (${mutants} mutants, ${batches.length} saved batches), ${probes} probes answered` +
            `${refused ? `, ${refused[1]} refused as malformed by the protocol library` : ''}`);
process.exit(0);
