// An MCAP recorder (@mcap/core's McapWriter): chunked, zstd- or lz4-compressed chunks
// (lib/codecs.mjs) or uncompressed ones, with the summary section (schemas, channels,
// statistics, chunk and message indexes) written by close().
import fs from 'node:fs';
import { McapWriter } from '@mcap/core';

import { chunkCompressor } from './codecs.mjs';
import { kJsonEncoding, kSchemaEncoding } from './convert.mjs';

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
    this.queue = this.queue.then(() => this.write(item));
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
      data: new TextEncoder().encode(JSON.stringify(item.message)),
    });
    this.messages += 1;
  }

  async close() {
    await this.queue;
    await this.writer.end();
    this.sink.close();
  }
}
