// The MCAP player (rack-foxglove play): reads a recording with @mcap/core's indexed
// reader and sends each recorded sample of the chosen component channels to the
// component of the same name in a running host, as the PUBLISH command of a playback
// class (components/playback: ChassisPlayback stands in for ChassisSim, MclPlayback for
// MCL, ...), through rack-gui's "command_json" op, at the recorded speed (--speed 1),
// faster (--speed N) or as fast as the host acknowledges (--speed 0), up to 16 samples
// on the way at once. Each sample keeps its recorded time (the message's log time, to
// the ns) and its fields (large integers exact: lib/exact_json.mjs).
//
// The file is outside input: openMcap reads and checks every record before anything
// is played, and a malformed file is refused (MalformedMcap) with what is wrong and
// where (byte offset, record); playableChannels names each channel it will not play.
// A recorded message that does not decode, or that the host refuses, is counted and
// reported (the first few with their reason), and playing goes on.
import fs from 'node:fs';
import { McapIndexedReader, McapStreamReader } from '@mcap/core';

import { decompressHandlers as codecs } from './codecs.mjs';
import { parseExact } from './exact_json.mjs';

// The bytes of a recording: a regular file of at most 2 GiB (what a Buffer holds),
// opened without waiting (readFileSync waited for ever on a FIFO with no writer and
// read /dev/zero until memory ran out). Throws "a FIFO, not a regular file" and the like.
const kMaxRecordingBytes = 2 ** 31 - 1;
function readRecording(path) {
  const fd = fs.openSync(path, fs.constants.O_RDONLY | fs.constants.O_NONBLOCK);
  try {
    const st = fs.fstatSync(fd);
    if (!st.isFile()) {
      const kind = st.isFIFO() ? 'a FIFO' : st.isDirectory() ? 'a directory' : st.isCharacterDevice()
        ? 'a character device' : st.isBlockDevice() ? 'a block device' : st.isSocket() ? 'a socket' : 'not a file';
      throw new Error(`${kind}, not a regular file`);
    }
    if (st.size > kMaxRecordingBytes) throw new Error(`${st.size} bytes, more than the limit of ${kMaxRecordingBytes}`);
    return new Uint8Array(fs.readFileSync(fd));
  } finally {
    fs.closeSync(fd);
  }
}

// Kept out: a chunk that says it holds more than this uncompressed (the recorder writes
// chunks of 1 MiB before compression); a corrupt size would otherwise be allocated.
export const kMaxChunkBytes = 256 * 1024 * 1024;

// A file the player refuses: what is wrong and where (byte offset, record).
export class MalformedMcap extends Error {}

const kMagic = [0x89, 0x4d, 0x43, 0x41, 0x50, 0x30, 0x0d, 0x0a];  // "\x89MCAP0\r\n"
const hex = (bytes) => Array.from(bytes, (b) => b.toString(16).padStart(2, '0')).join(' ');

// The chunk codecs with the size guard above.
async function guardedCodecs() {
  const handlers = await codecs();
  const guarded = {};
  for (const [name, f] of Object.entries(handlers)) {
    guarded[name] = (data, size) => {
      if (size > BigInt(kMaxChunkBytes)) {
        throw new Error(`the chunk says it holds ${size} bytes uncompressed, more than the ${kMaxChunkBytes} this player takes`);
      }
      return f(data, size);
    };
  }
  return guarded;
}

// Reads every record of the file in order with @mcap/core's stream reader (CRCs
// checked, every chunk decompressed) and throws MalformedMcap at the first fault, with
// its byte offset: the record's, or the chunk's for a fault inside a chunk (the stream
// reader hands out a chunk's records after the chunk: a fault that leaves the reader's
// position where it was lies in the chunk, one that moved it in the next record). An
// end inside a record (a recorder killed before its summary) is not a fault: `truncated`
// says where the file stops. keepMessages: the Message records, for a file without a
// usable index.
function scanMcap(bytes, decompressHandlers, keepMessages) {
  const total = bytes.length;
  if (total === 0) throw new MalformedMcap('an empty file (0 bytes), not an MCAP recording');
  const head = bytes.subarray(0, kMagic.length);
  if (head.length < kMagic.length || !kMagic.every((b, i) => head[i] === b)) {
    throw new MalformedMcap(`not an MCAP file: byte 0 holds ${hex(head)}, an MCAP file starts with its magic ${hex(kMagic)}`);
  }
  const stream = new McapStreamReader({ includeChunks: true, decompressHandlers, validateCrcs: true });
  stream.append(bytes);
  const out = { schemasById: new Map(), channelsById: new Map(), messages: [], messageCount: 0, records: 0,
                chunkOffsets: new Set(), footer: false, truncated: '' };
  let chunk = null;  // the chunk whose records are being read: {at, record, inner}
  for (;;) {
    const before = stream.bytesRemaining();
    let r;
    try {
      r = stream.nextRecord();
    } catch (e) {
      const where = stream.bytesRemaining() === before && chunk
        ? `in the chunk at byte ${chunk.at} (record ${chunk.record} of the file, after ${chunk.inner} of its records)`
        : `in record ${out.records + 1} at byte ${before === total ? kMagic.length : total - before}`;
      throw new MalformedMcap(`${where}: ${e.message}`);
    }
    if (r === undefined) break;
    if (stream.bytesRemaining() !== before || chunk === null) {  // a record of the file itself
      out.records += 1;
      chunk = null;
      if (r.type === 'Chunk') {
        chunk = { at: total - before, record: out.records, inner: 0 };
        out.chunkOffsets.add(BigInt(total - before));
      }
    } else {
      chunk.inner += 1;
    }
    if (r.type === 'Schema') out.schemasById.set(r.id, r);
    else if (r.type === 'Channel') out.channelsById.set(r.id, r);
    else if (r.type === 'Message') {
      out.messageCount += 1;
      if (keepMessages) out.messages.push(r);
    } else if (r.type === 'Footer') out.footer = true;
  }
  if (!stream.done()) {
    const left = stream.bytesRemaining();
    out.truncated = left > 0
      ? `the file ends inside record ${out.records + 1} (at byte ${total - left}, ${left} bytes of it), without its summary section`
      : `the file ends after record ${out.records} (byte ${total}) without its summary section and footer`;
  }
  return out;
}

// A recording's reader ({channelsById, schemasById, readMessages, truncated}), or
// MalformedMcap. Every record is read and checked first (scanMcap); then @mcap/core's
// indexed reader serves a whole file, and a file without a usable summary section (a
// recorder that was killed: rack-foxglove writes the summary when it stops) is read
// record by record as far as it is whole (`truncated` then says why).
export async function openMcap(path) {
  let bytes;
  try {
    bytes = readRecording(path);
  } catch (e) {
    throw new MalformedMcap(`cannot read it: ${e.message}`);
  }
  const decompressHandlers = await guardedCodecs();
  const scan = scanMcap(bytes, decompressHandlers, false);
  if (scan.messageCount === 0) {
    throw new MalformedMcap(`no message in its ${scan.records} record(s)${scan.truncated ? `: ${scan.truncated}` : ''}`);
  }
  let why = scan.truncated;
  if (scan.footer) {
    const readable = {
      size: async () => BigInt(bytes.length),
      read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
    };
    try {
      const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
      const bad = reader.chunkIndexes.find((c) => !scan.chunkOffsets.has(c.chunkStartOffset));
      if (bad) throw new Error(`it indexes a chunk at byte ${bad.chunkStartOffset}, where the file has none`);
      // The indexes lead to every message the data section holds (a message index that
      // points amiss inside a chunk shows only when read): read through them once.
      let n = 0;
      for await (const m of reader.readMessages()) if (m) n += 1;
      if (n !== scan.messageCount) throw new Error(`its indexes lead to ${n} messages, the data section holds ${scan.messageCount}`);
      const indexed = reader.readMessages.bind(reader);
      reader.readMessages = async function* readMessages(args) {
        try {
          yield* indexed(args);
        } catch (e) {  // (read once already: not expected)
          throw new MalformedMcap(`reading its messages through the summary's indexes: ${e.message}`);
        }
      };
      return reader;
    } catch (e) {
      why = `its summary section is unusable (${e.message})`;
    }
  }
  return streamedReader(scanMcap(bytes, decompressHandlers, true), why);
}

function streamedReader(scan, why) {
  const { schemasById, channelsById, messages } = scan;
  messages.sort((a, b) => (a.logTime < b.logTime ? -1 : a.logTime > b.logTime ? 1 : 0));
  return {
    schemasById,
    channelsById,
    statistics: undefined,
    truncated: `${why}; read record by record (${messages.length} messages)`,
    async *readMessages({ topics } = {}) {
      const ids = topics ? new Set([...channelsById.values()].filter((c) => topics.includes(c.topic)).map((c) => c.id)) : null;
      for (const m of messages) if (!ids || ids.has(m.channelId)) yield m;
    },
  };
}

// The channels of a recording the player can play: a component channel of
// rack-foxglove's recorder, /rack/<system>/<name>, JSON with a JSON schema named
// rack.<Class> whose text is a JSON object. Returns {playable: Map(id -> {topic,
// system, name}), refused: ["channel N '<topic>': why"]} for the channels `topics`
// (RegExp|null) takes; the channels rack-foxglove derives from a component's for
// Foxglove (foxglove.* schemas: /scan, /pose, /tf, ...) and its GDOS log are left out
// silently: they are views of the component channels, not samples to play.
export function playableChannels(reader, topics) {
  const playable = new Map();
  const refused = [];
  for (const [id, c] of reader.channelsById) {
    if (topics && !topics.test(c.topic)) continue;
    const schema = reader.schemasById.get(c.schemaId);
    if (schema?.name.startsWith('foxglove.') && schema.encoding === 'jsonschema' && c.messageEncoding === 'json') continue;
    const m = /^\/rack\/(\d+)\/([^/]+)$/.exec(c.topic);
    const what = `channel ${id} '${c.topic}'`;
    let why = '';
    if (!schema) why = c.schemaId === 0 ? 'no schema' : `schema ${c.schemaId}, which the file does not hold`;
    else if (!schema.name.startsWith('rack.')) why = `schema '${schema.name}' (encoding '${schema.encoding}') is not a RACK class's`;
    else if (schema.encoding !== 'jsonschema') why = `schema '${schema.name}' has encoding '${schema.encoding}', expected jsonschema`;
    else if (c.messageEncoding !== 'json') why = `message encoding '${c.messageEncoding}', expected json`;
    else if (!m) why = `topic is not a component's (/rack/<system>/<name>)`;
    else {
      try {
        const s = JSON.parse(new TextDecoder().decode(schema.data));
        if (s === null || typeof s !== 'object' || typeof s.properties?.data !== 'object') why = `schema '${schema.name}' has no data property`;
      } catch (e) {
        why = `schema '${schema.name}' is not JSON: ${e.message}`;
      }
    }
    if (why) refused.push(`${what}: ${why}`);
    else playable.set(id, { topic: c.topic, system: Number(m[1]), name: m[2] });
  }
  return { playable, refused };
}

const sleep = (ms) => new Promise((r) => { setTimeout(r, ms); });

// options: {reader (openMcap's), speed, topics (RegExp|null), initMcl (component name|''), sigmaXy,
//           sigmaPhi, waitS}; link: a connected GuiLink; converter: its Converter.
export async function play(options, link, converter, log) {
  const { reader } = options;
  // The component channels: /rack/<system>/<name> with a rack.<Class> schema (the
  // caller has said which others are not played, and why).
  const channels = playableChannels(reader, options.topics).playable;  // channel id -> {topic, system, name}

  // The host's components of those names, whose class takes PUBLISH.
  const target = (ch) => {
    for (const comp of converter.components.values()) {
      if (comp.system !== ch.system || comp.name !== ch.name) continue;
      const cls = converter.classOf(comp.system, comp.class);
      return { comp, publish: cls?.commands.some((k) => k.name === 'PUBLISH') === true, known: cls !== undefined };
    }
    return null;
  };
  // A component listed before its class is described (rack-gui lists it as
  // Class0xNN(s/i) until then): rack-gui is asked for the class ("get_class", answered
  // when the description arrives), and its refusal is the reason shown.
  const asked = new Map();  // address -> {at: Date.now(), why: rack-gui's refusal ('' while asked or described)}
  const describe = (comp) => {
    const a = asked.get(comp.address);
    if (a && (a.why === '' || Date.now() - a.at < 2000)) return a.why;
    asked.set(comp.address, { at: Date.now(), why: '' });
    link.request({ op: 'get_class', component: comp.address }).then((r) => {
      asked.set(comp.address, { at: Date.now(), why: r.ok ? '' : r.text });
    });
    return a?.why ?? '';
  };
  const reason = (t) => {
    if (!t) return 'no component of that name';
    if (!t.known) {
      const why = describe(t.comp);
      return `its class ${t.comp.class} is not described yet${why ? ` (rack-gui: ${why})` : ''}`;
    }
    if (!t.publish) return `${t.comp.class} takes no PUBLISH (not a playback class)`;
    return `state ${t.comp.state}`;
  };
  const waitStart = Date.now();
  const deadline = waitStart + options.waitS * 1000;
  let waitingSaid = false;
  let targets;
  for (;;) {
    targets = new Map();
    const notReady = [];  // "<topic>: <why>" of every channel without its component ready
    for (const [id, ch] of channels) {
      const t = target(ch);
      if (t && t.publish && t.comp.state === 'enabled') targets.set(id, t.comp);
      else notReady.push(`${ch.topic}: ${reason(t)}`);
    }
    // Without --topics, a channel whose component is not a playback class is left out.
    const pending = options.topics ? notReady : [];
    let mclWhy = '';
    if (options.initMcl) {
      const mcl = [...converter.components.values()].find((c) => c.name === options.initMcl);
      if (!mcl) mclWhy = 'no component of that name';
      else if (!converter.classOf(mcl.system, mcl.class)) mclWhy = reason({ comp: mcl, known: false });
      else if (mcl.state !== 'enabled') mclWhy = `state ${mcl.state}`;
    }
    if (targets.size > 0 && pending.length === 0 && !mclWhy) break;
    const why = [...(targets.size === 0 ? notReady : pending), ...(mclWhy ? [`--init-mcl ${options.initMcl}: ${mclWhy}`] : [])];
    if (Date.now() > deadline) {
      throw new Error(targets.size === 0
        ? `no recorded channel has a playback component of its name running in the host (${[...channels.values()].map((c) => c.topic).join(', ') || 'no component channels in the file'})${why.length ? `: ${why.join('; ')}` : ''}`
        : `not every channel's component is ready after ${options.waitS} s: ${why.join('; ')}`);
    }
    // Said once, when rack-gui's first lists have come and still lack something.
    if (!waitingSaid && Date.now() - waitStart >= 1000) {
      waitingSaid = true;
      log(`waiting up to ${options.waitS} s for the host's components: ${why.join('; ') || 'none listed yet'}`);
    }
    await sleep(200);
  }
  for (const [id, comp] of targets) log(`playing ${channels.get(id).topic} into ${comp.address} (${comp.impl})`);

  // First sample time, and the recorded MCL pose there (--init-mcl).
  const ids = [...targets.keys()];
  let first = null;
  for await (const m of reader.readMessages({ topics: ids.map((id) => channels.get(id).topic) })) {
    first = m.logTime;
    break;
  }
  if (first === null) throw new Error('the chosen channels hold no messages');
  if (options.initMcl) {
    const mcl = [...converter.components.values()].find((c) => c.name === options.initMcl);
    const topic = `/rack/${mcl.system}/${options.initMcl}`;
    let pose = null;
    for await (const m of reader.readMessages({ topics: [topic] })) {
      const d = parseExact(new TextDecoder().decode(m.data)).data;
      if (m.logTime > first && pose) break;
      pose = d;
    }
    if (!pose) throw new Error(`--init-mcl: the recording has no ${topic}`);
    const r = await link.request({ op: 'command_json', component: mcl.address, command: 'INIT',
                                   body: { x: pose.x, y: pose.y, phi: pose.phi, sigma_xy: options.sigmaXy, sigma_phi: options.sigmaPhi } });
    if (!r.ok) throw new Error(`--init-mcl: ${r.text}`);
    log(`${mcl.address} INIT at the recorded pose x ${pose.x.toFixed(3)} y ${pose.y.toFixed(3)} phi ${pose.phi.toFixed(3)}`);
  }

  const start = Date.now();
  const kInFlight = 16;
  const inFlight = [];
  let played = 0;
  let refused = 0;
  let unanswered = 0;  // no answer in time: the request or its reply lost on the way (TiMS over UDP)
  let last = first;
  for await (const m of reader.readMessages({ topics: ids.map((id) => channels.get(id).topic) })) {
    const comp = targets.get(m.channelId);
    last = m.logTime;
    if (options.speed > 0) {
      const due = start + Number(m.logTime - first) / 1e6 / options.speed;
      if (due > Date.now()) await sleep(due - Date.now());
    }
    // The sample as recorded, at its log time (the producer's time_ns, to the ns: the
    // request is written with stringifyExact); its fields as they were, large integers
    // included (parseExact).
    let body;
    try {
      const rec = parseExact(new TextDecoder().decode(m.data));
      if (rec === null || typeof rec !== 'object' || rec.data === null || typeof rec.data !== 'object' || Array.isArray(rec.data)) {
        throw new Error('not a recorded sample ({component, time_ns, sequence, data})');
      }
      body = { ...rec.data, time_ns: m.logTime };
    } catch (e) {
      refused += 1;
      if (refused <= 5) log(`${channels.get(m.channelId).topic} #${m.sequence} (log time ${m.logTime}): ${e.message} (skipped)`);
      continue;
    }
    // Up to kInFlight samples on the way at once: rack-gui sends them in order and each
    // playback component takes its own in order, so the round trips overlap (one at a
    // time, a loaded machine's 40 ms round trip paced 125 samples/s to 25).
    if (inFlight.length >= kInFlight) await inFlight.shift();
    const topic = channels.get(m.channelId).topic;
    const sequence = m.sequence;
    inFlight.push(link.request({ op: 'command_json', component: comp.address, command: 'PUBLISH', body }).then((r) => {
      if (r.ok) {
        played += 1;
      } else if (r.timeout === true || /no reply to PUBLISH in time/.test(r.text)) {
        unanswered += 1;
        if (unanswered <= 5) log(`${topic} #${sequence}: ${r.text}`);
      } else {
        refused += 1;
        if (refused <= 5) log(`${topic} #${sequence}: ${r.text}`);
      }
    }));
  }
  await Promise.all(inFlight);
  const seconds = (Date.now() - start) / 1000;
  const recorded = Number(last - first) / 1e9;
  log(`played ${played} samples in ${seconds.toFixed(1)} s (${recorded.toFixed(1)} s recorded; speed ${options.speed || '0: as fast as acknowledged'}); ` +
      `${refused} refused or skipped, ${unanswered} not answered (lost on the way?)`);
  return { played, refused, unanswered };
}
