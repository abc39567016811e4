// The recorder on its own (lib/recorder.mjs; driven by tests/integration/
// foxglove_test.cpp), read back with the npm MCAP reader (@mcap/core):
//   - each message is logged at its sample's time to the nanosecond, a time past 2^53
//     (ns since the epoch) included, and the message's time_ns keeps every digit;
//   - a gap in a stream's sequence numbers is counted as samples lost on the way, a
//     sequence that starts again (the producer switched off and on) as a restart, not a
//     loss, and both are in the file (Metadata "rack.recorder") and in lostReport();
//   - past kMaxPending messages waiting to be written, the recorder drops and counts.
//
// usage: node recorder_check.mjs DIR
import fs from 'node:fs';
import path from 'node:path';

import { McapIndexedReader } from '@mcap/core';

import { decompressHandlers as codecs } from '../lib/codecs.mjs';
import { parseExact } from '../lib/exact_json.mjs';
import { Recorder, kMaxPending } from '../lib/recorder.mjs';

const dir = process.argv[2];
if (!dir) {
  console.log('usage: node recorder_check.mjs DIR');
  process.exit(2);
}
let failed = false;
const ok = (s) => console.log(`ok ${s}`);
const fail = (s) => { console.log(`FAILED ${s}`); failed = true; };

const schema = { title: 'rack.Generator', type: 'object', properties: { data: { type: 'object', properties: {} } } };
const topic = '/rack/0/generator';
const t0 = 1795652163482672641n;  // odd: a number would round it to ...640
const file = path.join(dir, 'counted.mcap');
const r = await Recorder.open({ path: file, compression: 'zstd', topics: null, source: 'recorder_check' });
// Sequences 0..99, 103..149 (100, 101, 102 lost), then 0..9 again (a restart).
const sequences = [...Array(100).keys(), ...Array.from({ length: 47 }, (_, i) => 103 + i), ...Array(10).keys()];
sequences.forEach((sequence, i) => {
  const time = t0 + BigInt(i) * 10000001n;
  r.add({ topic, schemaName: 'rack.Generator', schema, time,
          message: { component: 'Generator(0/0)', time_ns: time, sequence, data: { value: i / 8, counter: BigInt(2) ** 60n + BigInt(i) } } });
  r.sample(topic, sequence);
});
await r.close();
const report = r.lostReport();
if (r.lost() === 3 && report.length === 1 && report[0].includes('3 sample(s) lost')) ok(`lostReport: ${report[0]}`);
else fail(`lost ${r.lost()}, report ${JSON.stringify(report)}`);

const bytes = new Uint8Array(fs.readFileSync(file));
const reader = await McapIndexedReader.Initialize({
  readable: { size: async () => BigInt(bytes.length), read: async (o, n) => bytes.subarray(Number(o), Number(o + n)) },
  decompressHandlers: await codecs(),
});
let i = 0;
let exact = 0;
for await (const m of reader.readMessages()) {
  const want = t0 + BigInt(i) * 10000001n;
  const text = new TextDecoder().decode(m.data);
  const rec = parseExact(text);
  if (m.logTime === want && m.publishTime === want && rec.time_ns === want && text.includes(`"time_ns":${want},`) &&
      rec.data.counter === 2n ** 60n + BigInt(i)) {
    exact += 1;
  } else if (exact === i) {
    fail(`message ${i}: log time ${m.logTime}, publish time ${m.publishTime}, text ${text.slice(0, 120)}; expected ${want}`);
  }
  i += 1;
}
if (i === sequences.length && exact === i) ok(`${exact} messages logged at their sample's time to the ns (from ${t0}), large integers kept`);
else fail(`${exact} of ${i} messages exact, ${sequences.length} written`);

let counts = null;
for await (const md of reader.readMetadata({ name: 'rack.recorder' })) counts = md.metadata;
const line = counts?.get(topic) ?? '';
if (line === 'recorded 157, lost 3, sequence 0..9, restarts 1' && counts.get('dropped_by_recorder') === '0' &&
    BigInt(counts.get('stopped_ns')) >= BigInt(counts.get('started_ns'))) {
  ok(`Metadata rack.recorder: ${topic}: ${line}; dropped_by_recorder 0`);
} else {
  fail(`Metadata rack.recorder: ${counts ? JSON.stringify([...counts]) : 'none'}`);
}

// A writer that cannot keep up: past kMaxPending queued messages, new ones are dropped
// and counted (added all at once, before any write has run).
const slow = await Recorder.open({ path: path.join(dir, 'dropped.mcap'), compression: 'none', topics: null });
const extra = 25;
for (let k = 0; k < kMaxPending + extra; ++k) {
  const time = t0 + BigInt(k);
  slow.add({ topic, schemaName: 'rack.Generator', schema, time, message: { component: 'Generator(0/0)', time_ns: time, sequence: k, data: {} } });
}
await slow.close();
if (slow.dropped === extra && slow.messages === kMaxPending && slow.lostReport().some((l) => l.includes(`${extra} message(s) dropped`))) {
  ok(`${slow.messages} written, ${slow.dropped} dropped past ${kMaxPending} waiting, and said`);
} else {
  fail(`dropped ${slow.dropped}, written ${slow.messages}, report ${JSON.stringify(slow.lostReport())}`);
}
console.log(failed ? 'FAILED' : 'all checks passed');
process.exit(failed ? 1 : 0);
