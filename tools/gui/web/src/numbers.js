// Numbers for people (issue 21 item 5) in the dashboard: a unit from the field's name
// (the interfaces' convention: metres, radians, m/s, rad/s, volts, nanoseconds),
// sensible precision, angles in degrees, durations in the unit that fits, and enums
// and addresses by the name rack-gui sends beside the raw value ("names", as
// `rackctl get-data`). The raw value stays visible in brackets where a name replaces it.

// [test, unit]: the first whose pattern matches the field's name.
const UNITS = [
  [/(^|_)var_phi$/, 'rad²'],
  [/(^|_)var_(x|y)$/, 'm²'],
  [/_ns$/, 'ns'],
  [/(^|_)(phi|angle|yaw|bearing|heading)$|^start_angle$|^angle_step$/, 'rad'],
  [/(^|_)omega(_max)?$/, 'rad/s'],
  [/(^|_)(vx|vy|vx_max|vx_min|speed|speed_limit)$/, 'm/s'],
  [/(^|_)(acc_max|dec_max)$/, 'm/s²'],
  [/^battery$/, 'V'],
  [/(^|_)(x|y|z|distance|length|range|max_range|min_range|margin|radius|error|distance_to_target|obstacle_distance)$|^boundary_|^pose_(x|y)$|^target_(x|y)$|^truth_(x|y)$|^delta_(x|y)$/, 'm'],
];

export function unitOf(field) {
  for (const [re, unit] of UNITS) if (re.test(field)) return unit;
  return '';
}

// At most `digits` significant digits, no trailing zeros, no exponent for the usual
// magnitudes: 0.8, 12.35, 1234.6, 0.000123.
export function num(v, digits = 4) {
  if (!Number.isFinite(v)) return String(v);
  if (Number.isInteger(v)) return String(v);
  const a = Math.abs(v);
  if (a >= 1e6 || (a > 0 && a < 1e-4)) return v.toExponential(2);
  const decimals = Math.max(0, digits - 1 - Math.floor(Math.log10(a || 1)));
  return String(Number(v.toFixed(Math.min(decimals, 6))));
}

// A duration in nanoseconds as text in the unit that fits: 850 ns, 12.3 us, 4.56 ms, 1.2 s.
export function duration(ns) {
  const a = Math.abs(ns);
  if (a < 1e3) return `${num(ns, 3)} ns`;
  if (a < 1e6) return `${num(ns / 1e3, 3)} us`;
  if (a < 1e9) return `${num(ns / 1e6, 3)} ms`;
  return `${num(ns / 1e9, 4)} s`;
}

// One value of field `field` as text, with `names` (rack-gui's "names" object).
export function formatField(field, v, names) {
  const name = names && Object.prototype.hasOwnProperty.call(names, field) ? names[field] : null;
  if (name !== null) return `${name} (${v})`;
  if (typeof v !== 'number') return String(v);
  const unit = unitOf(field);
  if (unit === 'rad') return `${num(v * 180 / Math.PI, 4)}° (${num(v, 4)} rad)`;
  if (unit === 'ns') return duration(v);
  if (Number.isInteger(v) && !unit) return String(v);
  // Lengths to the millimetre, speeds to the cm/s, others to 4 significant digits.
  if (unit === 'm') return `${Number(v.toFixed(3))} m`;
  if (unit === 'm/s' || unit === 'V') return `${Number(v.toFixed(2))} ${unit}`;
  return unit ? `${num(v)} ${unit}` : num(v);
}

// Arrays: the first few values, then how many there are.
export function formatArray(field, arr) {
  const unit = unitOf(field);
  const f = (v) => (typeof v === 'number' ? num(v) : String(v));
  const body = arr.length > 12 ? `${arr.slice(0, 8).map(f).join(', ')}, … ${arr.length} values` : arr.map(f).join(', ');
  return `[${body}]${unit ? ' ' + unit : ''}`;
}
