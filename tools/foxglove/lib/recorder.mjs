// An MCAP recorder (@mcap/core's McapWriter): chunked, zstd- or lz4-compressed chunks
// (lib/codecs.mjs) or uncompressed ones, with the summary section (schemas, channels,
// statistics, chunk and message indexes) written by close().
//
// Every message is logged at its sample's own time (logTime = publishTime = the
// producer's time_ns, exact: lib/exact_json.mjs), never at the time it arrived.
//
// What did not reach the file is counted, per component stream: a stream sample
// carries the producer's sequence number (one per sample published), so a gap in it is
// a sample lost on the way (the producer's send to rack-gui, rack-gui's mailbox, its
// queue to this client); and a message the recorder itself could not keep up with
// (more than kMaxPending waiting to be written) is dropped and counted. close() prints
// nothing; lostReport() says it, and the Metadata record "rack.recorder" in the file
// keeps it (per topic: recorded, lost, sequences; and when the recording started and
// stopped, ns since the epoch).
import fs from 'node:fs';
import { McapWriter } from '@mcap/core';

import { chunkCompressor } from './codecs.mjs';
import { kJsonEncoding, kSchemaEncoding } from './convert.mjs';
import { stringifyExact } from './exact_json.mjs';

// Messages queued for writing beyond which the recorder drops (and counts) new ones:
// at sim_mcl's ~400 messages/s, 25 s of backlog.
export const kMaxPending = 10000;

// A file handle as McapWriter wants it (position and write).
class FileSink {
  constructor(path) {
    // Opening a FIFO for writing waits for a reader: rack-foxglove hung there, silent.
    let st = null;
    try { st = fs.statSync(path); } catch { /* not there yet: a new file */ }
    if (st?.isFIFO()) throw new Error('a FIFO, not a regular file (a recording is written to a file)');
    this.fd = fs.openSync(path, 'w');
    this.pos = 0n;
  }
  position() { return this.pos; }
  async write(buffer) {
    let off = 0;
    while (off < buffer.byteLength) off += fs.writeSync(this.fd, buffer, off);
    this.pos += BigInt(buffer.byteLength);
  }
  close() { fs.closeSync(this.fd); }
}

export class Recorder {
  // options: {path, compression: 'zstd'|'lz4'|'none', topics: RegExp|null, chunkSize (bytes)}
  static async open(options) {
    const r = new Recorder({ ...options, compressChunk: await chunkCompressor(options.compression ?? 'zstd') });
    await r.writer.start({ profile: '', library: 'rack-foxglove (@mcap/core)' });
    await r.writer.addMetadata({ name: 'rack', metadata: new Map([['source', options.source ?? '']]) });
    return r;
  }

  constructor({ path, compressChunk, topics = null, chunkSize = 1024 * 1024 }) {
    this.path = path;
    this.topics = topics;
    this.sink = new FileSink(path);
    this.schemas = new Map();   // schema name -> id
    this.channels = new Map();  // topic -> id
    this.sequence = 0;
    this.messages = 0;
    this.queue = Promise.resolve();
    this.lastTime = 0n;
    this.early = [];
    this.startedNs = BigInt(Date.now()) * 1000000n;  // host clock, as the samples' times
    this.pending = 0;
    this.dropped = 0;  // messages the recorder could not keep up with
    this.streams = new Map();  // topic -> {recorded, lost, restarts, first, last} (stream samples)
    this.writer = new McapWriter({ writable: this.sink, chunkSize, compressChunk });
  }

  // Whether a topic is recorded (--topics).
  wants(topic) { return this.topics === null || this.topics.test(topic); }

  // One converted message ({topic, schemaName, schema, time, message}); the writes are
  // queued in order (McapWriter's calls are asynchronous).
  // A latched message without a time of its own (the map, time 0) is logged at the
  // time of the latest message, or of the first one when none came yet, so that a
  // player's timeline is not stretched back to 0.
  add(item) {
    if (!this.wants(item.topic)) return;
    if (this.pending >= kMaxPending) {
      this.dropped += 1;
      return;
    }
    if (item.time === 0n) {
      if (this.lastTime === 0n) {
        this.early.push(item);
        return;
      }
      item = { ...item, time: this.lastTime };
    } else {
      this.lastTime = item.time;
      for (const e of this.early.splice(0)) this.add({ ...e, time: item.time });
    }
    this.pending += 1;
    this.queue = this.queue.then(() => this.write(item)).finally(() => { this.pending -= 1; });
  }

  // A stream sample of a recorded component channel (its producer's sequence number):
  // a gap since the previous one is counted as lost; a sequence at or before the
  // previous one is a restart of the producer (switched off and on), not a loss.
  sample(topic, sequence) {
    if (!this.wants(topic) || !Number.isInteger(sequence)) return;
    let s = this.streams.get(topic);
    if (!s) {
      s = { recorded: 0, lost: 0, restarts: 0, first: sequence, last: sequence - 1 };
      this.streams.set(topic, s);
    }
    if (sequence > s.last + 1) s.lost += sequence - s.last - 1;
    else if (sequence <= s.last) s.restarts += 1;
    s.last = sequence;
    s.recorded += 1;
  }

  // Samples lost on the way in all, and one line per topic that lost any.
  lost() {
    let total = 0;
    for (const s of this.streams.values()) total += s.lost;
    return total;
  }

  lostReport() {
    const lines = [];
    for (const [t, s] of [...this.streams].sort((a, b) => a[0].localeCompare(b[0]))) {
      if (s.lost > 0) lines.push(`${t}: ${s.lost} sample(s) lost on the way (sequence gaps), ${s.recorded} recorded`);
    }
    if (this.dropped > 0) lines.push(`${this.dropped} message(s) dropped: the recorder could not write them as fast as they came`);
    return lines;
  }

  async write(item) {
    let schemaId = this.schemas.get(item.schemaName);
    if (schemaId === undefined) {
      schemaId = await this.writer.registerSchema({
        name: item.schemaName, encoding: kSchemaEncoding,
        data: new TextEncoder().encode(JSON.stringify(item.schema)),
      });
      this.schemas.set(item.schemaName, schemaId);
    }
    let channelId = this.channels.get(item.topic);
    if (channelId === undefined) {
      channelId = await this.writer.registerChannel({
        topic: item.topic, schemaId, messageEncoding: kJsonEncoding, metadata: new Map(),
      });
      this.channels.set(item.topic, channelId);
    }
    await this.writer.addMessage({
      channelId, sequence: this.sequence++, logTime: item.time, publishTime: item.time,
      data: new TextEncoder().encode(stringifyExact(item.message)),
    });
    this.messages += 1;
  }

  async close() {
    await this.queue;
    const counts = new Map([['dropped_by_recorder', String(this.dropped)], ['started_ns', String(this.startedNs)],
                            ['stopped_ns', String(BigInt(Date.now()) * 1000000n)]]);
    for (const [t, s] of [...this.streams].sort((a, b) => a[0].localeCompare(b[0]))) {
      counts.set(t, `recorded ${s.recorded}, lost ${s.lost}, sequence ${s.first}..${s.last}, restarts ${s.restarts}`);
    }
    await this.writer.addMetadata({ name: 'rack.recorder', metadata: counts });
    await this.writer.end();
    this.sink.close();
  }
}
