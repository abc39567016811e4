// Loads a Chrome JSON trace (rackctl trace --out FILE) with the trace engine of Chrome
// DevTools' Performance panel (@paulirish/trace_engine, the engine Lighthouse uses),
// and prints on stdout, as one JSON object, what that engine made of it:
//   {"processes": [{"pid", "name"}],
//    "threads":   [{"pid", "tid", "name", "slices": {NAME: {"count", "min_dur_us", "max_dur_us"}},
//                   "instants": {NAME: count}, "roots": n}],
//    "flows":     [{"events": [{"pid", "tid", "ph", "name", "ts"}...]}],
//    "bounds_us": {"min", "max", "range"},
//    "warnings":  {WARNING: count},     (the engine's own warnings about the trace)
//    "messages":  ["..."]}              (what the engine wrote on the console while it parsed)
// Exit status: 0 when the engine parsed the file, 1 when it refused it (the reason on
// stderr), 2 on a usage error.
//
// Used by tests/integration/trace_test.cpp (TraceLoaderTest); not part of the product.
// Packages: package.json / package-lock.json here (npm ci --no-audit --no-fund).
import fs from 'node:fs';

import { polyfillDOMRect } from '@paulirish/trace_engine/analyze-trace.mjs';
import * as Trace from '@paulirish/trace_engine/models/trace/trace.js';

const file = process.argv[2];
if (!file || process.argv.length !== 3) {
  process.stderr.write('usage: node load_trace.mjs TRACE.json\n');
  process.exit(2);
}

// Whatever the engine says on the console while it parses is a finding, not noise.
const messages = [];
for (const level of ['error', 'warn', 'assert']) {
  const original = console[level];
  console[level] = (...args) => {
    if (level === 'assert') {
      if (args[0]) return;
      args = args.slice(1);
    }
    messages.push(`${level}: ${args.map(String).join(' ')}`);
    if (level !== 'assert') original.call(console, ...args);
  };
}

try {
  polyfillDOMRect();
  const text = fs.readFileSync(file, 'utf8');
  const json = JSON.parse(text);
  const events = Array.isArray(json) ? json : json.traceEvents;
  if (!Array.isArray(events)) throw new Error('no traceEvents array');

  const model = Trace.TraceModel.Model.createWithAllHandlers();
  await model.parse(events);
  const parsed = model.parsedTrace()?.data;
  if (!parsed) throw new Error('the engine returned no parsed trace');

  const out = { processes: [], threads: [], flows: [], bounds_us: {}, warnings: {}, messages };
  for (const [pid, event] of parsed.Meta.processNames) {
    out.processes.push({ pid: Number(pid), name: event.args?.name ?? null });
  }
  for (const [pid, proc] of parsed.Renderer.processes) {
    for (const [tid, thread] of proc.threads) {
      const slices = {};
      const instants = {};
      for (const e of thread.entries) {
        if (Trace.Types.Events.isComplete(e)) {
          const s = (slices[e.name] ??= { count: 0, min_dur_us: Infinity, max_dur_us: -Infinity });
          s.count += 1;
          s.min_dur_us = Math.min(s.min_dur_us, e.dur);
          s.max_dur_us = Math.max(s.max_dur_us, e.dur);
        } else if (Trace.Types.Events.isInstant(e)) {
          instants[e.name] = (instants[e.name] ?? 0) + 1;
        }
      }
      out.threads.push({
        pid: Number(pid),
        tid: Number(tid),
        name: thread.name,
        slices,
        instants,
        roots: thread.tree?.roots.size ?? 0,
      });
    }
  }
  for (const flow of parsed.Flows.flows) {
    out.flows.push({
      events: flow.map(e => ({ pid: Number(e.pid), tid: Number(e.tid), ph: e.ph, name: e.name, ts: e.ts })),
    });
  }
  const b = parsed.Meta.traceBounds;
  out.bounds_us = { min: Number(b.min), max: Number(b.max), range: Number(b.range) };
  for (const [warning, list] of parsed.Warnings.perWarning) out.warnings[warning] = list.length;
  process.stdout.write(JSON.stringify(out) + '\n');
} catch (e) {
  process.stderr.write(`load_trace: ${file}: the trace engine refused it: ${e?.stack ?? e}\n`);
  process.exit(1);
}
