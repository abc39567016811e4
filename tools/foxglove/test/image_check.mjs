// A camera in Foxglove (driven by tests/integration/foxglove_test.cpp): Foxglove's own
// WebSocket client (@foxglove/ws-protocol) against rack-foxglove serving a host whose
// Camera plays a sequence of 64x48 RGB frames (pixel (x, y) of frame i is x*4, y*5,
// i*50): the channel /rack/0/camera/image is advertised as foxglove.RawImage, and its
// messages match the schema and hold the frames' pixels (rgb8, step 192). One frame is
// checked: a camera sample is 0.9 MB over LCM, and a loaded machine may lose a few.
//
// usage: node image_check.mjs --url ws://127.0.0.1:PORT [--timeout S]
import { WebSocket } from 'ws';
import wsProtocol from '@foxglove/ws-protocol';

import { matchesSchema } from './schema_check.mjs';

const { FoxgloveClient } = wsProtocol;
const args = process.argv.slice(2);
const url = args[args.indexOf('--url') + 1];
const timeoutS = args.includes('--timeout') ? Number(args[args.indexOf('--timeout') + 1]) : 30;
const topic = '/rack/0/camera/image';

let failed = false;
const fail = (s) => { console.log(`FAILED ${s}`); failed = true; };
const client = new FoxgloveClient({ ws: new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]) });
let channel = null;
let sub = -1;
let good = 0;
let resolveDone;
const done = new Promise((r) => { resolveDone = r; });
client.on('advertise', (list) => {
  for (const c of list) {
    if (c.topic !== topic) continue;
    channel = c;
    if (c.schemaName !== 'foxglove.RawImage') fail(`${topic}: schema ${c.schemaName}`);
    sub = client.subscribe(c.id);
  }
});
client.on('message', ({ subscriptionId, data }) => {
  if (subscriptionId !== sub) return;
  const m = JSON.parse(new TextDecoder().decode(data));
  const problem = matchesSchema(m, JSON.parse(channel.schema), topic);
  if (problem) fail(problem);
  const px = Buffer.from(m.data, 'base64');
  const at = 5 * m.step + 10 * 3;  // (x 10, y 5)
  if (m.width !== 64 || m.height !== 48 || m.encoding !== 'rgb8' || m.step !== 192 || px.length !== 64 * 48 * 3 ||
      px[at] !== 40 || px[at + 1] !== 25 || px[at + 2] % 50 !== 0 || m.frame_id !== 'camera') {
    fail(`${topic}: ${m.width}x${m.height} ${m.encoding} step ${m.step}, ${px.length} bytes, pixel (10, 5) ${px[at]} ${px[at + 1]} ${px[at + 2]}, frame ${m.frame_id}`);
  } else {
    good += 1;
  }
  if (good >= 1) resolveDone();
});
const timer = setTimeout(() => resolveDone(), timeoutS * 1000);
await done;
clearTimeout(timer);
if (good >= 1) console.log(`ok ${topic}: foxglove.RawImage, a frame of 64x48 rgb8 with the camera's pixels`);
else fail(`${topic}: ${good} good frames in ${timeoutS} s (${channel ? 'advertised' : 'not advertised'})`);
client.close();
console.log(failed ? 'FAILED' : 'all checks passed');
process.exit(failed ? 1 : 0);
