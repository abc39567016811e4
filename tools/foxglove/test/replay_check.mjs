// Compares MCL's localisation on a replay with the recording's (driven by
// tests/integration/foxglove_test.cpp): both MCAP files are read with the npm MCAP
// reader; each MCL estimate of the replay (channel /rack/0/mcl, its scan_time_ns) is
// compared with the recorded MCL pose at the same scan time (linear between the two
// recorded estimates around it) and, where the recording has the chassis, with the
// simulator's true pose there.
//
// usage: node replay_check.mjs RECORDED.mcap REPLAYED.mcap [--topic /rack/0/mcl]
//          [--max-xy M] [--max-phi RAD] [--min-compared N]
// Prints the figures; exit status 0 when every compared estimate is within the bounds.
import { openMcap } from '../lib/player.mjs';

const args = process.argv.slice(2);
const [recordedFile, replayedFile] = args;
const arg = (name, def) => {
  const i = args.indexOf(name);
  return i >= 0 && i + 1 < args.length ? args[i + 1] : def;
};
const topic = arg('--topic', '/rack/0/mcl');
const maxXy = Number(arg('--max-xy', '0.25'));
const maxPhi = Number(arg('--max-phi', '0.10'));
const minCompared = Number(arg('--min-compared', '10'));
if (!recordedFile || !replayedFile) {
  console.log('usage: node replay_check.mjs RECORDED.mcap REPLAYED.mcap [--max-xy M] [--max-phi RAD] [--min-compared N]');
  process.exit(2);
}

async function samples(file, t) {
  const r = await openMcap(file);
  const out = [];
  for await (const m of r.readMessages({ topics: [t] })) out.push(JSON.parse(new TextDecoder().decode(m.data)));
  return out;
}

const wrap = (a) => Math.atan2(Math.sin(a), Math.cos(a));
// The pose at time t between the samples (sorted by key) that surround it, or null.
function at(list, key, t, fx, fy, fphi) {
  let i = list.findIndex((s) => key(s) >= t);
  if (i < 0) return null;
  if (key(list[i]) === t) return { x: fx(list[i]), y: fy(list[i]), phi: fphi(list[i]) };
  if (i === 0) return null;
  const a = list[i - 1];
  const b = list[i];
  const w = (t - key(a)) / (key(b) - key(a));
  return { x: fx(a) + w * (fx(b) - fx(a)), y: fy(a) + w * (fy(b) - fy(a)), phi: fphi(a) + w * wrap(fphi(b) - fphi(a)) };
}

const recorded = (await samples(recordedFile, topic)).filter((s) => s.data.scan_time_ns > 0 && s.data.updates > 0);
const replayed = (await samples(replayedFile, topic)).filter((s) => s.data.scan_time_ns > 0);
const chassis = await samples(recordedFile, topic.replace(/[^/]+$/, 'chassis')).catch(() => []);
recorded.sort((a, b) => a.data.scan_time_ns - b.data.scan_time_ns);
const truthList = chassis.filter((s) => s.data.truth_valid);

const errs = [];
const truthErrRec = [];
const truthErrRep = [];
let failed = false;
const seen = new Set();
for (const s of replayed) {
  const t = s.data.scan_time_ns;
  if (seen.has(t)) continue;  // rack-gui polled the same estimate twice
  seen.add(t);
  const ref = at(recorded, (r) => r.data.scan_time_ns, t, (r) => r.data.x, (r) => r.data.y, (r) => r.data.phi);
  if (!ref) continue;
  const dxy = Math.hypot(s.data.x - ref.x, s.data.y - ref.y);
  const dphi = Math.abs(wrap(s.data.phi - ref.phi));
  errs.push({ t, dxy, dphi });
  if (dxy > maxXy || dphi > maxPhi) {
    console.log(`FAILED at scan time ${t}: replay (${s.data.x.toFixed(3)}, ${s.data.y.toFixed(3)}, ${s.data.phi.toFixed(3)}) ` +
                `recorded (${ref.x.toFixed(3)}, ${ref.y.toFixed(3)}, ${ref.phi.toFixed(3)}): ${dxy.toFixed(3)} m, ${dphi.toFixed(3)} rad`);
    failed = true;
  }
  const truth = at(truthList, (c) => c.time_ns, t, (c) => c.data.truth_x, (c) => c.data.truth_y, (c) => c.data.truth_phi);
  if (truth) {
    truthErrRep.push(Math.hypot(s.data.x - truth.x, s.data.y - truth.y));
    truthErrRec.push(Math.hypot(ref.x - truth.x, ref.y - truth.y));
  }
}
const stats = (v) => {
  if (v.length === 0) return 'none';
  const s = [...v].sort((a, b) => a - b);
  return `mean ${(s.reduce((a, b) => a + b, 0) / s.length).toFixed(3)}, median ${s[Math.floor(s.length / 2)].toFixed(3)}, max ${s[s.length - 1].toFixed(3)}`;
};
console.log(`recorded MCL estimates ${recorded.length}, replayed ${replayed.length}, compared ${errs.length}`);
console.log(`replay vs recorded MCL: position (m) ${stats(errs.map((e) => e.dxy))}; heading (rad) ${stats(errs.map((e) => e.dphi))}`);
console.log(`bounds: ${maxXy} m, ${maxPhi} rad`);
if (truthErrRep.length > 0) {
  console.log(`against the simulator's true pose (m): replay ${stats(truthErrRep)}; recording ${stats(truthErrRec)}`);
}
if (errs.length < minCompared) {
  console.log(`FAILED only ${errs.length} estimates compared, expected at least ${minCompared}`);
  failed = true;
}
console.log(failed ? 'FAILED' : 'all checks passed');
process.exit(failed ? 1 : 0);
