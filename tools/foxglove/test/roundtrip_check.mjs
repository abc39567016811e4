// A recording played back and recorded again holds the same samples (driven by
// tests/integration/foxglove_test.cpp): both MCAP files are read with the npm MCAP
// reader (@mcap/core, through the player's openMcap); for each --topic, every sample of
// the replay is a recorded one, at the same time to the nanosecond, with the same fields
// (every value equal: integers past 2^53 compared exactly, floats as written), and the
// replay has every recorded sample but at most --allow-missing N in all (the samples
// the player and the replay's recorder counted as lost on the way: TiMS over LCM is
// UDP, and a loaded machine drops a datagram now and then; 0 by default).
//
// usage: node roundtrip_check.mjs RECORDED.mcap REPLAYED.mcap --topic T... [--min N] [--allow-missing N]
// Prints one line per topic; exit status 0 when all are the same.
import { parseExact } from '../lib/exact_json.mjs';
import { openMcap } from '../lib/player.mjs';

const args = process.argv.slice(2);
const [recordedFile, replayedFile] = args;
const topics = [];
let min = 1;
let allowMissing = 0;
for (let i = 2; i < args.length; i += 2) {
  if (args[i] === '--topic') topics.push(args[i + 1]);
  else if (args[i] === '--min') min = Number(args[i + 1]);
  else if (args[i] === '--allow-missing') allowMissing = Number(args[i + 1]);
}
if (!recordedFile || !replayedFile || topics.length === 0) {
  console.log('usage: node roundtrip_check.mjs RECORDED.mcap REPLAYED.mcap --topic T... [--min N]');
  process.exit(2);
}

let failed = false;
const fail = (s) => { console.log(`FAILED ${s}`); failed = true; };

async function samples(file, topic) {
  const r = await openMcap(file);
  const out = [];
  for await (const m of r.readMessages({ topics: [topic] })) {
    out.push({ time: m.logTime, data: parseExact(new TextDecoder().decode(m.data)).data });
  }
  return out;
}

// The first path where a and b differ ('' when equal).
function differ(a, b, where) {
  if (typeof a !== typeof b) return `${where}: ${String(a)} vs ${String(b)}`;
  if (Array.isArray(a)) {
    if (!Array.isArray(b) || a.length !== b.length) return `${where}: ${a.length} vs ${b?.length} entries`;
    for (let i = 0; i < a.length; ++i) {
      const d = differ(a[i], b[i], `${where}[${i}]`);
      if (d) return d;
    }
    return '';
  }
  if (a !== null && typeof a === 'object') {
    const keys = new Set([...Object.keys(a), ...Object.keys(b ?? {})]);
    for (const k of keys) {
      const d = differ(a[k], b?.[k], `${where}.${k}`);
      if (d) return d;
    }
    return '';
  }
  return a === b ? '' : `${where}: ${String(a)} vs ${String(b)}`;
}

let missingAll = 0;
for (const topic of topics) {
  const rec = await samples(recordedFile, topic);
  const rep = await samples(replayedFile, topic);
  if (rec.length < min) {
    fail(`${topic}: ${rec.length} recorded samples, expected at least ${min}`);
    continue;
  }
  const byTime = new Map(rec.map((r) => [r.time, r]));
  let same = 0;
  let first = '';
  for (const r of rep) {
    const was = byTime.get(r.time);
    const d = !was ? `a sample at ${r.time}, which the recording does not have` : differ(r.data, was.data, 'data');
    if (d) {
      if (!first) first = d;
    } else {
      same += 1;
    }
  }
  const ordered = rep.every((r, i) => i === 0 || rep[i - 1].time < r.time);
  const missing = rec.length - same;
  missingAll += Math.max(0, missing);
  const line = `${topic}: ${rec.length} recorded, ${rep.length} replayed, ${same} the same (time to the ns, every field), ${missing} missing`;
  if (same !== rep.length || !ordered) fail(`${line}; ${ordered ? `first difference: ${first}` : 'out of order'}`);
  else console.log(`ok ${line}`);
}
if (missingAll > allowMissing) fail(`${missingAll} recorded sample(s) missing from the replay, at most ${allowMissing} counted as lost on the way`);
else console.log(`ok ${missingAll} recorded sample(s) missing from the replay (${allowMissing} counted as lost on the way)`);
console.log(failed ? 'FAILED' : 'all checks passed');
process.exit(failed ? 1 : 0);
