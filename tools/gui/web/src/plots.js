// Plots tab (issue 21 item 4): live time series of any numeric field of any
// component, drawn with uPlot (a small canvas plotting library made for streaming
// data). The fields offered are those of the component's data type as its class
// describes itself (GET_CLASS, through rack-gui's "class" message): scalar numbers,
// not padding. Each plot keeps the last `window` seconds of the samples rack-gui
// polls (every 200 ms for the navigation classes, every second for the others); a
// sample is added once (by its sequence number), at the time the page received it.
import uPlot from 'uplot';
import 'uplot/dist/uPlot.min.css';
import { unitOf, num } from './numbers.js';

const NUMERIC = new Set(['i8', 'u8', 'bool', 'i16', 'u16', 'i32', 'u32', 'i64', 'u64', 'f32', 'f64']);
const MAX_PLOTS = 8;
const MAX_POINTS = 3000;  // per plot: 5 Hz for 10 minutes

// Numeric scalar fields of a class message's data type.
export function numericFields(cls) {
  if (!cls || !cls.data) return [];
  return cls.data.fields.filter((f) => NUMERIC.has(f.kind) && f.count === 1 && !f.name.endsWith('_')).map((f) => f.name);
}

export function setupPlots({ st, send, $ }) {
  const plots = [];  // {component, field, xs, ys, lastSeq, chart, el, stale}
  st.plots = plots;
  let windowS = 60;

  const compSel = $('pl-comp'), fieldSel = $('pl-field'), root = $('plots');

  function refreshComponents() {
    const want = [...st.comps.values()].map((c) => c.address);
    const have = [...compSel.options].map((o) => o.value);
    if (want.join() === have.slice(1).join()) return;
    const cur = compSel.value;
    compSel.replaceChildren(new Option('component…', ''), ...[...st.comps.values()].map((c) => new Option(`${c.name} ${c.address}`, c.address)));
    if (want.includes(cur)) compSel.value = cur;
  }
  function refreshFields() {
    const a = compSel.value;
    const cls = st.classes.get(a);
    if (a && !cls) {
      fieldSel.replaceChildren(new Option('asking its class…', ''));
      send({ op: 'get_class', component: a });
      return;
    }
    const fields = numericFields(cls);
    fieldSel.replaceChildren(...(fields.length ? fields.map((f) => new Option(unitOf(f) ? `${f} (${unitOf(f)})` : f, f))
      : [new Option(a ? 'no numeric fields' : 'field…', '')]));
  }
  compSel.onchange = refreshFields;
  $('pl-window').onchange = (e) => { const v = Number(e.target.value); if (v > 0) windowS = v; };
  $('pl-add').onclick = () => add(compSel.value, fieldSel.value);

  function add(component, field) {
    if (!component || !field) return;
    if (plots.some((p) => p.component === component && p.field === field)) return;
    if (plots.length >= MAX_PLOTS) plots.shift().el.remove();
    const c = st.comps.get(component);
    const el = document.createElement('div');
    el.className = 'plotbox';
    el.dataset.testid = `plot-${c ? c.name : component}-${field}`;
    const head = document.createElement('div');
    head.className = 'plothead';
    const title = document.createElement('span');
    const unit = unitOf(field);
    title.textContent = `${c ? c.name : component} ${field}${unit ? ` [${unit}]` : ''}`;
    const value = document.createElement('span');
    value.className = 'plotvalue';
    const close = document.createElement('button');
    close.textContent = '×';
    close.title = 'remove this plot';
    head.append(title, value, close);
    const body = document.createElement('div');
    el.append(head, body);
    root.appendChild(el);
    const p = { component, field, xs: [], ys: [], lastSeq: null, el, body, value, chart: null };
    close.onclick = () => { el.remove(); plots.splice(plots.indexOf(p), 1); };
    p.chart = new uPlot({
      width: Math.max(200, body.clientWidth || root.clientWidth - 20),
      height: 160,
      legend: { show: false },
      scales: { x: { time: true } },
      series: [{}, { label: field, stroke: '#1565c0', width: 1.5, points: { show: false } }],
      axes: [{}, { size: 60, values: (u, vals) => vals.map((v) => num(v, 3)) }],
    }, [[], []], body);
    plots.push(p);
    // The last sample already received starts the plot.
    const d = st.data.get(component);
    if (d) onData(d);
    $('pl-empty').hidden = true;
  }

  function onData(m) {
    for (const p of plots) {
      if (p.component !== m.component || p.lastSeq === m.sequence) continue;
      const v = m.data[p.field];
      if (typeof v !== 'number' && typeof v !== 'boolean') continue;
      p.lastSeq = m.sequence;
      const t = Date.now() / 1000;
      p.xs.push(t);
      p.ys.push(Number(v));
      const cut = t - windowS;
      let drop = 0;
      while (drop < p.xs.length && p.xs[drop] < cut) drop++;
      if (p.xs.length - drop > MAX_POINTS) drop = p.xs.length - MAX_POINTS;
      if (drop) { p.xs.splice(0, drop); p.ys.splice(0, drop); }
      const unit = unitOf(p.field);
      p.value.textContent = `${num(Number(v))}${unit ? ' ' + unit : ''}`;
      if (p.el.offsetParent) p.chart.setData([p.xs, p.ys]);
    }
  }

  // A plot whose component sends nothing any more says so (never a flat line as if live).
  setInterval(() => {
    for (const p of plots) {
      const d = st.data.get(p.component);
      const stale = !st.connected || !d || performance.now() - d.received > 2500;
      p.el.classList.toggle('stale', stale);
      if (stale) p.value.textContent = 'no new samples';
    }
  }, 500);

  function resize() {
    for (const p of plots) {
      const w = p.body.clientWidth;
      if (w > 0 && Math.abs(w - p.chart.width) > 2) p.chart.setSize({ width: w, height: 160 });
      p.chart.setData([p.xs, p.ys]);
    }
  }
  window.addEventListener('resize', resize);

  return {
    onData,
    onComponents: refreshComponents,
    onClass(m) { if (m.component === compSel.value) refreshFields(); },
    show() { refreshComponents(); resize(); },
    add,
  };
}
