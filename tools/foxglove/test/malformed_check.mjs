// The player given a malformed MCAP file (driven by tests/integration/
// foxglove_test.cpp): `rack-foxglove play FILE` refuses it before joining rack-gui,
// exit status 2, saying what is wrong and where (byte offset, record), within seconds,
// never with a crash (no stack trace) or a hang:
//   - a file that is not MCAP (wrong magic), an empty one;
//   - one cut short in its header or in its first chunk (no complete message);
//   - a corrupt chunk (its bytes changed: CRC or decompression), a chunk of an unknown
//     compression, one that claims a huge uncompressed size, a record whose length is
//     past any file;
//   - a whole file whose channels no RACK class records (a ROS 2 schema in CDR): each
//     channel named with why it is not played.
// A good file (made here with the recorder, several zstd chunks) is accepted: the
// player goes on to join rack-gui (unreachable here: exit 1). Then a sweep of seeded
// random mutations (bytes changed, cut, overwritten) of the good file through the
// player's reader (openMcap) in-process: each is either read, every message then
// readable, or refused with MalformedMcap; nothing else is thrown.
//
// usage: node malformed_check.mjs DIR [--mutations N]
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

import { McapWriter } from '@mcap/core';

import { MalformedMcap, openMcap } from '../lib/player.mjs';
import { Recorder } from '../lib/recorder.mjs';

const args = process.argv.slice(2);
const dir = args[0];
const mutations = args.includes('--mutations') ? Number(args[args.indexOf('--mutations') + 1]) : 300;
if (!dir) {
  console.log('usage: node malformed_check.mjs DIR [--mutations N]');
  process.exit(2);
}
const tool = path.join(path.dirname(fileURLToPath(import.meta.url)), '..', 'rack-foxglove.mjs');
let failed = false;
const ok = (s) => console.log(`ok ${s}`);
const fail = (s) => { console.log(`FAILED ${s}`); failed = true; };

// ---- a good recording: 300 samples of a component channel and its Foxglove view, in
// chunks of 4 KiB (before compression)
const good = path.join(dir, 'good.mcap');
const schema = { title: 'rack.Ladar', type: 'object', properties: { data: { type: 'object', properties: {} } } };
const rec = await Recorder.open({ path: good, compression: 'zstd', topics: null, source: 'malformed_check', chunkSize: 4096 });
const t0 = 1795652163000000000n;
for (let i = 0; i < 300; ++i) {
  const time = t0 + BigInt(i) * 40000000n;
  rec.add({ topic: '/rack/0/ladar', schemaName: 'rack.Ladar', schema, time,
            message: { component: 'Ladar(0/0)', time_ns: time, sequence: i, data: { beam_count: 3, range: [1, 2, i / 100] } } });
  rec.add({ topic: '/rack/0/ladar/scan', schemaName: 'foxglove.LaserScan', schema: { title: 'foxglove.LaserScan', type: 'object' }, time,
            message: { timestamp: { sec: 1, nsec: i }, frame_id: 'ladar', ranges: [1, 2, 3] } });
}
await rec.close();
const bytes = new Uint8Array(fs.readFileSync(good));
const whole = await openMcap(good);
const chunks = [...whole.chunkIndexes].sort((a, b) => (a.chunkStartOffset < b.chunkStartOffset ? -1 : 1));
if (whole.truncated || chunks.length < 3) fail(`the good file: ${chunks.length} chunks, ${whole.truncated || 'whole'}`);
else ok(`the good file: ${bytes.length} bytes, ${chunks.length} chunks`);

// rack-foxglove play on a file, against a rack-gui that is not there.
function play(file) {
  const started = Date.now();
  const r = spawnSync(process.execPath, [tool, 'play', file, '--gui', 'ws://127.0.0.1:9/ws', '--wait', '1'],
                      { encoding: 'utf8', timeout: 30000 });
  return { status: r.status, signal: r.signal, err: r.stderr ?? '', ms: Date.now() - started };
}

function expectRefused(name, data, wanted) {
  const file = path.join(dir, `${name}.mcap`);
  fs.writeFileSync(file, data);
  const r = play(file);
  const said = r.err.trim().split('\n').filter((l) => l.includes('refused') || l.includes('not played')).join(' | ');
  const missing = wanted.filter((w) => !r.err.includes(w));
  if (r.signal) fail(`${name}: killed by ${r.signal} after ${r.ms} ms (a hang?)\n${r.err}`);
  else if (r.status !== 2) fail(`${name}: exit status ${r.status}, expected 2\n${r.err}`);
  else if (/\n\s+at /.test(r.err) || r.err.includes('Uncaught')) fail(`${name}: a stack trace\n${r.err}`);
  else if (missing.length > 0) fail(`${name}: does not say ${JSON.stringify(missing)}: ${r.err}`);
  else ok(`${name} (${r.ms} ms): ${said}`);
}

const u64 = (data, at, value) => new DataView(data.buffer, data.byteOffset).setBigUint64(at, value, true);
const copy = () => new Uint8Array(bytes);

// The good file is accepted: the player goes on to rack-gui.
{
  const r = play(good);
  if (r.status === 1 && r.err.includes('cannot reach rack-gui')) ok(`the good file is accepted (then: ${r.err.trim().split('\n').at(-1)})`);
  else fail(`the good file: exit status ${r.status}\n${r.err}`);
}

{
  const d = copy();
  d[0] = 0x50;
  expectRefused('wrong-magic', d, ['not an MCAP file', 'byte 0 holds 50 4d 43 41']);
}
expectRefused('empty', new Uint8Array(0), ['empty file']);
expectRefused('cut-in-header', bytes.subarray(0, 20), ['no message', 'ends inside record 1 (at byte 8']);
{
  const at = Number(chunks[0].chunkStartOffset);
  expectRefused('cut-in-first-chunk', bytes.subarray(0, at + 40), ['no message', `(at byte ${at},`]);
}
{
  // The second chunk's compressed bytes changed: refused, although the first is whole.
  const c = chunks[1];
  const d = copy();
  const at = Number(c.chunkStartOffset + c.chunkLength) - 20;
  for (let k = 0; k < 8; ++k) d[at + k] ^= 0x5a;
  expectRefused('corrupt-chunk', d, [`in the chunk at byte ${c.chunkStartOffset}`]);
}
{
  // Chunk: opcode, length, message start and end times, uncompressed size and CRC, then
  // the compression's name (u32 length, text).
  const c = chunks[0];
  const at = Number(c.chunkStartOffset) + 1 + 8 + 8 + 8 + 8 + 4 + 4;
  const d = copy();
  d.set(new TextEncoder().encode('zzzz'), at);
  expectRefused('unknown-compression', d, [`in the chunk at byte ${c.chunkStartOffset}`, 'Unsupported compression zzzz']);
  const e = copy();
  u64(e, Number(c.chunkStartOffset) + 1 + 8 + 8 + 8, 1n << 40n);
  expectRefused('huge-chunk', e, [`in the chunk at byte ${c.chunkStartOffset}`, '1099511627776 bytes uncompressed']);
}
{
  const d = copy();
  u64(d, 9, 1n << 63n);  // the Header record's length (after the magic and its opcode)
  expectRefused('huge-record-length', d, ['in record 1 at byte 8', 'too large']);
}
{
  // A whole, valid MCAP file of a ROS 2 recording: nothing the player can play.
  const file = path.join(dir, 'ros2.mcap');
  const fd = fs.openSync(file, 'w');
  let pos = 0n;
  const w = new McapWriter({
    writable: { position: () => pos, write: async (b) => { fs.writeSync(fd, b); pos += BigInt(b.byteLength); } },
  });
  await w.start({ profile: 'ros2', library: 'malformed_check' });
  const schemaId = await w.registerSchema({ name: 'geometry_msgs/msg/Pose', encoding: 'ros2msg', data: new TextEncoder().encode('float64 x') });
  const channelId = await w.registerChannel({ topic: '/pose', schemaId, messageEncoding: 'cdr', metadata: new Map() });
  const bad = await w.registerSchema({ name: 'rack.Ladar', encoding: 'jsonschema', data: new TextEncoder().encode('{not json') });
  const badChannel = await w.registerChannel({ topic: '/rack/0/ladar', schemaId: bad, messageEncoding: 'json', metadata: new Map() });
  await w.addMessage({ channelId, sequence: 0, logTime: 1n, publishTime: 1n, data: new Uint8Array(8) });
  await w.addMessage({ channelId: badChannel, sequence: 0, logTime: 2n, publishTime: 2n, data: new TextEncoder().encode('{}') });
  await w.end();
  fs.closeSync(fd);
  expectRefused('unknown-schema', fs.readFileSync(file),
                ["channel 0 '/pose': schema 'geometry_msgs/msg/Pose' (encoding 'ros2msg') is not a RACK class's",
                 "'/rack/0/ladar': schema 'rack.Ladar' is not JSON", 'no channel to play']);
}

// ---- lz4 chunks: a corrupt one is refused with its chunk, and a good lz4 recording
// read after it in the same process is read whole (@foxglove/wasm-lz4 kept its failed
// context: every later lz4 chunk failed, the next file at its first chunk; codecs.mjs)
{
  const lz4File = path.join(dir, 'good-lz4.mcap');
  const r4 = await Recorder.open({ path: lz4File, compression: 'lz4', topics: null, source: 'malformed_check', chunkSize: 4096 });
  for (let i = 0; i < 100; ++i) {
    const time = t0 + BigInt(i) * 40000000n;
    r4.add({ topic: '/rack/0/ladar', schemaName: 'rack.Ladar', schema, time,
             message: { component: 'Ladar(0/0)', time_ns: time, sequence: i, data: { beam_count: 3, range: [1, 2, i / 100] } } });
  }
  await r4.close();
  const lz4Chunks = [...(await openMcap(lz4File)).chunkIndexes].sort((a, b) => (a.chunkStartOffset < b.chunkStartOffset ? -1 : 1));
  const c = lz4Chunks[1];
  const d = new Uint8Array(fs.readFileSync(lz4File));
  const at = Number(c.chunkStartOffset + c.chunkLength) - 20;
  for (let k = 0; k < 8; ++k) d[at + k] ^= 0x5a;
  const bad = path.join(dir, 'corrupt-lz4.mcap');
  fs.writeFileSync(bad, d);
  let why = 'read without an error';
  try {
    await openMcap(bad);
  } catch (e) {
    why = e.message;
  }
  if (why.includes(`in the chunk at byte ${c.chunkStartOffset}`)) ok(`corrupt-lz4 (in-process): ${why}`);
  else fail(`corrupt-lz4: does not name the chunk at byte ${c.chunkStartOffset}: ${why}`);
  try {
    const again = await openMcap(lz4File);
    let n = 0;
    for await (const m of again.readMessages()) if (m) n += 1;
    if (n === 100 && !again.truncated) ok('the good lz4 recording read after the corrupt one: 100 of 100 messages');
    else fail(`the good lz4 recording after the corrupt one: ${n} messages, ${again.truncated || 'whole'}`);
  } catch (e) {
    fail(`the good lz4 recording after the corrupt one is refused: ${e.message}`);
  }
}

// ---- seeded random mutations through the reader, in-process
let seed = 24;
const random = () => {
  seed = (seed * 1103515245 + 12345) % 2147483648;
  return seed / 2147483648;
};
const counts = { read: 0, refused: 0 };
const reasons = new Map();
for (let k = 0; k < mutations; ++k) {
  const d = copy();
  const kind = k % 3;
  let what;
  if (kind === 0) {
    const n = 1 + Math.floor(random() * 4);
    const at = [];
    for (let j = 0; j < n; ++j) {
      const p = Math.floor(random() * d.length);
      d[p] ^= 1 + Math.floor(random() * 255);
      at.push(p);
    }
    what = `bytes ${at.join(', ')} changed`;
  } else if (kind === 1) {
    const p = 8 + Math.floor(random() * (d.length - 8));
    what = `cut at byte ${p}`;
  } else {
    const p = Math.floor(random() * (d.length - 8));
    d.fill(0xff, p, p + 8);
    what = `bytes ${p}..${p + 7} set to ff`;
  }
  const file = path.join(dir, 'mutated.mcap');
  fs.writeFileSync(file, kind === 1 ? d.subarray(0, Number(what.split(' ').at(-1))) : d);
  const started = Date.now();
  try {
    const r = await openMcap(file);
    for await (const m of r.readMessages()) new TextDecoder().decode(m.data);
    counts.read += 1;
  } catch (e) {
    if (!(e instanceof MalformedMcap)) {
      fail(`mutation ${k} (${what}): ${e.constructor.name}: ${e.message}`);
      continue;
    }
    counts.refused += 1;
    const reason = e.message.replace(/\d+/g, 'N').slice(0, 90);
    reasons.set(reason, (reasons.get(reason) ?? 0) + 1);
  }
  if (Date.now() - started > 5000) fail(`mutation ${k} (${what}): ${Date.now() - started} ms`);
}
ok(`${mutations} mutations: ${counts.read} read (the change fell in an index, the summary section or a metadata value, or the cut after whole chunks: played from the data section), ${counts.refused} refused with where and why`);
for (const [reason, n] of [...reasons].sort((a, b) => b[1] - a[1]).slice(0, 8)) console.log(`   ${n} x ${reason}`);
console.log(failed ? 'FAILED' : 'all checks passed');
process.exit(failed ? 1 : 0);
