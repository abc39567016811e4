// Foxglove's own WebSocket client (@foxglove/ws-protocol's FoxgloveClient) against
// rack-foxglove serving a running sim_mcl host (driven by tests/integration/
// foxglove_test.cpp): the expected channels are advertised with their schemas, typed
// messages arrive on them and match their schemas, a service answers and a malformed
// call is refused, parameters are read and set; a subscribed channel comes at its
// producer's full rate (the bridge streams what a Foxglove client subscribes to), not
// at rack-gui's 5 Hz poll.
//
// usage: node live_check.mjs --url ws://127.0.0.1:PORT [--timeout S]
// Prints one line per check ("ok ..." or "FAILED ..."); exit status 0 when all passed.
import { WebSocket } from 'ws';
import wsProtocol from '@foxglove/ws-protocol';

import { matchesSchema } from './schema_check.mjs';

const { FoxgloveClient } = wsProtocol;

const args = process.argv.slice(2);
const arg = (name, def) => {
  const i = args.indexOf(name);
  return i >= 0 && i + 1 < args.length ? args[i + 1] : def;
};
const url = arg('--url', '');
const timeoutS = Number(arg('--timeout', '40'));
if (!url) {
  console.log('usage: node live_check.mjs --url ws://127.0.0.1:PORT');
  process.exit(2);
}

// Topic -> schema name, and what a message on it must hold.
const expected = {
  '/rack/0/map': ['foxglove.Grid', (m) => m.column_count > 0 && Buffer.from(m.data, 'base64').length % m.column_count === 0 &&
                                          m.cell_size.x > 0 && m.frame_id === 'map'],
  '/rack/0/ladar/scan': ['foxglove.LaserScan', (m) => m.ranges.length === 541 && m.ranges.every((r) => typeof r === 'number') &&
                                                    m.end_angle > m.start_angle],
  '/rack/0/scan2d/points': ['foxglove.PointCloud', (m) => m.point_stride === 8 && Buffer.from(m.data, 'base64').length > 0 &&
                                                         m.fields.length === 2],
  '/rack/0/position/pose': ['foxglove.PoseInFrame', (m) => m.pose.position.x > 0 && m.pose.position.x < 30 && m.pose.position.y > 0 && m.pose.position.y < 30 &&
                                                          Math.abs(Math.hypot(m.pose.orientation.z, m.pose.orientation.w) - 1) < 1e-6],
  '/rack/0/mcl/pose': ['foxglove.PoseInFrame', (m) => m.frame_id === 'map' && Number.isFinite(m.pose.position.x)],
  '/rack/0/mcl/particles': ['foxglove.PosesInFrame', (m) => m.poses.length > 0],
  // The pose with its covariance: MCL's x, y and phi entries in the 6x6 (x, y, yaw).
  '/rack/0/mcl/estimate': ['foxglove.Odometry', (m) => m.frame_id === 'map' && m.body_frame_id === 'base_link' &&
                                                      m.pose_covariance.length === 36 && m.pose_covariance[0] > 0 &&
                                                      m.pose_covariance[7] > 0 && m.pose_covariance[35] > 0],
  '/rack/0/tf': ['foxglove.FrameTransforms', (m) => m.transforms[0].parent_frame_id === 'map' && m.transforms[0].child_frame_id === 'base_link'],
  '/rack/0/chassis': ['rack.Chassis', (m) => m.component === 'Chassis(0/0)' && typeof m.data.vx === 'number' && m.time_ns > 0],
  '/rack/0/mcl': ['rack.MCL', (m) => Array.isArray(m.data.covariance) && m.data.covariance.length === 9],
};

const t0 = Date.now();
const log = (s) => console.log(`[${((Date.now() - t0) / 1000).toFixed(1)} s] ${s}`);
let failed = false;
const fail = (s) => { log(`FAILED ${s}`); failed = true; };

const client = new FoxgloveClient({ ws: new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]) });
const channels = new Map();  // id -> channel
const bySub = new Map();     // subscription id -> channel
const services = new Map();  // name -> service
const seen = new Map();      // topic -> messages checked
let serverInfo = null;
let lastMclPose = { x: 4.0, y: 7.2, phi: 0.0 };
let resolveDone;
const done = new Promise((r) => { resolveDone = r; });
const pendingCalls = new Map();
const pendingParams = new Map();
const chassisSequences = [];  // the chassis samples' own sequence numbers, as they came

client.on('serverInfo', (i) => { serverInfo = i; });
client.on('error', (e) => fail(`client error: ${e.message}`));
client.on('advertise', (list) => {
  for (const c of list) {
    channels.set(c.id, c);
    if (c.encoding !== 'json' || c.schemaEncoding !== 'jsonschema') fail(`${c.topic}: encoding ${c.encoding}/${c.schemaEncoding}`);
    const want = expected[c.topic];
    if (want && c.schemaName !== want[0]) fail(`${c.topic}: schema ${c.schemaName}, expected ${want[0]}`);
    bySub.set(client.subscribe(c.id), c);
  }
});
client.on('advertiseServices', (list) => { for (const s of list) services.set(s.name, s); });
client.on('message', ({ subscriptionId, timestamp, data }) => {
  const c = bySub.get(subscriptionId);
  if (!c) return fail(`message on unknown subscription ${subscriptionId}`);
  let m;
  try {
    m = JSON.parse(new TextDecoder().decode(data));
  } catch (e) {
    return fail(`${c.topic}: not JSON: ${e.message}`);
  }
  if (c.topic === '/rack/0/mcl') lastMclPose = m.data;
  if (c.topic === '/rack/0/chassis') chassisSequences.push(m.sequence);
  const n = (seen.get(c.topic) ?? 0) + 1;
  seen.set(c.topic, n);
  if (n > 3) return undefined;  // the first few of each are checked in full
  const problem = matchesSchema(m, JSON.parse(c.schema), c.topic);
  if (problem) fail(problem);
  const want = expected[c.topic];
  if (want && !want[1](m)) fail(`${c.topic}: unexpected content ${JSON.stringify(m).slice(0, 300)}`);
  if (typeof timestamp !== 'bigint') fail(`${c.topic}: timestamp ${typeof timestamp}`);
  if (Object.keys(expected).every((t) => seen.has(t)) && services.has('/rack/0/chassis/switch') && services.has('/rack/0/mcl/INIT')) resolveDone();
  return undefined;
});
client.on('serviceCallResponse', (r) => {
  const p = pendingCalls.get(r.callId);
  if (p) p({ response: JSON.parse(new TextDecoder().decode(r.data)) });
});
client.on('serviceCallFailure', (r) => {
  const p = pendingCalls.get(r.callId);
  if (p) p({ failure: r.message });
});
client.on('parameterValues', (e) => {
  const p = pendingParams.get(e.id);
  if (p) p(e.parameters);
});

let callId = 1;
const call = (name, body, raw) => new Promise((resolve) => {
  const s = services.get(name);
  const id = callId++;
  const timer = setTimeout(() => resolve({ failure: 'no answer in 10 s' }), 10000);
  pendingCalls.set(id, (r) => { clearTimeout(timer); resolve(r); });
  client.sendServiceCallRequest({ serviceId: s.id, callId: id, encoding: 'json',
                                  data: raw ?? new TextEncoder().encode(JSON.stringify(body)) });
});
const waitParams = (id) => new Promise((resolve) => {
  const timer = setTimeout(() => resolve(null), 10000);
  pendingParams.set(id, (p) => { clearTimeout(timer); resolve(p); });
});
const params = (names, id) => {
  const p = waitParams(id);
  client.getParameters(names, id);
  return p;
};

const timer = setTimeout(() => resolveDone('timeout'), timeoutS * 1000);
const why = await done;
clearTimeout(timer);
if (why === 'timeout') {
  const missing = Object.keys(expected).filter((t) => !seen.has(t));
  fail(`in ${timeoutS} s no message on ${missing.join(', ') || '(none missing)'}; services: ${[...services.keys()].join(', ')}`);
} else {
  log(`ok serverInfo ${serverInfo?.name} capabilities ${serverInfo?.capabilities.join(',')}`);
  log(`ok ${channels.size} channels; typed messages on ${Object.keys(expected).join(', ')}`);
  for (const c of [...channels.values()].sort((a, b) => a.topic.localeCompare(b.topic))) {
    log(`   ${c.topic} ${c.schemaName} ${seen.get(c.topic) ?? 0} messages`);
  }
  if (!serverInfo?.capabilities.includes('services') || !serverInfo?.capabilities.includes('parameters')) {
    fail(`capabilities ${serverInfo?.capabilities}`);
  }
  // A service through rack-gui (the chassis is on already: ON again is answered ok).
  const on = await call('/rack/0/chassis/switch', { on: true });
  if (on.response?.ok === true) log(`ok /rack/0/chassis/switch: ${on.response.text}`);
  else fail(`/rack/0/chassis/switch: ${JSON.stringify(on)}`);
  // A call that is not JSON is refused with a reason, and the bridge goes on.
  const bad = await call('/rack/0/chassis/switch', null, new Uint8Array([0x7b, 0xff, 0x00]));
  if (typeof bad.failure === 'string' && bad.failure.includes('not JSON')) log(`ok malformed call refused: ${bad.failure}`);
  else fail(`malformed call: ${JSON.stringify(bad)}`);
  // A value rack-gui refuses (a coordinate out of range) comes back as ok:false.
  const far = await call('/rack/0/set_destination', { x: 1e9, y: 0 });
  if (far.response?.ok === false) log(`ok set_destination out of range refused: ${far.response.text}`);
  else fail(`set_destination x=1e9: ${JSON.stringify(far)}`);
  // A class command from the class description (MCL's INIT, at the pose MCL has now),
  // and one whose body names a field INIT does not have: refused, nothing sent.
  if (!services.has('/rack/0/mcl/INIT')) {
    fail(`no service /rack/0/mcl/INIT: ${[...services.keys()].join(', ')}`);
  } else {
    const schema = JSON.parse(services.get('/rack/0/mcl/INIT').request?.schema ?? '{}');
    if (!schema.properties?.sigma_xy) fail(`/rack/0/mcl/INIT request schema ${JSON.stringify(schema)}`);
    const init = await call('/rack/0/mcl/INIT', { x: lastMclPose.x, y: lastMclPose.y, phi: lastMclPose.phi, sigma_xy: 0.1, sigma_phi: 0.05 });
    if (init.response?.ok === true) log(`ok /rack/0/mcl/INIT: ${init.response.text}`);
    else fail(`/rack/0/mcl/INIT: ${JSON.stringify(init)}`);
    const wrong = await call('/rack/0/mcl/INIT', { speed: 1 });
    if (wrong.response?.ok === false && wrong.response.text.includes("field 'speed'")) log(`ok INIT with an unknown field refused: ${wrong.response.text}`);
    else fail(`/rack/0/mcl/INIT {speed}: ${JSON.stringify(wrong)}`);
  }
  // Hostile input from another client: not JSON, a subscription to no channel, a
  // truncated and an unknown binary message, a parameter of the wrong type. Each is
  // refused (statuses come back), and the bridge goes on serving this client.
  const statuses = [];
  await new Promise((resolve) => {
    const raw = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
    raw.on('open', () => {
      raw.send('{not json');
      raw.send(JSON.stringify({ op: 'subscribe', subscriptions: [{ id: 1, channelId: 999999 }] }));
      raw.send(Buffer.from([2, 0, 0, 0, 0, 1, 2]));
      raw.send(Buffer.from([9, 9, 9]));
      raw.send(JSON.stringify({ op: 'setParameters', parameters: [{ name: 'Pilot(0/0).vx_max', value: 'fast' }], id: 'bad' }));
    });
    raw.on('message', (d, binary) => {
      if (binary) return;
      const m = JSON.parse(d.toString());
      if (m.op === 'status') statuses.push(m.message);
      if (m.op === 'parameterValues' && m.id === 'bad') {
        raw.close();
        resolve();
      }
    });
    setTimeout(resolve, 10000);
  });
  if (statuses.some((t) => t.includes("'vx_max' (float): expected a number")) && statuses.some((t) => t.includes('999999'))) {
    log(`ok hostile client refused with ${statuses.length} statuses`);
  } else {
    fail(`hostile client: statuses ${JSON.stringify(statuses)}`);
  }
  // Full rate: the chassis publishes at 100 Hz, the ladar at 25 Hz (configs/sim_mcl.yaml);
  // rack-gui's poll would give 5 Hz. Over 2 s, and the chassis' sequence numbers in a row.
  {
    const ladar0 = seen.get('/rack/0/ladar/scan') ?? 0;
    const chassisFrom = chassisSequences.length;
    const t = Date.now();
    await new Promise((r) => { setTimeout(r, 2000); });
    const s = (Date.now() - t) / 1000;
    const ladarHz = ((seen.get('/rack/0/ladar/scan') ?? 0) - ladar0) / s;
    const seqs = chassisSequences.slice(chassisFrom);
    const gaps = seqs.filter((q, i) => i > 0 && q !== seqs[i - 1] + 1).length;
    const chassisHz = seqs.length / s;
    const line = `ladar/scan ${ladarHz.toFixed(1)} Hz, chassis ${chassisHz.toFixed(1)} Hz (${seqs.length} samples, ${gaps} gap(s) in their sequence)`;
    if (ladarHz > 15 && chassisHz > 60 && gaps === 0) log(`ok full rate: ${line}`);
    else fail(`not the full rate: ${line}`);
  }
  const countBefore = [...seen.values()].reduce((a, b) => a + b, 0);
  await new Promise((r) => { setTimeout(r, 1500); });
  const countAfter = [...seen.values()].reduce((a, b) => a + b, 0);
  if (countAfter > countBefore) log(`ok still served after it: ${countAfter - countBefore} messages in 1.5 s`);
  else fail('no message after the hostile client');
  // Parameters: the host file's value, then set and read back.
  const got = await params(['Chassis(0/0).vx_max'], 'get1');
  const vx = got?.find((p) => p.name === 'Chassis(0/0).vx_max');
  if (vx && vx.value === 1.0) log('ok parameter Chassis(0/0).vx_max = 1 (host file)');
  else fail(`parameter Chassis(0/0).vx_max: ${JSON.stringify(got)}`);
  const setDone = waitParams('set1');
  client.setParameters([{ name: 'Pilot(0/0).vx_max', value: 0.35 }], 'set1');
  const after = await setDone;
  const pv = after?.find((p) => p.name === 'Pilot(0/0).vx_max');
  if (pv && Math.abs(pv.value - 0.35) < 1e-9) log('ok parameter Pilot(0/0).vx_max set to 0.35 and read back');
  else fail(`set Pilot(0/0).vx_max: ${JSON.stringify(after)}`);
}
client.close();
log(failed ? 'FAILED' : 'all checks passed');
process.exit(failed ? 1 : 0);
