// The MCAP player (rack-foxglove play): reads a recording with @mcap/core's indexed
// reader and sends each recorded sample of the chosen component channels to the
// component of the same name in a running host, as the PUBLISH command of a playback
// class (components/playback: Scan2dPlayback stands in for Scan2D), through rack-gui's
// "command" op, at the recorded speed (--speed 1), faster (--speed N) or as fast as
// the host acknowledges (--speed 0), up to 16 samples on the way at once. Each sample
// keeps its recorded time.
//
// A recorded message that does not decode, or that the host refuses, is counted and
// reported (the first few with their reason), and playing goes on.
import fs from 'node:fs';
import { McapIndexedReader, McapStreamReader, hasMcapPrefix } from '@mcap/core';
import { decompressHandlers as codecs } from './codecs.mjs';

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

// A recording's reader: @mcap/core's indexed reader, or, for a file without its summary
// section (a recorder that was killed: rack-foxglove writes the summary when it stops),
// every complete record read in order with the stream reader, as far as the file is
// whole (the reader's `truncated` then says where it ends).
export async function openMcap(path) {
  const bytes = readRecording(path);
  const decompressHandlers = await codecs();
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
  };
  try {
    return await McapIndexedReader.Initialize({ readable, decompressHandlers });
  } catch (indexed) {
    if (!hasMcapPrefix(new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength))) throw indexed;
    return streamedReader(bytes, decompressHandlers, indexed.message);
  }
}

function streamedReader(bytes, decompressHandlers, why) {
  const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  stream.append(bytes);
  const schemasById = new Map();
  const channelsById = new Map();
  const messages = [];
  let truncated = '';
  try {
    for (let r; (r = stream.nextRecord());) {
      if (r.type === 'Schema') schemasById.set(r.id, r);
      else if (r.type === 'Channel') channelsById.set(r.id, r);
      else if (r.type === 'Message') messages.push(r);
    }
    if (!stream.done()) truncated = `the last ${stream.bytesRemaining()} bytes are an incomplete record`;
  } catch (e) {
    truncated = e.message;
  }
  if (channelsById.size === 0) throw new Error(`${why}; and no channel could be read record by record`);
  messages.sort((a, b) => (a.logTime < b.logTime ? -1 : a.logTime > b.logTime ? 1 : 0));
  return {
    schemasById,
    channelsById,
    statistics: undefined,
    truncated: `no summary section (${bytes.length} bytes without a footer: the recorder did not stop cleanly?); ` +
               `read record by record${truncated ? `: ${truncated}` : ''}`,
    async *readMessages({ topics } = {}) {
      const ids = topics ? new Set([...channelsById.values()].filter((c) => topics.includes(c.topic)).map((c) => c.id)) : null;
      for (const m of messages) if (!ids || ids.has(m.channelId)) yield m;
    },
  };
}

const sleep = (ms) => new Promise((r) => { setTimeout(r, ms); });

// options: {reader (openMcap's), speed, topics (RegExp|null), initMcl (component name|''), sigmaXy,
//           sigmaPhi, waitS}; link: a connected GuiLink; converter: its Converter.
export async function play(options, link, converter, log) {
  const { reader } = options;
  // The component channels: /rack/<system>/<name> with a rack.<Class> schema.
  const channels = new Map();  // channel id -> {topic, system, name}
  for (const [id, c] of reader.channelsById) {
    const m = /^\/rack\/(\d+)\/([^/]+)$/.exec(c.topic);
    const schema = reader.schemasById.get(c.schemaId);
    if (!m || !schema?.name.startsWith('rack.')) continue;
    if (options.topics && !options.topics.test(c.topic)) continue;
    channels.set(id, { topic: c.topic, system: Number(m[1]), name: m[2] });
  }

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
      const d = JSON.parse(new TextDecoder().decode(m.data)).data;
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
  let last = first;
  for await (const m of reader.readMessages({ topics: ids.map((id) => channels.get(id).topic) })) {
    const comp = targets.get(m.channelId);
    last = m.logTime;
    if (options.speed > 0) {
      const due = start + Number(m.logTime - first) / 1e6 / options.speed;
      if (due > Date.now()) await sleep(due - Date.now());
    }
    let body;
    try {
      const rec = JSON.parse(new TextDecoder().decode(m.data));
      body = { time_ns: rec.time_ns, ...rec.data };
    } catch (e) {
      refused += 1;
      if (refused <= 5) log(`${channels.get(m.channelId).topic} #${m.sequence}: not JSON: ${e.message} (skipped)`);
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
      } else {
        refused += 1;
        if (refused <= 5) log(`${topic} #${sequence}: ${r.text}`);
      }
    }));
  }
  await Promise.all(inFlight);
  const seconds = (Date.now() - start) / 1000;
  const recorded = Number(last - first) / 1e9;
  log(`played ${played} samples in ${seconds.toFixed(1)} s (${recorded.toFixed(1)} s recorded; speed ${options.speed || '0: as fast as acknowledged'}); ${refused} refused or skipped`);
  return { played, refused };
}
