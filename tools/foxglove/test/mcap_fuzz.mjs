// A mutation fuzzer for the MCAP player's reader (lib/player.mjs openMcap and
// readMessages, @mcap/core's indexed and streamed readers with lib/codecs.mjs'
// decompressors): rack-foxglove play reads recordings handed to it by a user, which
// may be cut short, corrupt or not MCAP at all. No harness of tests/fuzz/ reaches it
// (JavaScript), so this one writes recordings with the recorder (lib/recorder.mjs: zstd,
// lz4 and uncompressed chunks), mutates them (bytes flipped, length and offset fields
// set to extremes, cuts, slices repeated) and reads every mutant as `play` does.
//
// What must hold for every input: openMcap either gives a reader or throws an Error
// with a message (rack-foxglove then says "not a readable MCAP file: ..."); reading the
// messages either ends or throws an Error with a message; no input takes longer than
// --slow-ms (a hang shows as the last input left in OUT/last.mcap), none grows the
// heap past --max-heap-mb. An input that breaks a rule is saved to OUT/ and the run
// exits 1. Every file of tests/fuzz/regressions/mcap/ is read first (regressions).
//
// usage: node mcap_fuzz.mjs [--seconds N] [--iterations N] [--seed N] [--out DIR]
//          [--slow-ms MS] [--max-heap-mb MB] [FILE...]
// (FILE: further seed recordings.) Prints the inputs run, how they ended (read to the
// end, refused at open, refused while reading) and the refusals' commonest messages.
// Exit 0 when every input kept the rules, 1 when one did not, 77 without the npm
// packages (ctest: fuzz_mcap, 10 s, skipped then).
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { seededRandom } from './fuzz_random.mjs';


// The player's and the recorder's modules import the npm packages: without `npm ci`
// here, the run is skipped (exit 77, as ctest's SKIP_RETURN_CODE), not passed.
let openMcap;
let Recorder;
try {
  ({ openMcap } = await import('../lib/player.mjs'));
  ({ Recorder } = await import('../lib/recorder.mjs'));
} catch (e) {
  console.error(`mcap_fuzz: ${e.message} (run npm ci in tools/foxglove; scripts/setup.sh does)`);
  process.exit(77);
}

const here = path.dirname(fileURLToPath(import.meta.url));
const regressions = path.join(here, '..', '..', '..', 'tests', 'fuzz', 'regressions', 'mcap');

const args = process.argv.slice(2);
const o = { seconds: 20, iterations: Infinity, seed: 1, out: '', slowMs: 5000, maxHeapMb: 1024, files: [] };
for (let i = 0; i < args.length; i += 1) {
  const a = args[i];
  const v = () => {
    if (i + 1 >= args.length) throw new Error(`${a} needs a value`);
    return args[++i];
  };
  if (a === '--seconds') o.seconds = Number(v());
  else if (a === '--iterations') o.iterations = Number(v());
  else if (a === '--seed') o.seed = Number(v());
  else if (a === '--out') o.out = v();
  else if (a === '--slow-ms') o.slowMs = Number(v());
  else if (a === '--max-heap-mb') o.maxHeapMb = Number(v());
  else if (a === '-h' || a === '--help') {
    console.log(fs.readFileSync(fileURLToPath(import.meta.url), 'utf8').split('\nimport ')[0]);
    process.exit(0);
  } else if (a.startsWith('-')) {
    console.error(`mcap_fuzz: unknown option ${a}`);
    process.exit(2);
  } else o.files.push(a);
}
const work = fs.mkdtempSync(path.join(os.tmpdir(), 'mcap-fuzz-'));
const out = o.out || work;
fs.mkdirSync(out, { recursive: true });

const { rand, below } = seededRandom(o.seed);  // a seed repeats a run

// Seeds: recordings as rack-foxglove writes them, one per compression, two chunks each.
async function record(compression) {
  const file = path.join(work, `seed-${compression}.mcap`);
  const r = await Recorder.open({ path: file, compression, chunkSize: 600, source: 'mcap_fuzz' });
  const schema = { type: 'object', properties: { time_ns: { type: 'integer' }, data: { type: 'object' } } };
  for (let k = 1; k <= 12; k += 1) {
    for (const [topic, data] of [['/rack/0/scan2d', { x: k * 0.1, y: 2, phi: 0.5, ranges: [1, 2, 3] }],
                                 ['/rack/0/mcl', { x: k * 0.1, y: 2.1, phi: 0.4 }]]) {
      r.add({ topic, schemaName: `rack.${topic.slice(8)}`, schema, time: BigInt(k) * 100000000n,
              message: { time_ns: k * 100000000, sequence: k, data } });
    }
  }
  await r.close();
  return new Uint8Array(fs.readFileSync(file));
}
const seeds = [];
for (const c of ['zstd', 'lz4', 'none']) seeds.push(await record(c));
for (const f of o.files) seeds.push(new Uint8Array(fs.readFileSync(f)));

const extremes = [0, 1, 0x7f, 0xff, 0xffff, 0x7fffffff, 0x80000000, 0xffffffff];
function mutate(seed) {
  let b = Uint8Array.from(seed);
  const n = 1 + below(4);
  for (let k = 0; k < n; k += 1) {
    const at = below(Math.max(1, b.length));
    switch (below(6)) {
      case 0:  // flip bits
        b[at] ^= 1 << below(8);
        break;
      case 1: {  // a 32- or 64-bit little-endian field (lengths, offsets, sizes) set to an extreme
        const dv = new DataView(b.buffer, b.byteOffset, b.byteLength);
        const e = extremes[below(extremes.length)];
        if (at + 8 <= b.length && rand() < 0.5) dv.setBigUint64(at, rand() < 0.3 ? 0xffffffffffffffffn : BigInt(e), true);
        else if (at + 4 <= b.length) dv.setUint32(at, e, true);
        break;
      }
      case 2:  // cut
        b = b.subarray(0, at);
        break;
      case 3: {  // repeat a slice
        const len = below(64);
        const c = new Uint8Array(b.length + len);
        c.set(b.subarray(0, at));
        c.set(b.subarray(at, at + len), at);
        c.set(b.subarray(at), at + Math.min(len, b.length - at));
        b = c;
        break;
      }
      case 4:  // random bytes
        for (let j = 0; j < 1 + below(8) && at + j < b.length; j += 1) b[at + j] = below(256);
        break;
      default:  // remove a slice
        b = Uint8Array.from([...b.subarray(0, at), ...b.subarray(at + below(32))]);
    }
  }
  return b;
}

const outcomes = { read: 0, refusedAtOpen: 0, refusedWhileReading: 0 };
const messages = new Map();  // refusal text (digits blanked) -> count
let failures = 0;
const lastFile = path.join(out, 'last.mcap');

function note(e) {
  const key = String(e?.message ?? e).replace(/[0-9]+/g, 'N').slice(0, 120);
  messages.set(key, (messages.get(key) ?? 0) + 1);
}

async function runOne(bytes, label) {
  fs.writeFileSync(lastFile, bytes);
  const started = Date.now();
  const heapBefore = process.memoryUsage().rss;
  let why = '';
  let reader = null;
  try {
    reader = await openMcap(lastFile);
  } catch (e) {
    if (!(e instanceof Error) || !e.message) why = `openMcap threw a non-Error or an empty message: ${String(e)}`;
    else {
      outcomes.refusedAtOpen += 1;
      note(e);
    }
  }
  if (reader && !why) {
    try {
      for await (const m of reader.readMessages()) {
        // The player's own decoding of a message (player.mjs: JSON, caught there).
        try { JSON.parse(new TextDecoder().decode(m.data)); } catch { /* counted by the player */ }
      }
      outcomes.read += 1;
    } catch (e) {
      if (!(e instanceof Error) || !e.message) why = `readMessages threw a non-Error or an empty message: ${String(e)}`;
      else {
        outcomes.refusedWhileReading += 1;
        note(e);
      }
    }
  }
  const ms = Date.now() - started;
  const grown = (process.memoryUsage().rss - heapBefore) / 1048576;
  if (!why && ms > o.slowMs) why = `took ${ms} ms (more than --slow-ms ${o.slowMs})`;
  if (!why && grown > o.maxHeapMb) why = `grew the process by ${grown.toFixed(0)} MB (more than --max-heap-mb ${o.maxHeapMb})`;
  if (why) {
    failures += 1;
    const keep = path.join(out, `failure-${failures}.mcap`);
    fs.writeFileSync(keep, bytes);
    console.log(`FAILED ${label}: ${why} (input: ${keep})`);
  }
}

let n = 0;
if (fs.existsSync(regressions)) {
  for (const f of fs.readdirSync(regressions).sort()) {
    await runOne(new Uint8Array(fs.readFileSync(path.join(regressions, f))), `regression ${f}`);
    n += 1;
  }
}
const deadline = Date.now() + o.seconds * 1000;
let i = 0;
while (Date.now() < deadline && i < o.iterations) {
  await runOne(mutate(seeds[i % seeds.length]), `mutant ${i} (seed ${o.seed})`);
  i += 1;
}
n += i;
console.log(`mcap_fuzz: ${n} inputs (${i} mutants, seed ${o.seed}): ${outcomes.read} read to the end, ` +
            `${outcomes.refusedAtOpen} refused at open, ${outcomes.refusedWhileReading} refused while reading, ` +
            `${failures} failed`);
for (const [m, c] of [...messages].sort((a, b) => b[1] - a[1]).slice(0, 12)) console.log(`  ${String(c).padStart(6)}  ${m}`);
if (!o.out && failures === 0) fs.rmSync(work, { recursive: true, force: true });
process.exit(failures > 0 ? 1 : 0);
