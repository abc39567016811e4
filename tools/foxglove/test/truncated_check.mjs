// A recording cut short (a recorder that was killed before it wrote the summary) is
// still played as far as it is whole (driven by tests/integration/foxglove_test.cpp):
// the file is cut just after its first chunk; the player's reader (lib/player.mjs
// openMcap) says it is truncated and gives back that chunk's messages, each one of the
// whole file's.
//
// usage: node truncated_check.mjs FILE.mcap
import fs from 'node:fs';

import { openMcap } from '../lib/player.mjs';

const file = process.argv[2];
let failed = false;
const fail = (s) => { console.log(`FAILED ${s}`); failed = true; };

const whole = await openMcap(file);
if (whole.truncated) fail(`the whole file reads as truncated: ${whole.truncated}`);
const all = new Set();
for await (const m of whole.readMessages()) all.add(`${m.channelId}/${m.sequence}/${m.logTime}`);
const first = whole.chunkIndexes[0];
const cutAt = Number(first.chunkStartOffset + first.chunkLength) + 10;
const cut = `${file}.cut`;
fs.writeFileSync(cut, fs.readFileSync(file).subarray(0, cutAt));

const r = await openMcap(cut);
if (!r.truncated) fail('the cut file reads as whole');
else console.log(`ok ${r.truncated}`);
let n = 0;
for await (const m of r.readMessages()) {
  n += 1;
  if (!all.has(`${m.channelId}/${m.sequence}/${m.logTime}`)) fail(`message ${m.channelId}/${m.sequence} is not in the whole file`);
  JSON.parse(new TextDecoder().decode(m.data));
}
if (n === 0 || n > all.size) fail(`${n} messages from the cut file, the whole file has ${all.size}`);
else console.log(`ok ${n} of ${all.size} messages read from the file cut at byte ${cutAt} (after the first chunk)`);
fs.unlinkSync(cut);
console.log(failed ? 'FAILED' : 'all checks passed');
process.exit(failed ? 1 : 0);
