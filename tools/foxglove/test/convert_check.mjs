// Checks of the converter (lib/convert.mjs) on rack-gui's "components" and "class"
// messages in the order rack-gui sends them to a client that connected before a host's
// classes were described: each component listed under its class number first
// (Class0x11(0/0)), then, once the description has come, under its class name
// (Ladar(0/0)). Run by tests/integration/foxglove_test.cpp
// (FoxgloveTest.ConverterTakesEachComponentsMessageAsTheWholeList), or by hand:
//
//   node test/convert_check.mjs
//
// Exit status 0 when every check passed ("all checks passed"), 1 otherwise.
import { Converter } from '../lib/convert.mjs';

const failures = [];
const check = (ok, what) => {
  console.log(`${ok ? 'ok' : 'FAILED'}: ${what}`);
  if (!ok) failures.push(what);
};

// One robot, one host, the ladar of configs/replay_mcap_mcl.yaml under `cls`.
const components = (cls, state = 'enabled') => ({
  type: 'components',
  robots: [{ system: 0, joystick: false, hosts: [{ key: 'replay-mcap-mcl#0/0', host: 'replay-mcap-mcl', components: [
    { address: `${cls}(0/0)`, name: 'ladar', class: cls, impl: 'LadarPlayback', state },
  ] }] }],
});
const ladarClass = {
  type: 'class', system: 0, class_id: 0x11, class: 'Ladar', impl: 'LadarPlayback', summary: 'playback',
  data: { name: 'LadarData', size: 16, fields: [{ name: 'start_angle', kind: 'f32', count: 1 }] },
  commands: [{ name: 'PUBLISH', type: 21, summary: 'a sample', body: null }], parameters: [],
};

const c = new Converter();
c.convert(components('Class0x11', 'no_reply'));
check(c.components.size === 1 && c.components.has('Class0x11(0/0)'), 'the ladar listed under its class number first');
c.convert(ladarClass);
c.convert(components('Ladar'));
const listed = [...c.components.values()];
check(listed.length === 1 && listed[0].address === 'Ladar(0/0)' && listed[0].state === 'enabled',
      `once described, the ladar is listed once, under its class name (listed: ${listed.map((x) => x.address).join(', ')})`);
const first = listed.find((x) => x.name === 'ladar');
check(c.classOf(first.system, first.class)?.commands.some((k) => k.name === 'PUBLISH') === true,
      'the first component named ladar has its class description, with PUBLISH');

// A list without a component empties it (a host that left rack-gui's list).
c.convert({ type: 'components', robots: [] });
check(c.components.size === 0, 'an empty list leaves no component');

// Malformed lists are skipped, never thrown.
for (const [what, m] of [
  ['hosts not an array', { type: 'components', robots: [{ system: 0, hosts: 5 }] }],
  ['components not an array', { type: 'components', robots: [{ system: 0, hosts: [{ components: 'ladar' }] }] }],
  ['a robot that is null', { type: 'components', robots: [null] }],
  ['robots not an array', { type: 'components', robots: {} }],
]) {
  try {
    c.convert(m);
    check(true, `${what}: skipped`);
  } catch (e) {
    check(false, `${what}: threw ${e.message}`);
  }
}

if (failures.length > 0) {
  console.log(`${failures.length} check(s) failed`);
  process.exit(1);
}
console.log('all checks passed');
