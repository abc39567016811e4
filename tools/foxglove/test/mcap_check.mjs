// Reads an MCAP file of rack-foxglove's recorder with the npm MCAP reader (@mcap/core)
// and checks every record (driven by tests/integration/foxglove_test.cpp):
//   - record by record (McapStreamReader, CRCs validated): header, schemas (jsonschema),
//     channels (json), chunks (all with the expected compression), messages (each JSON
//     that matches its channel's schema), message indexes, metadata, the summary
//     section (schemas, channels, statistics, chunk indexes, summary offsets), footer;
//   - through the index (McapIndexedReader): the statistics count what the stream
//     holds, per channel, and the indexed messages are the streamed ones;
//   - every component channel's message is logged at its sample's own time: log time
//     = publish time = the message's time_ns, to the nanosecond (the text's digits);
//   - --every-sample T=HZ: the component channel T holds every sample its producer
//     published while it was recorded: the samples' own sequence numbers (each
//     message's "sequence") run without a gap, their count is the producer's rate HZ
//     times the time between the first and the last sample, plus one, within two
//     samples (or 1 %, whichever is more: the producer's own overruns on a loaded
//     machine), they cover most of the recording, and the recorder's own count in the
//     file (Metadata "rack.recorder") says it lost none and dropped none;
//   - --same-times A=B: every log time of channel A (within B's) is one of B's (Scan2D's
//     scans carry the ladar's scan times);
//   - --scan-times A=B: every data.scan_time_ns of channel A (MCL: the scan each estimate
//     is for, a field its producer wrote) within B's log times is one of them, to the
//     nanosecond: the log times are the producers' times, not when the samples came.
//
// usage: node mcap_check.mjs FILE [--compression zstd|lz4|none] [--topic T]... [--min-messages N]
//          [--every-sample T=HZ]... [--same-times A=B]... [--scan-times A=B]...
// Prints one line per check; exit status 0 when all passed.
import fs from 'node:fs';
import { McapIndexedReader, McapStreamReader } from '@mcap/core';
import { decompressHandlers as codecs } from '../lib/codecs.mjs';
import { parseExact } from '../lib/exact_json.mjs';

import { matchesSchema } from './schema_check.mjs';

const args = process.argv.slice(2);
const file = args[0];
let compression = 'zstd';
let minMessages = 1;
const topics = [];
const everySample = new Map();  // topic -> producer rate (Hz)
const sameTimes = [];  // [A, B]
const scanTimes = [];  // [A, B]
for (let i = 1; i < args.length; i += 2) {
  if (args[i] === '--compression') compression = args[i + 1] === 'none' ? '' : args[i + 1];
  else if (args[i] === '--topic') topics.push(args[i + 1]);
  else if (args[i] === '--every-sample') {
    const [t, hz] = args[i + 1].split('=');
    everySample.set(t, Number(hz));
  }
  else if (args[i] === '--min-messages') minMessages = Number(args[i + 1]);
  else if (args[i] === '--same-times') sameTimes.push(args[i + 1].split('='));
  else if (args[i] === '--scan-times') scanTimes.push(args[i + 1].split('='));
  else {
    console.log(`unknown argument ${args[i]}`);
    process.exit(2);
  }
}
if (!file) {
  console.log('usage: node mcap_check.mjs FILE [--compression zstd|lz4|none] [--topic T]... [--min-messages N] [--every-sample T=HZ]... [--same-times A=B]... [--scan-times A=B]...');
  process.exit(2);
}

let failed = false;
const ok = (s) => console.log(`ok ${s}`);
const fail = (s) => { console.log(`FAILED ${s}`); failed = true; };

// The chunks decompressed with the codecs @mcap/support gives the MCAP readers
// (@foxglove/wasm-zstd, @foxglove/wasm-lz4).
const decompressHandlers = await codecs();
const bytes = new Uint8Array(fs.readFileSync(file));

// ---- every record, in file order
const stream = new McapStreamReader({ includeChunks: true, decompressHandlers, validateCrcs: true });
stream.append(bytes);
const counts = {};
const schemas = new Map();
const channels = new Map();
const perChannel = new Map();
const streamed = [];
const samples = new Map();  // topic (--every-sample) -> [{sequence, time_ns}]
const logTimes = new Map();  // component topic -> [logTime]
const scanTimesOf = new Map();  // component topic -> [data.scan_time_ns]
const recorderCounts = new Map();  // Metadata "rack.recorder"
let timeMismatches = 0;
let timeExample = '';
let componentMessages = 0;
let inSummary = false;
let record;
try {
  while ((record = stream.nextRecord())) {
    counts[record.type] = (counts[record.type] ?? 0) + 1;
    switch (record.type) {
      case 'Header':
        if (!record.library.startsWith('rack-foxglove')) fail(`header library '${record.library}'`);
        break;
      case 'Schema':
        if (record.encoding !== 'jsonschema') fail(`schema ${record.name}: encoding ${record.encoding}`);
        try {
          const s = JSON.parse(new TextDecoder().decode(record.data));
          if (s.title !== record.name) fail(`schema ${record.name}: title ${s.title}`);
          if (!inSummary) schemas.set(record.id, s);
        } catch (e) {
          fail(`schema ${record.name}: not JSON: ${e.message}`);
        }
        break;
      case 'Channel':
        if (record.messageEncoding !== 'json') fail(`channel ${record.topic}: encoding ${record.messageEncoding}`);
        if (!inSummary) channels.set(record.id, record);
        break;
      case 'Chunk':
        if (record.compression !== compression) fail(`chunk at ${record.messageStartTime}: compression '${record.compression}', expected '${compression}'`);
        break;
      case 'Message': {
        const c = channels.get(record.channelId);
        if (!c) {
          fail(`message on channel ${record.channelId} before its Channel record`);
          break;
        }
        perChannel.set(c.id, (perChannel.get(c.id) ?? 0) + 1);
        streamed.push(`${record.channelId}/${record.sequence}/${record.logTime}`);
        let m;
        let exact;
        try {
          const text = new TextDecoder().decode(record.data);
          m = JSON.parse(text);
          exact = parseExact(text);  // its integers to the last digit
        } catch (e) {
          fail(`${c.topic} #${record.sequence}: not JSON: ${e.message}`);
          break;
        }
        const problem = matchesSchema(m, schemas.get(c.schemaId), `${c.topic} #${record.sequence}`);
        if (problem) fail(problem);
        // A component channel (rack.<Class>): logged at its sample's own time.
        if (schemas.get(c.schemaId)?.title?.startsWith('rack.')) {
          componentMessages += 1;
          const t = BigInt(exact.time_ns);
          if (t !== record.logTime || record.publishTime !== record.logTime) {
            timeMismatches += 1;
            if (!timeExample) timeExample = `${c.topic} #${record.sequence}: time_ns ${t}, log time ${record.logTime}, publish time ${record.publishTime}`;
          }
          if (!logTimes.has(c.topic)) logTimes.set(c.topic, []);
          logTimes.get(c.topic).push(record.logTime);
          const st = exact.data?.scan_time_ns;
          if (st !== undefined && st !== 0) {
            if (!scanTimesOf.has(c.topic)) scanTimesOf.set(c.topic, []);
            scanTimesOf.get(c.topic).push(BigInt(st));
          }
        }
        if (everySample.has(c.topic)) {
          if (!samples.has(c.topic)) samples.set(c.topic, []);
          samples.get(c.topic).push({ sequence: m.sequence, time_ns: BigInt(exact.time_ns) });
        }
        if (record.logTime <= 0n) fail(`${c.topic} #${record.sequence}: log time ${record.logTime}`);
        break;
      }
      case 'DataEnd':
        inSummary = true;
        break;
      case 'Metadata':
        if (record.name === 'rack.recorder') for (const [k, v] of record.metadata) recorderCounts.set(k, v);
        break;
      default:
        break;
    }
  }
} catch (e) {
  fail(`reading record by record: ${e.message}`);
}
if (!stream.done()) fail(`the stream reader did not reach the end (${stream.bytesRemaining()} bytes left)`);
ok(`records: ${Object.entries(counts).map(([k, v]) => `${k} ${v}`).join(', ')}`);
for (const t of ['Header', 'Schema', 'Channel', 'Chunk', 'Message', 'MessageIndex', 'ChunkIndex', 'Statistics',
                 'SummaryOffset', 'DataEnd', 'Footer', 'Metadata']) {
  if (!counts[t]) fail(`no ${t} record`);
}

// ---- the summary and the index
const readable = { size: async () => BigInt(bytes.length), read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)) };
try {
  const r = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  const st = r.statistics;
  const total = streamed.length;
  if (!st) {
    fail('no statistics in the summary');
  } else {
    if (st.messageCount !== BigInt(total)) fail(`statistics: ${st.messageCount} messages, the file holds ${total}`);
    if (st.channelCount !== channels.size) fail(`statistics: ${st.channelCount} channels, the file holds ${channels.size}`);
    if (st.chunkCount !== counts.Chunk) fail(`statistics: ${st.chunkCount} chunks, the file holds ${counts.Chunk}`);
    for (const [id, n] of perChannel) {
      if (st.channelMessageCounts.get(id) !== BigInt(n)) fail(`statistics: channel ${id}: ${st.channelMessageCounts.get(id)}, the file holds ${n}`);
    }
    ok(`statistics: ${st.messageCount} messages, ${st.channelCount} channels, ${st.schemaCount} schemas, ${st.chunkCount} chunks`);
  }
  if (r.chunkIndexes.length !== counts.Chunk) fail(`${r.chunkIndexes.length} chunk indexes for ${counts.Chunk} chunks`);
  if (r.chunkIndexes.some((c) => c.compression !== compression)) fail('a chunk index names another compression');
  if (r.channelsById.size !== channels.size || r.schemasById.size !== schemas.size) fail('summary channels or schemas differ from the data section');
  const indexed = [];
  for await (const m of r.readMessages()) indexed.push(`${m.channelId}/${m.sequence}/${m.logTime}`);
  if (indexed.length !== total || [...indexed].sort().join() !== [...streamed].sort().join()) {
    fail(`indexed reading gave ${indexed.length} messages, the stream ${total}`);
  } else {
    ok(`indexed reading: the same ${total} messages, in log-time order`);
  }
  if (total < minMessages) fail(`${total} messages, expected at least ${minMessages}`);
  const byTopic = new Map([...channels.values()].map((c) => [c.topic, c]));
  for (const t of topics) {
    const c = byTopic.get(t);
    if (!c || !perChannel.get(c.id)) fail(`no message on ${t}`);
  }
  for (const [t, hz] of everySample) {
    const list = (samples.get(t) ?? []).sort((a, b) => a.sequence - b.sequence);
    if (list.length < 2) {
      fail(`--every-sample ${t}: ${list.length} samples`);
      continue;
    }
    const gaps = [];
    for (let i = 1; i < list.length; ++i) {
      if (list[i].sequence !== list[i - 1].sequence + 1) gaps.push(`${list[i - 1].sequence}..${list[i].sequence}`);
    }
    const seconds = Number(list.at(-1).time_ns - list[0].time_ns) / 1e9;
    const expected = seconds * hz + 1;
    const tolerance = Math.max(2, 0.01 * expected);
    const line = `${t}: ${list.length} samples, sequence ${list[0].sequence}..${list.at(-1).sequence}, ` +
                 `${seconds.toFixed(2)} s at ${hz} Hz: ${expected.toFixed(1)} expected`;
    // How much of the recording they cover (the recorder's start and stop, in its
    // Metadata): the stream flows from rack-gui's subscription on, a moment after the start.
    const started = Number(recorderCounts.get('started_ns') ?? 0);
    const stopped = Number(recorderCounts.get('stopped_ns') ?? 0);
    const span = stopped > started ? (stopped - started) / 1e9 : 0;
    const cover = span > 0 ? `; the recording ran ${span.toFixed(2)} s` : '';
    const counted = recorderCounts.get(t) ?? '';
    if (gaps.length > 0) fail(`${line}; ${gaps.length} gap(s): ${gaps.slice(0, 5).join(', ')}`);
    else if (Math.abs(list.length - expected) > tolerance) fail(`${line}: the count is off by more than ${tolerance.toFixed(1)} (overruns?)`);
    else if (span > 0 && seconds < 0.5 * span) fail(`${line}${cover}: the samples cover less than half of it`);
    else if (!/^recorded \d+, lost 0,/.test(counted)) fail(`${line}: the recorder's count in the file says '${counted}'`);
    else ok(`every sample: ${line}${cover}; the recorder's count: ${counted}`);
  }
  if (everySample.size > 0) {
    if (recorderCounts.get('dropped_by_recorder') !== '0') fail(`the recorder dropped ${recorderCounts.get('dropped_by_recorder')} message(s)`);
    else ok('the recorder dropped no message');
  }
  if (timeMismatches > 0) fail(`${timeMismatches} of ${componentMessages} component messages not logged at their sample's time, e.g. ${timeExample}`);
  else ok(`every one of the ${componentMessages} component messages is logged at its sample's time_ns, to the ns`);
  const inRange = (list, t) => list.length > 0 && t >= list[0] && t <= list.at(-1);
  for (const [a, b] of sameTimes) {
    const of = new Set(logTimes.get(b) ?? []);
    const bs = [...of].sort((x, y) => (x < y ? -1 : x > y ? 1 : 0));
    const within = (logTimes.get(a) ?? []).filter((t) => inRange(bs, t));
    const missing = within.filter((t) => !of.has(t));
    if (within.length < 5 || missing.length > 0) fail(`--same-times ${a}=${b}: ${within.length} log times within ${b}'s, ${missing.length} not among them (e.g. ${missing[0]})`);
    else ok(`every one of ${within.length} log times of ${a} is a log time of ${b}`);
  }
  for (const [a, b] of scanTimes) {
    const of = new Set(logTimes.get(b) ?? []);
    const bs = [...of].sort((x, y) => (x < y ? -1 : x > y ? 1 : 0));
    const within = [...new Set(scanTimesOf.get(a) ?? [])].filter((t) => inRange(bs, t));
    const missing = within.filter((t) => !of.has(t));
    if (within.length < 5 || missing.length > 0) {
      fail(`--scan-times ${a}=${b}: ${within.length} scan times within ${b}'s log times, ${missing.length} not among them (e.g. ${missing[0]})`);
    } else {
      ok(`each of the ${within.length} scans ${a} used (its data.scan_time_ns) is a sample of ${b} logged at that time, to the ns`);
    }
  }
  for (const c of [...channels.values()].sort((a, b) => a.topic.localeCompare(b.topic))) {
    console.log(`   ${c.topic} ${r.schemasById.get(c.schemaId)?.name} ${perChannel.get(c.id) ?? 0} messages`);
  }
} catch (e) {
  fail(`indexed reader: ${e.message}`);
}
console.log(failed ? 'FAILED' : 'all checks passed');
process.exit(failed ? 1 : 0);
