#!/usr/bin/env node
// rack-foxglove: RACK-RT in Foxglove. Connects to rack-gui's WebSocket (/ws, the
// dashboard's protocol: tools/gui/gui_protocol.h and backend.h), serves the Foxglove
// WebSocket protocol (@foxglove/ws-protocol) and/or records MCAP (@mcap/core). See
// --help and README.md ("Foxglove and MCAP").
import fs from 'node:fs';

import { WebSocket, WebSocketServer } from 'ws';
import wsProtocol from '@foxglove/ws-protocol';

import { Converter, kJsonEncoding, kSchemaEncoding, topicsOf, typeSchema } from './lib/convert.mjs';
import { parseExact, stringifyExact } from './lib/exact_json.mjs';
import { MalformedMcap, openMcap, play, playableChannels } from './lib/player.mjs';
import { Recorder } from './lib/recorder.mjs';

const { FoxgloveServer } = wsProtocol;

const kHelp = `usage: rack-foxglove --gui URL [options]
       rack-foxglove play FILE --gui URL [play options]

RACK-RT's robots in Foxglove, and recorded as MCAP. Takes everything from rack-gui
(start rack-gui on the robots' network first) over its WebSocket.

  --gui URL            rack-gui's WebSocket, e.g. ws://127.0.0.1:8080/ws (required)
  --port N             serve the Foxglove WebSocket protocol on port N (default 8765;
                       0: any free port). Foxglove: Open connection -> Foxglove WebSocket
                       -> ws://HOST:N
  --host ADDR          address to listen on (default 127.0.0.1; 0.0.0.0: every interface)
  --no-server          do not serve Foxglove (record only)
  --record FILE        record into the MCAP file FILE (chunked, with a summary section)
  --topics REGEX       record only the topics REGEX matches (default: all), e.g.
                       '^/rack/0/(ladar|mcl)|^/rack/gdos'
  --compression C      chunk compression: zstd (default), lz4 or none
  --period-ms P        stream period of the components recorded or subscribed to in
                       Foxglove (default 0: every sample the component publishes)
  --polled             no streams: only the samples rack-gui polls (5 Hz for navigation
                       classes, 1 Hz for the others)
  --duration S         stop after S seconds (default: run until SIGINT or SIGTERM)
  -h, --help           this text
  --version            rack-foxglove's version and its protocol and MCAP libraries'

Channels (JSON encoding, JSON schemas):
  /rack/<system>/<name>            every component's data; schema rack.<Class> from its
                                   class description
  /rack/<system>/<name>/scan       Ladar as foxglove.LaserScan
  /rack/<system>/<name>/points     Scan2D as foxglove.PointCloud (frame base_link)
  /rack/<system>/<name>/pose       Position, MCL, Odometry as foxglove.PoseInFrame (frame map)
  /rack/<system>/<name>/estimate   Position, MCL as foxglove.Odometry: the pose with its
                                   covariance (x, y, yaw of the 6x6), frame map
  /rack/<system>/<name>/particles  MCL's particles as foxglove.PosesInFrame
  /rack/<system>/<name>/path       Path as foxglove.PosesInFrame
  /rack/<system>/map               the occupancy map as foxglove.Grid
  /rack/<system>/tf                Position as foxglove.FrameTransforms (map -> base_link)
  /rack/<system>/<name>/image      Camera as foxglove.RawImage (rgb8, mono8) or
                                   foxglove.CompressedImage (jpeg), polled once a second
  /rack/gdos                       every host's GDOS log as foxglove.Log
Services (JSON): /rack/<system>/<name>/switch {"on":true}, /rack/<system>/all_off {},
  /rack/<system>/set_destination {"x":..,"y":..}, /rack/<system>/set_pose {"x":..,"y":..,"phi":..},
  and every class command: /rack/<system>/<name>/<COMMAND> with its body's fields, e.g.
  /rack/0/mcl/INIT {"x":4,"y":7.2,"phi":0,"sigma_xy":0.2,"sigma_phi":0.1}. Each answers
  {"ok":..,"text":..}; a value that does not fit its field is refused, nothing sent.
Parameters: "<address>.<parameter>", e.g. "Pilot(0/0).vx_max" (get and set).

Rates: every component whose channel a Foxglove client subscribes to, and every
component a recording takes (--topics), is streamed at its full rate (or --period-ms)
through rack-gui's "subscribe"; the others arrive at rack-gui's poll rate (5 Hz for
navigation classes, 1 Hz for the others).

Recording: each message is logged at its sample's own time (the producer's time_ns, to
the nanosecond), never at the time it came. Samples lost on the way (gaps in a stream's
sequence numbers) and messages the recorder could not write as fast as they came are
counted, said when it stops and kept in the file (Metadata "rack.recorder").

play FILE: plays an MCAP recording of rack-foxglove back into a running host (through
rack-gui): each recorded component channel /rack/<system>/<name> goes to the component
<name> of that system, which must be of a playback class standing in for the recorded
one: ChassisPlayback, LadarPlayback, OdometryPlayback, Scan2dPlayback, PositionPlayback,
MclPlayback, PathPlayback, ServoDrivePlayback or GeneratorPlayback (host files:
configs/replay_mcap_sim.yaml plays every stream of sim_mcl, configs/replay_mcap_mcl.yaml
runs MCL on the played laser and odometry, configs/replay_mcap_chassis_mcl.yaml on the
played laser and chassis). Every sample keeps its recorded time and
fields. The file is read and checked whole first: a malformed one (not MCAP, cut short
before its first message, a corrupt chunk, ...) is refused with what is wrong and at
which byte, exit status 2; a channel of a schema no RACK class records is named and
not played.
  --gui URL            rack-gui's WebSocket on the host's network (required)
  --speed S            1: as recorded (default); 2: twice as fast; 0: as fast as the
                       host acknowledges (at most 16 samples on the way at once)
  --topics REGEX       play only the channels REGEX matches, and wait until every one of
                       them has its playback component (default: every channel whose
                       component is a playback class)
  --init-mcl NAME      first INIT the MCL component NAME at the recorded MCL pose (the
                       channel /rack/<system>/NAME) of the first played sample's time
  --init-sigma-xy M    its spread (default 0.1 m)
  --init-sigma-phi R   (default 0.05 rad)
  --wait S             wait this long for the host's components to be listed, described
                       and enabled (default 30 s; the host may start after the player);
                       what is missing is said after 1 s, and at the end

Exit status: 0 after SIGINT, SIGTERM or --duration (play: every sample acknowledged); 1
when rack-gui cannot be reached, the arguments are wrong or (play) a sample was refused
or not answered (counted apart: lost on the way, TiMS being UDP on a loaded machine);
2 when the recording cannot be written, or (play) is malformed or holds nothing to play.`;

function parseArgs(argv) {
  const o = { gui: '', port: 8765, host: '127.0.0.1', server: true, record: '', topics: null,
              compression: 'zstd', duration: 0, periodMs: 0, polled: false, play: '', speed: 1, initMcl: '', sigmaXy: 0.1, sigmaPhi: 0.05, waitS: 30 };
  const positive = (v, name, min) => {
    const n = Number(v);
    if (!Number.isFinite(n) || n < min) throw new Error(`${name} ${v}: expected a number >= ${min}`);
    return n;
  };
  if (argv[0] === 'play') {
    if (argv.length < 2 || argv[1].startsWith('-')) throw new Error('play needs the MCAP file (see --help)');
    o.play = argv[1];
    o.server = false;
    argv = argv.slice(2);
  }
  const value = (i, name) => {
    if (i + 1 >= argv.length) throw new Error(`${name} needs a value`);
    return argv[i + 1];
  };
  for (let i = 0; i < argv.length; ++i) {
    const a = argv[i];
    switch (a) {
      case '-h': case '--help': o.help = true; break;
      case '--version': o.version = true; break;
      case '--gui': o.gui = value(i++, a); break;
      case '--port': {
        const v = value(i++, a);
        o.port = Number(v);
        if (!/^\d+$/.test(v) || o.port > 65535) throw new Error(`--port ${v}: expected 0..65535`);
        break;
      }
      case '--host': o.host = value(i++, a); break;
      case '--no-server': o.server = false; break;
      case '--record': o.record = value(i++, a); break;
      case '--topics': {
        const v = value(i++, a);
        try { o.topics = new RegExp(v); } catch (e) { throw new Error(`--topics ${v}: ${e.message}`); }
        break;
      }
      case '--compression':
        o.compression = value(i++, a);
        if (!['zstd', 'lz4', 'none'].includes(o.compression)) throw new Error(`--compression ${o.compression}: expected zstd, lz4 or none`);
        break;
      case '--period-ms': {
        const v = value(i++, a);
        o.periodMs = Number(v);
        if (!Number.isFinite(o.periodMs) || o.periodMs < 0 || o.periodMs > 60000) throw new Error(`--period-ms ${v}: expected 0..60000`);
        break;
      }
      case '--polled': o.polled = true; break;
      case '--duration': {
        const v = value(i++, a);
        o.duration = Number(v);
        if (!Number.isFinite(o.duration) || o.duration <= 0) throw new Error(`--duration ${v}: expected seconds > 0`);
        break;
      }
      case '--speed': o.speed = positive(value(i++, a), a, 0); break;
      case '--init-mcl': o.initMcl = value(i++, a); break;
      case '--init-sigma-xy': o.sigmaXy = positive(value(i++, a), a, 0); break;
      case '--init-sigma-phi': o.sigmaPhi = positive(value(i++, a), a, 0); break;
      case '--wait': o.waitS = positive(value(i++, a), a, 0); break;
      default: throw new Error(`unknown argument '${a}' (see --help)`);
    }
  }
  if (o.version) return o;
  if (!o.help && !o.gui) throw new Error('--gui URL is required (see --help)');
  if (!o.help && !o.play && !o.server && !o.record) throw new Error('--no-server without --record does nothing');
  if (o.play && (o.record || o.duration)) throw new Error('play takes no --record or --duration');
  return o;
}

// The link to rack-gui: parsed messages in, requests out (with an id; the result
// message comes back with it).
class GuiLink {
  constructor(url, onMessage) {
    this.url = url;
    this.onMessage = onMessage;
    this.nextId = 1;
    this.pending = new Map();  // id -> {resolve, timer}
    this.paramWaiters = new Map();  // address -> [resolve]
  }

  connect() {
    return new Promise((resolve, reject) => {
      this.ws = new WebSocket(this.url, { maxPayload: 64 * 1024 * 1024 });
      this.ws.on('open', resolve);
      this.ws.on('error', (e) => reject(new Error(`${this.url}: ${e.message}`)));
      this.ws.on('message', (data, binary) => {
        if (binary) return;
        let m;
        // Exact: a sample's time_ns (ns since the epoch) is past what a number holds.
        try { m = parseExact(data.toString('utf8')); } catch { return; }
        // A request's answer: its result, or rack-gui's refusal of it (an error with its id).
        if ((m?.type === 'result' || m?.type === 'error') && this.pending.has(m.id)) {
          const p = this.pending.get(m.id);
          this.pending.delete(m.id);
          clearTimeout(p.timer);
          p.resolve(m.type === 'result' ? m : { ok: false, text: `refused by rack-gui: ${m.error}` });
        }
        if (m?.type === 'params' && this.paramWaiters.has(m.component)) {
          for (const w of this.paramWaiters.get(m.component)) w(m.params);
          this.paramWaiters.delete(m.component);
        }
        this.onMessage(m);
      });
    });
  }

  // Sends a request; resolves with its result message ({ok:false,text} on a timeout).
  request(body, timeoutMs = 5000) {
    const id = this.nextId++;
    return new Promise((resolve) => {
      const timer = setTimeout(() => {
        this.pending.delete(id);
        resolve({ ok: false, timeout: true, text: `rack-gui did not answer in ${timeoutMs} ms` });
      }, timeoutMs);
      this.pending.set(id, { resolve, timer });
      this.ws.send(stringifyExact({ ...body, id }));
    });
  }

  // A component's parameters ([{name, kind, value}]), or null.
  async params(address) {
    const got = new Promise((resolve) => {
      if (!this.paramWaiters.has(address)) this.paramWaiters.set(address, []);
      this.paramWaiters.get(address).push(resolve);
    });
    const r = await this.request({ op: 'get_params', component: address });
    if (!r.ok) {
      this.paramWaiters.delete(address);
      return null;
    }
    return got;
  }
}

// The component streams this bridge takes through rack-gui ("subscribe"): each one
// while anyone wants it (the recorder, a Foxglove channel's subscribers). While a
// component's stream flows, its polled samples are left out (the stream has them all).
class Streams {
  constructor(link, periodMs, enabled, log) {
    this.link = link;
    this.periodMs = periodMs;
    this.enabled = enabled;
    this.log = log;
    this.wanted = new Map();  // address -> Set(who)
    this.lastStream = new Map();  // address -> Date.now() of its last stream sample
    this.silentMs = Math.max(1000, 2 * periodMs);  // a stream this quiet is taken as not flowing
  }

  want(address, who) {
    if (!this.enabled) return;
    let s = this.wanted.get(address);
    if (!s) {
      s = new Set();
      this.wanted.set(address, s);
    }
    const first = s.size === 0;
    s.add(who);
    if (first) this.subscribe(address, 0);
  }

  // Asks rack-gui for the stream; said either way: "Ladar(0/0): streaming every sample"
  // once rack-gui has it (a recording holds every sample from then on), or why not.
  // rack-gui keeps a refused subscription and streams once the component is enabled,
  // without telling: asked again every second until it says it streams (a subscribe of
  // a stream that flows is answered at once), so that the line comes when it does.
  subscribe(address, attempt) {
    if (!this.wanted.has(address)) return;
    this.link.request({ op: 'subscribe', component: address, period_ms: this.periodMs }).then((r) => {
      if (r.ok || attempt === 0) this.log(`stream of ${address}: ${r.text}`);
      if (!r.ok && this.wanted.has(address)) setTimeout(() => this.subscribe(address, attempt + 1), 1000).unref();
    });
  }

  drop(address, who) {
    const s = this.wanted.get(address);
    if (!s || !s.delete(who) || s.size > 0) return;
    this.wanted.delete(address);
    this.link.request({ op: 'unsubscribe', component: address });
  }

  // Whether a rack-gui message is passed on: a stream sample always (the producer
  // sends each once, in order), a polled one while its component's stream is silent.
  pass(m) {
    if (m?.type !== 'data' || typeof m.component !== 'string') return true;
    const now = Date.now();
    if (m.stream === true) {
      this.lastStream.set(m.component, now);
      return true;
    }
    return now - (this.lastStream.get(m.component) ?? 0) >= this.silentMs;
  }
}

const kObject = (properties, required) => JSON.stringify({ type: 'object', properties, required });
const kNum = { type: 'number' };

// The Foxglove side: channels advertised as topics first appear, latched messages
// resent to a new subscriber, services and parameters carried out through rack-gui.
class Bridge {
  constructor(server, converter, link, streams) {
    this.server = server;
    this.converter = converter;
    this.link = link;
    this.streams = streams;
    this.channels = new Map();  // topic -> {id, last, latched, component}
    this.services = new Map();  // service id -> handler(request) -> Promise<result>
    this.serviceNames = new Set();
    this.subscribed = new Set();
    server.on('subscribe', (id) => {
      this.subscribed.add(id);
      for (const c of this.channels.values()) {
        if (c.id !== id) continue;
        if (c.latched && c.last) server.sendMessage(id, c.last.time, c.last.payload);
        if (c.component) streams.want(c.component, `channel ${id}`);  // every sample from now on
      }
    });
    server.on('unsubscribe', (id) => {
      this.subscribed.delete(id);
      for (const c of this.channels.values()) if (c.id === id && c.component) streams.drop(c.component, `channel ${id}`);
    });
    // The library passes these on as the client sent them (fields of any type): each is
    // checked before use, and whatever still goes wrong refuses that message only (an
    // async handler's exception would otherwise end the process: an unhandled rejection).
    const guarded = (what, f) => (req, conn) => f(req, conn).catch((e) => this.refuse(`${what}: ${e.message}`, conn));
    server.on('serviceCallRequest', guarded('service call', (req, conn) => this.call(req, conn)));
    server.on('getParameters', guarded('getParameters', (req, conn) => this.getParameters(req, conn)));
    server.on('setParameters', guarded('setParameters', (req, conn) => this.setParameters(req, conn)));
    // A malformed message from a Foxglove client (the library refuses it and goes on):
    // counted, logged at most once a second, the count printed at exit.
    this.malformed = 0;
    this.lastLog = 0;
    server.on('error', (e) => {
      this.malformed += 1;
      const now = Date.now();
      if (now - this.lastLog >= 1000) {
        this.lastLog = now;
        console.error(`rack-foxglove: refused a Foxglove client's message: ${e.message} (${this.malformed} so far)`);
      }
    });
  }

  // A client message the library passed on that this bridge cannot carry out: counted and
  // logged as the library's refusals are, and the client told (a status).
  refuse(why, conn) {
    this.malformed += 1;
    const now = Date.now();
    if (now - this.lastLog >= 1000) {
      this.lastLog = now;
      console.error(`rack-foxglove: refused a Foxglove client's message: ${why} (${this.malformed} so far)`);
    }
    try {
      this.server.sendStatus({ level: 2, message: why }, conn);
    } catch {
      // the client is gone
    }
  }

  publish(item) {
    let c = this.channels.get(item.topic);
    if (!c) {
      const id = this.server.addChannel({
        topic: item.topic, encoding: kJsonEncoding, schemaName: item.schemaName,
        schema: JSON.stringify(item.schema), schemaEncoding: kSchemaEncoding,
      });
      c = { id, latched: item.latched === true, last: null, component: item.component };
      this.channels.set(item.topic, c);
    }
    const payload = new TextEncoder().encode(stringifyExact(item.message));
    if (c.latched) c.last = { time: item.time, payload };
    if (this.subscribed.has(c.id)) this.server.sendMessage(c.id, item.time, payload);
  }

  addService(name, requestSchema, handler) {
    if (this.serviceNames.has(name)) return;
    this.serviceNames.add(name);
    const def = (schemaName, schema) => ({ encoding: kJsonEncoding, schemaName, schemaEncoding: kSchemaEncoding, schema });
    const id = this.server.addService({
      name, type: `rack.${name.split('/').pop()}`,
      request: def(`rack.${name.split('/').pop()}.Request`, requestSchema),
      response: def('rack.Result', kObject({ ok: { type: 'boolean' }, text: { type: 'string' } }, ['ok', 'text'])),
    });
    this.services.set(id, handler);
  }

  // Services for the components and robots rack-gui knows.
  updateServices() {
    const systems = new Set();
    for (const c of this.converter.components.values()) {
      systems.add(c.system);
      this.addService(`/rack/${c.system}/${c.name}/switch`, kObject({ on: { type: 'boolean' } }, ['on']),
                      (r) => this.link.request({ op: 'switch', component: c.address, on: r.on === true }));
      // The class's commands (from its description), the body's fields as the request.
      const cls = this.converter.classOf(c.system, c.class);
      for (const k of cls?.commands ?? []) {
        const schema = k.body ? typeSchema(`${cls.class}.${k.name}`, k.body) : { type: 'object', properties: {} };
        schema.description = k.summary;
        this.addService(`/rack/${c.system}/${c.name}/${k.name}`, JSON.stringify(schema),
                        (r) => this.link.request({ op: 'command_json', component: c.address, command: k.name, body: r }));
      }
    }
    for (const s of systems) {
      this.addService(`/rack/${s}/all_off`, kObject({}, []), () => this.link.request({ op: 'all_off', system: s }, 30000));
      this.addService(`/rack/${s}/set_destination`, kObject({ x: kNum, y: kNum }, ['x', 'y']),
                      (r) => this.link.request({ op: 'set_destination', system: s, x: r.x, y: r.y }));
      this.addService(`/rack/${s}/set_pose`, kObject({ x: kNum, y: kNum, phi: kNum }, ['x', 'y', 'phi']),
                      (r) => this.link.request({ op: 'set_pose', system: s, x: r.x, y: r.y, phi: r.phi }));
    }
  }

  async call(req, conn) {
    const handler = this.services.get(req.serviceId);
    const fail = (message) => this.server.sendServiceCallFailure({ op: 'serviceCallFailure', serviceId: req.serviceId,
                                                                   callId: req.callId, message }, conn);
    if (!handler) return fail(`no service ${req.serviceId}`);
    if (req.encoding !== kJsonEncoding) return fail(`encoding '${req.encoding}': this server takes json`);
    let body;
    try {
      body = JSON.parse(new TextDecoder().decode(req.data));
    } catch (e) {
      return fail(`request is not JSON: ${e.message}`);
    }
    if (body === null || typeof body !== 'object' || Array.isArray(body)) return fail('request is not a JSON object');
    const r = await handler(body);
    // rack-gui checks every value (types, ranges) and answers a refusal as ok:false.
    this.server.sendServiceCallResponse({ serviceId: req.serviceId, callId: req.callId, encoding: kJsonEncoding,
                                          data: new TextEncoder().encode(JSON.stringify({ ok: r.ok === true, text: String(r.text ?? r.error ?? '') })) }, conn);
  }

  // "<address>.<parameter>" names; no names: every parameter of every enabled component.
  async getParameters(req, conn) {
    if (!Array.isArray(req.parameterNames) || !req.parameterNames.every((n) => typeof n === 'string')) {
      return this.refuse('getParameters: parameterNames is not a list of strings', conn);
    }
    const wanted = new Map();  // address -> Set(parameter) | null (all)
    if (req.parameterNames.length === 0) {
      for (const c of this.converter.components.values()) if (c.state === 'enabled') wanted.set(c.address, null);
    }
    for (const n of req.parameterNames) {
      const dot = n.lastIndexOf('.');
      if (dot <= 0) continue;
      const a = n.slice(0, dot);
      if (!wanted.has(a)) wanted.set(a, new Set());
      wanted.get(a)?.add(n.slice(dot + 1));
    }
    const out = [];
    await Promise.all([...wanted].map(async ([address, names]) => {
      const list = await this.link.params(address);
      for (const p of list ?? []) {
        if (names === null || names.has(p.name)) out.push({ name: `${address}.${p.name}`, value: p.value ?? undefined });
      }
    }));
    this.server.publishParameterValues(out, req.id, conn);
  }

  async setParameters(req, conn) {
    if (!Array.isArray(req.parameters) || !req.parameters.every((p) => typeof p?.name === 'string')) {
      return this.refuse('setParameters: parameters is not a list of {name, value}', conn);
    }
    const results = [];
    for (const p of req.parameters) {
      const dot = p.name.lastIndexOf('.');
      if (dot <= 0) continue;
      const r = await this.link.request({ op: 'set_param', component: p.name.slice(0, dot), name: p.name.slice(dot + 1),
                                          value: p.value });
      if (!r.ok) this.server.sendStatus({ level: 2, message: `${p.name}: ${r.text}` }, conn);
      results.push(p.name);
    }
    if (req.id !== undefined) await this.getParameters({ parameterNames: results, id: req.id }, conn);
  }
}

async function main() {
  let o;
  try {
    o = parseArgs(process.argv.slice(2));
  } catch (e) {
    console.error(`rack-foxglove: ${e.message}`);
    return 1;
  }
  if (o.help) {
    console.log(kHelp);
    return 0;
  }
  if (o.version) {
    const version = (rel) => JSON.parse(fs.readFileSync(new URL(rel, import.meta.url), 'utf8')).version;
    console.log(`rack-foxglove ${version('./package.json')} (@foxglove/ws-protocol ${version('./node_modules/@foxglove/ws-protocol/package.json')}, ` +
                `@mcap/core ${version('./node_modules/@mcap/core/package.json')})`);
    return 0;
  }
  const converter = new Converter();
  let reader = null;
  if (o.play) {
    // Every record is read and checked before rack-gui is joined: a malformed file is
    // refused (exit 2) with what is wrong and where, before anything is played.
    try {
      reader = await openMcap(o.play);
      if (reader.truncated) console.error(`rack-foxglove: play ${o.play}: ${reader.truncated}`);
    } catch (e) {
      console.error(`rack-foxglove: play ${o.play}: refused: ${e.message}`);
      return 2;
    }
    const { playable, refused } = playableChannels(reader, o.topics);
    for (const why of refused) console.error(`rack-foxglove: play ${o.play}: not played: ${why}`);
    if (playable.size === 0) {
      console.error(`rack-foxglove: play ${o.play}: refused: no channel to play${o.topics ? ` among those --topics takes` : ''} ` +
                    `(a component channel /rack/<system>/<name> with a rack.<Class> JSON schema, as rack-foxglove records)`);
      return 2;
    }
  }
  let recorder = null;
  if (o.record) {
    try {
      recorder = await Recorder.open({ path: o.record, compression: o.compression, topics: o.topics, source: o.gui });
    } catch (e) {
      console.error(`rack-foxglove: --record ${o.record}: ${e.message}`);
      return 2;
    }
  }
  let bridge = null;
  let wss = null;
  let link = null;
  let lastRejected = 0;
  let streams = null;
  const recording = new Set();  // components the recorder streams
  const onMessage = (m) => {
    if (streams && !streams.pass(m)) return;
    const items = converter.convert(m);
    if (converter.rejected !== lastRejected) {
      lastRejected = converter.rejected;
      console.error(`rack-foxglove: skipped a rack-gui message: ${converter.lastRejection} (${converter.rejected} so far)`);
    }
    // A component the recorder streams is recorded from its stream only: every sample,
    // once, in order (a polled sample before the stream flowed would stand apart).
    const record = recorder && !(m?.type === 'data' && streams?.enabled && recording.has(m.component) && m.stream !== true);
    for (const item of items) {
      if (bridge) bridge.publish(item);
      if (record) recorder.add(item);
    }
    // Each stream sample's sequence number: the recorder counts the gaps (samples lost
    // on the way to it).
    // (--period-ms: the producer leaves samples out on purpose; no gaps counted.)
    if (record && o.periodMs === 0 && m?.type === 'data' && m.stream === true && items.length > 0) {
      recorder.sample(items[0].topic, m.sequence);
    }
    if (bridge && (m?.type === 'components' || m?.type === 'class')) bridge.updateServices();
    // A recording streams every component whose topics it takes.
    if (recorder && streams && m?.type === 'components') {
      for (const c of converter.components.values()) {
        if (recording.has(c.address) || !topicsOf(c.system, c.name, c.class).some((t) => recorder.wants(t))) continue;
        recording.add(c.address);
        streams.want(c.address, 'recorder');
      }
    }
  };
  link = new GuiLink(o.gui, onMessage);
  streams = o.play ? null : new Streams(link, o.periodMs, !o.polled, (t) => console.error(`rack-foxglove: ${t}`));
  try {
    await link.connect();
  } catch (e) {
    console.error(`rack-foxglove: cannot reach rack-gui at ${e.message}`);
    if (recorder) await recorder.close();
    return 1;
  }
  if (o.play) {
    const log = (t) => console.error(`rack-foxglove: ${t}`);
    try {
      const r = await play({ reader, speed: o.speed, topics: o.topics, initMcl: o.initMcl, sigmaXy: o.sigmaXy,
                             sigmaPhi: o.sigmaPhi, waitS: o.waitS }, link, converter, log);
      link.ws.close();
      return r.refused === 0 && r.unanswered === 0 ? 0 : 1;
    } catch (e) {
      log(`play ${o.play}: ${e instanceof MalformedMcap ? 'refused: ' : ''}${e.message}`);
      link.ws.close();
      return e instanceof MalformedMcap ? 2 : 1;
    }
  }
  if (o.server) {
    const server = new FoxgloveServer({
      name: 'rack-foxglove',
      capabilities: ['services', 'parameters'],
      supportedEncodings: [kJsonEncoding],
    });
    bridge = new Bridge(server, converter, link, streams);
    wss = new WebSocketServer({ host: o.host, port: o.port, handleProtocols: (protocols) => server.handleProtocols(protocols) });
    wss.on('connection', (conn, req) => server.handleConnection(conn, `${req.socket.remoteAddress}:${req.socket.remotePort}`));
    await new Promise((resolve, reject) => {
      wss.on('listening', resolve);
      wss.on('error', reject);
    }).catch((e) => {
      console.error(`rack-foxglove: cannot listen on ${o.host}:${o.port}: ${e.message}`);
      process.exit(1);
    });
    console.error(`rack-foxglove: serving ws://${o.host}:${wss.address().port} (Foxglove WebSocket), from ${o.gui}`);
  }
  if (recorder) console.error(`rack-foxglove: recording ${o.record} (${o.compression} chunks)`);

  let stopping = null;
  const stop = (why) => {
    if (stopping) return stopping;
    stopping = (async () => {
      link.ws.close();
      if (wss) {
        for (const c of wss.clients) c.terminate();
        wss.close();
      }
      if (recorder) {
        try {
          await recorder.close();
          console.error(`rack-foxglove: wrote ${recorder.messages} messages on ${recorder.channels.size} channels to ${o.record}; ` +
                        `${recorder.lost()} stream sample(s) lost on the way, ${recorder.dropped} dropped by the recorder`);
          for (const line of recorder.lostReport()) console.error(`rack-foxglove: ${line}`);
        } catch (e) {
          console.error(`rack-foxglove: ${o.record}: ${e.message}`);
          return 2;
        }
      }
      if (bridge) console.error(`rack-foxglove: ${bridge.malformed} malformed Foxglove client message(s) refused`);
      console.error(`rack-foxglove: stopped (${why})`);
      return 0;
    })();
    return stopping;
  };
  return new Promise((resolve) => {
    process.on('SIGINT', () => stop('SIGINT').then(resolve));
    process.on('SIGTERM', () => stop('SIGTERM').then(resolve));
    link.ws.on('close', () => stop('rack-gui closed the connection').then((c) => resolve(c === 0 ? 1 : c)));
    if (o.duration > 0) setTimeout(() => stop(`--duration ${o.duration}`).then(resolve), o.duration * 1000);
  });
}

process.exit(await main());
