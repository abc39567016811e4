// RACK-RT dashboard: talks to rack-gui over one WebSocket (/ws). The protocol is
// described in tools/gui/gui_protocol.h. No framework: the page is a handful of
// panels redrawn from the latest messages; the map is one 2-D canvas redrawn per
// animation frame with particles batched into one path.
import './style.css';
import { setupTimeline } from './timeline.js';
import { setupPlots } from './plots.js';
import { setupCommands } from './commands.js';
import { setupMapTools } from './map_tools.js';
import { formatField, formatArray, duration } from './numbers.js';
import { setupConfig } from './config/config.js';

const $ = (id) => document.getElementById(id);
const LEVELS = ['print', 'error', 'warning', 'info', 'detail'];
const STATE_TEXT = { enabled: 'ON', disabled: 'OFF', error: 'ERROR', no_reply: 'no reply', not_available: 'not available' };

const st = {
  ws: null,
  connected: false,
  nextId: 1,
  robots: [],            // from "components"
  comps: new Map(),      // address -> component (with system, host)
  data: new Map(),       // address -> latest data message
  maps: new Map(),       // system -> {meta, canvas}
  params: new Map(),     // address -> params list
  classes: new Map(),    // address -> its class description ("class" message)
  images: new Map(),     // camera address -> latest "image" message
  selected: null,        // address shown in the details view
  selectedKey: null,     // its robot|host|name: followed when rack-gui renames its address
  log: [],               // GDOS records
  reports: [],           // mode-switch / crash reports from GDOS
  reportFiles: [],       // report files symbolized by rack-backtrace
  hosts: new Set(),
  view: { system: null, scale: 0, ox: 0, oy: 0, fitted: false },
};
window.__rack = st;  // for debugging and the end-to-end test

// ---------------------------------------------------------------- connection
function connect() {
  const ws = new WebSocket(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws`);
  st.ws = ws;
  ws.onopen = () => { st.connected = true; st.componentsSeen = false; setConn(); };
  ws.onclose = () => {
    st.connected = false;
    setConn();
    // Never show a last state as if it were current: without the server, nothing is known.
    for (const c of st.comps.values()) c.state = 'no_reply';
    st.componentsKey = null;
    renderComponents();
    setTimeout(connect, 1000);
  };
  ws.onmessage = (ev) => {
    let m;
    try { m = JSON.parse(ev.data); } catch { notice('bad message from rack-gui', false); return; }
    handle(m);
  };
}
// Green only when a robot answers: rack-gui being there is not the robot being there.
function setConn() {
  const el = $('conn');
  let text, cls;
  if (!st.connected) {
    text = 'rack-gui disconnected: reconnecting…'; cls = 'down';
  } else {
    const all = [...st.comps.values()];
    const answering = all.filter((c) => c.state !== 'no_reply' && c.state !== 'not_available');
    const robots = new Set(answering.map((c) => c.system));
    if (all.length === 0) { text = st.componentsSeen ? 'no robot found (yet)' : 'connected to rack-gui; looking for robots…'; cls = 'warn'; }
    else if (answering.length === 0) { text = 'no robot answering'; cls = 'down'; }
    else { text = `${robots.size} robot${robots.size === 1 ? '' : 's'} answering (${answering.length}/${all.length} components)`; cls = answering.length === all.length ? 'up' : 'warn'; }
  }
  el.textContent = text;
  el.className = 'conn ' + cls;
  el.dataset.state = cls;
}
function send(obj) {
  if (!st.ws || st.ws.readyState !== 1) { notice('not connected to rack-gui', false); return null; }
  const id = st.nextId++;
  st.ws.send(JSON.stringify({ ...obj, id }));
  return id;
}
// Raw text, for the test of malformed input.
st.sendRaw = (text) => st.ws.send(text);

let noticeTimer = null;
const notices = [];
st.notices = notices;
function notice(text, ok) {
  const el = $('notice');
  el.textContent = text;
  el.className = ok ? 'good' : 'bad';
  notices.push({ text, ok, time: Date.now() });
  if (notices.length > 100) notices.shift();
  clearTimeout(noticeTimer);
  noticeTimer = setTimeout(() => { el.textContent = ''; }, ok ? 4000 : 10000);
}

function handle(m) {
  switch (m.type) {
    case 'hello': st.lcm = m.lcm; break;
    case 'class':
      if (!m.component) break;  // broadcast per class for other programs (the Foxglove bridge)
      st.classes.set(m.component, m);
      plots.onClass(m);
      if (st.selected === m.component && document.querySelector('#view-details.active')) renderDetails();
      break;
    case 'command_result': commands.onCommandResult(m); break;
    case 'trace':
      if (drawTimeline.load) drawTimeline.load(m.json, `live trace of host ${m.host}`);
      $('tl-record').disabled = false;
      break;
    case 'components': onComponents(m); break;
    case 'data': onData(m); break;
    case 'map': onMap(m); break;
    case 'image':
      st.images.set(m.component, m);
      if (st.selected === m.component && document.querySelector('#view-details.active')) drawCamera();
      break;
    case 'gdos': onGdos(m.records); break;
    case 'params': st.params.set(m.component, m.params); if (st.selected === m.component) renderDetails(); break;
    case 'result':
      commands.onResult(m);
      if (m.op === 'get_class' && !m.ok && $('d-commands')) $('d-commands').innerHTML = `<h3>Commands</h3><p class="empty">${esc(m.text)}</p>`;
      if (m.op === 'trace' && !m.ok) { $('tl-record').disabled = false; $('tl-info').textContent = `trace: ${m.text}`; $('tl-info').className = 'bad'; }
      if (!(m.ok && m.op === 'joystick') && !(m.ok && m.op === 'get_class')) notice(`${m.op}: ${m.text}`, m.ok);
      break;
    case 'error': notice(`refused: ${m.error}`, false); break;
    case 'reports':
      st.reportFiles = m.reports;
      st.reportDir = m.dir;
      if (document.querySelector('#view-reports.active')) renderReports();
      break;
    case 'notice': notice(m.text, m.level !== 'error' && m.level !== 'warning'); break;
    case 'config': config.handle(m); break;
    default: break;
  }
}

// ---------------------------------------------------------------- components
function onComponents(m) {
  st.robots = m.robots;
  st.comps.clear();
  for (const r of m.robots) {
    for (const h of r.hosts) {
      for (const c of h.components) st.comps.set(c.address, { ...c, system: r.system, host: h.host, hostKey: h.key });
    }
  }
  // rack-gui lists a component under its class number (Class0x19(0/0)) until its class
  // description comes, and under its class name (Pilot(0/0)) after: a component chosen
  // before that stays chosen under its new address (else its view and command panel
  // never came: GuiE2eTest.DashboardPanelsInChromium under CI load).
  if (st.selected && !st.comps.has(st.selected) && st.selectedKey) {
    const moved = [...st.comps.values()].find((c) => componentKey(c) === st.selectedKey);
    if (moved) {
      st.selected = moved.address;
      send({ op: 'get_params', component: moved.address });
    }
  }
  // Redrawn only when something shown changed: a redraw between mouse-down and
  // mouse-up would swallow the click.
  const key = JSON.stringify(m.robots.map((r) => [r.system, r.joystick, r.hosts.map((h) => [h.key, h.alive, Math.round((h.silent_ms ?? 0) / 1000), h.pid, h.components.map((c) => [c.address, c.name, c.state])])]));
  if (key !== st.componentsKey || !st.connected) {
    st.componentsKey = key;
    renderComponents();
  }
  // A few rounds without any component: nothing answers on this network.
  st.emptyRounds = m.robots.length === 0 ? (st.emptyRounds ?? 0) + 1 : 0;
  st.componentsSeen = st.emptyRounds > 10;
  setConn();
  plots.onComponents();
  updateRobotSelect();
  updateGdosTargets();
  if (st.selected && document.querySelector('#view-details.active')) renderDetails();
}

function renderComponents() {
  const root = $('components');
  const frag = document.createDocumentFragment();
  if (st.robots.length === 0) {
    const p = document.createElement('div');
    p.className = 'empty';
    p.dataset.testid = 'no-robots';
    p.textContent = !st.connected ? 'Not connected to rack-gui: nothing is known about the robots.'
      : `No robot answers on ${st.lcm ?? 'this network'}. Is rackd running there, with "lcm: true" in its host file, and does rack-gui listen on the same URL (--lcm)?`;
    frag.appendChild(p);
  }
  for (const r of st.robots) {
    const div = document.createElement('div');
    div.className = 'robot';
    div.dataset.system = r.system;
    const h3 = document.createElement('h3');
    h3.textContent = `Robot ${r.system}${r.joystick ? ' (joystick)' : ''}`;
    const off = document.createElement('button');
    off.textContent = 'all off';
    off.dataset.testid = `all-off-${r.system}`;
    off.onclick = () => { if (confirm(`Switch off every component of robot ${r.system}?`)) send({ op: 'all_off', system: r.system }); };
    h3.appendChild(off);
    div.appendChild(h3);
    for (const h of r.hosts) {
      const hd = document.createElement('div');
      hd.className = 'host' + (h.alive === false ? ' lost' : '');
      const h4 = document.createElement('h4');
      const silent = h.alive === false && h.silent_ms !== undefined
        ? ` for ${Math.round(h.silent_ms / 1000)} s${h.forget_ms >= 0 ? ` (leaves the list after ${Math.round(h.forget_ms / 1000)} s)` : ''}` : '';
      h4.textContent = `${h.host ?? h.key} ${h.pid ? `(pid ${h.pid})` : ''}${h.alive === false ? `: NOT ANSWERING${silent}` : ''}`;
      hd.appendChild(h4);
      for (const c of h.components) {
        const state = st.connected ? (st.comps.get(c.address)?.state ?? c.state) : 'no_reply';
        const row = document.createElement('div');
        row.className = `comp state-${state}`;
        row.dataset.testid = `comp-${c.name}`;
        row.dataset.address = c.address;
        row.dataset.state = state;
        const t = document.createElement('button');
        t.className = 'toggle';
        t.textContent = STATE_TEXT[state] ?? state;
        t.title = state === 'enabled' || state === 'error' ? 'click: switch off' : state === 'disabled' ? 'click: switch on' : 'not answering';
        t.dataset.testid = `toggle-${c.name}`;
        t.onclick = () => {
          if (state === 'enabled' || state === 'error') send({ op: 'switch', component: c.address, on: false });
          else if (state === 'disabled') send({ op: 'switch', component: c.address, on: true });
        };
        const n = document.createElement('span');
        n.className = 'name';
        n.innerHTML = `${esc(c.name)} <span class="cls">${esc(c.class)}${c.impl ? '(' + esc(c.impl) + ')' : ''} ${esc(c.address)}</span>`;
        n.onclick = () => selectComponent(c.address);
        row.append(t, n);
        hd.appendChild(row);
      }
      div.appendChild(hd);
    }
    frag.appendChild(div);
  }
  root.replaceChildren(frag);
}
function esc(s) { return String(s).replace(/[&<>"]/g, (ch) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[ch])); }

// ---------------------------------------------------------------- tabs
function showView(name) {
  for (const b of document.querySelectorAll('#tabs button')) b.classList.toggle('active', b.dataset.view === name);
  for (const v of document.querySelectorAll('.view')) v.classList.toggle('active', v.id === `view-${name}`);
  if (name === 'details') renderDetails();
  if (name === 'reports') renderReports();
  if (name === 'gdos') renderGdos(true);
  if (name === 'map') resizeMap();
  if (name === 'timeline') drawTimeline();
  if (name === 'plots') plots.show();
  if (name === 'config') config.show();
}
const drawTimeline = setupTimeline() ?? (() => {});
const config = setupConfig(send);  // the Configuration view (src/config/): adds its tab
const plots = setupPlots({ st, send, $ });
const commands = setupCommands({ st, send });
st.addPlot = (component, field) => plots.add(component, field);
st.timeline = drawTimeline;
// A live trace (issue 20): rack-gui asks the host's executor, as `rackctl trace` does.
$('tl-record').onclick = () => {
  const seconds = Number($('tl-seconds').value);
  const system = Number($('tl-system').value);
  if (!(seconds > 0 && seconds <= 10) || !Number.isInteger(system)) { notice('trace: 0 < seconds <= 10 and a robot number', false); return; }
  if (send({ op: 'trace', system, host: $('tl-host').value.trim(), duration_s: seconds }) !== null) {
    $('tl-record').disabled = true;
    $('tl-info').textContent = `recording ${seconds} s of robot ${system}…`;
  }
};
for (const b of document.querySelectorAll('#tabs button')) b.onclick = () => showView(b.dataset.view);

// ---------------------------------------------------------------- details: parameters, timing, class views
// A component's identity across the address renames of onComponents: its robot, host and name.
function componentKey(c) { return `${c.system}|${c.hostKey}|${c.name}`; }
function selectComponent(address) {
  st.selected = address;
  const c = st.comps.get(address);
  st.selectedKey = c ? componentKey(c) : null;
  send({ op: 'get_params', component: address });
  showView('details');
}

// The component view is built once per component (and again when its parameters
// arrive); the live parts (state, timing, data, plots) are refreshed in place, so a
// click on a "set" button or typing in a field is never lost to a redraw.
function renderDetails() {
  const root = $('details');
  const c = st.comps.get(st.selected);
  if (!c) return;
  const params = st.params.get(c.address);
  const key = `${c.address}|${JSON.stringify(params ?? null)}|${st.classes.has(c.address)}`;
  if (root.dataset.key !== key) {
    root.dataset.key = key;
    const parts = ['<h2 id="d-head"></h2><div id="d-timing"></div>'];
    if (c.class === 'Camera') parts.push('<h3>Image</h3><p class="hint" id="camera-info">no image yet (polled once a second while the camera is ON)</p><canvas id="camera" class="plot" data-testid="camera" width="320" height="240"></canvas>');
    if (c.class === 'Ladar' || c.class === 'Scan2D') parts.push('<h3>Scan (polar)</h3><canvas id="polar" class="plot" width="360" height="360" data-testid="polar"></canvas>');
    parts.push('<div id="d-data"></div><div id="d-commands" data-testid="commands"></div>');
    if (params) {
      parts.push('<h3>Parameters</h3><table class="kv" data-testid="params"><tr><th>name</th><th>kind</th><th>value</th><th></th></tr>');
      for (const p of params) {
        const input = p.kind === 'bool'
          ? `<input type="checkbox" ${p.value ? 'checked' : ''} data-p="${esc(p.name)}">`
          : `<input ${p.kind === 'string' ? 'type="text"' : 'type="text" inputmode="decimal"'} value="${esc(p.value ?? '')}" data-p="${esc(p.name)}" size="24">`;
        parts.push(`<tr><td>${esc(p.name)}</td><td>${p.kind}</td><td>${input}</td><td><button data-set="${esc(p.name)}" data-kind="${p.kind}">set</button></td></tr>`);
      }
      parts.push('</table>');
    }
    root.innerHTML = parts.join('');
    for (const b of root.querySelectorAll('button[data-set]')) b.onclick = () => setParam(c.address, b.dataset.set, b.dataset.kind);
    commands.render($('d-commands'), c.address);
  }
  $('d-head').innerHTML = `${esc(c.name)} <span class="cls">${esc(c.class)}(${esc(c.impl)}) ${esc(c.address)} on ${esc(c.host ?? '?')}: ${esc(STATE_TEXT[c.state] ?? c.state)}</span>`;
  // Timing: the data task's wake-up latency histogram, percentiles and overruns.
  const timing = $('d-timing');
  if (c.stats) {
    const s = c.stats;
    if (!document.getElementById('latency-plot')) {
      timing.innerHTML = '<h3>Timing</h3><div id="d-tstats"></div><canvas id="latency-plot" class="plot" width="560" height="200" data-testid="latency"></canvas>';
    }
    $('d-tstats').innerHTML = `<table class="kv"><tr><th>period</th><td>${s.period_ns ? duration(s.period_ns) : 'triggered/none'}</td><th>cycles</th><td>${s.cycles}</td><th>overruns</th><td data-testid="overruns">${s.overruns}</td><th>published</th><td>${s.published}</td><th>listeners</th><td>${s.listeners}</td><th>errors</th><td>${s.errors}</td></tr>${latencyRow(c.latency ?? null, s)}</table>`;
  }
  const d = st.data.get(c.address);
  if (d) $('d-data').innerHTML = `<h3>Latest data${isStale(d, performance.now()) ? ' (OLD: no new sample)' : ''}</h3>${dataTable(d.data, d.names)}`;
  drawDetailPlots(c, d);
}

// Type checks before anything is sent (rack-gui checks again against the component's kind).
function parseParam(kind, input) {
  if (kind === 'bool') return { ok: true, value: input.checked };
  const t = input.value.trim();
  if (kind === 'string') return { ok: true, value: input.value };
  if (kind === 'int') {
    if (!/^[+-]?\d+$/.test(t)) return { ok: false, why: `'${t}' is not an integer` };
    const v = Number(t);
    if (!Number.isSafeInteger(v)) return { ok: false, why: `'${t}' is out of range` };
    return { ok: true, value: v };
  }
  if (kind === 'float') {
    const v = Number(t);
    if (t === '' || !Number.isFinite(v)) return { ok: false, why: `'${t}' is not a finite number` };
    return { ok: true, value: v };
  }
  return { ok: false, why: `unknown kind ${kind}` };
}
function setParam(address, name, kind) {
  const input = $('details').querySelector(`input[data-p="${CSS.escape(name)}"]`);
  const r = parseParam(kind, input);
  input.classList.toggle('bad', !r.ok);
  if (!r.ok) { notice(`${name}: ${r.why}; nothing sent`, false); return; }
  send({ op: 'set_param', component: address, name, value: r.value });
  setTimeout(() => send({ op: 'get_params', component: address }), 300);
}

// Units, sensible precision, enums and addresses by name (numbers.js).
function dataTable(obj, names) {
  const rows = [];
  for (const [k, v] of Object.entries(obj)) {
    if (k.endsWith('_')) continue;  // padding
    const text = Array.isArray(v) ? formatArray(k, v) : formatField(k, v, names);
    rows.push(`<tr><td>${esc(k)}</td><td data-field="${esc(k)}">${esc(text)}</td></tr>`);
  }
  return `<table class="kv" data-testid="data-table">${rows.join('')}</table>`;
}

// A camera image: raw RGB or mono pixels into ImageData, JPEG through an <img>.
function drawCamera() {
  const cv = document.getElementById('camera');
  const img = st.images.get(st.selected);
  if (!cv || !img) return;
  const info = document.getElementById('camera-info');
  if (info) info.textContent = `${img.width}x${img.height} ${img.format}, frame ${img.frame}, dropped ${img.dropped}, bad ${img.bad_frames}`;
  if (cv.width !== img.width || cv.height !== img.height) { cv.width = img.width; cv.height = img.height; }
  const g = cv.getContext('2d');
  if (img.format === 'jpeg') {
    const el = new Image();
    el.onload = () => g.drawImage(el, 0, 0);
    el.src = `data:image/jpeg;base64,${img.data}`;
    return;
  }
  const bytes = Uint8Array.from(atob(img.data), (ch) => ch.charCodeAt(0));
  const out = g.createImageData(img.width, img.height);
  const n = img.width * img.height;
  for (let i = 0; i < n; i++) {
    const [r, gr, b] = img.format === 'mono' ? [bytes[i], bytes[i], bytes[i]] : [bytes[3 * i], bytes[3 * i + 1], bytes[3 * i + 2]];
    out.data[4 * i] = r; out.data[4 * i + 1] = gr; out.data[4 * i + 2] = b; out.data[4 * i + 3] = 255;
  }
  g.putImageData(out, 0, 0);
  st.cameraFramesShown = (st.cameraFramesShown ?? 0) + 1;
}

function drawDetailPlots(c, d) {
  if (c.class === 'Camera') drawCamera();
  const lat = document.getElementById('latency-plot');
  if (lat && c.stats) drawLatency(lat, c);
  const polar = document.getElementById('polar');
  if (polar && d) drawPolar(polar, c.class, d.data);
}

// The percentiles as text under the counters (from the histogram's reply when there is one).
function latencyRow(h, s) {
  const l = (h ?? s).latency_ns;
  const n = (h ?? s).samples;
  if (!l || !n) return '<tr><th>wake-up</th><td colspan="11">none measured</td></tr>';
  const us = (v) => duration(v);
  return `<tr><th>wake-up</th><td colspan="11" data-testid="latency-text">min ${us(l.min)}, p50 ${us(l.p50)}, p99 ${us(l.p99)}, p99.9 ${us(l.p999)}, max ${us(l.max)}, mean ${us(l.mean)} (${n} samples)</td></tr>`;
}

// A bucket edge as a short label: 800u, 1.2m, 10m.
function edgeText(ns) { return ns >= 1e6 ? `${+(ns / 1e6).toFixed(1)}m` : `${+(ns / 1e3).toFixed(1)}u`; }

// Wake-up latency histogram (rack-gui's "latency", gui_protocol.h): every bucket the
// component reports, on a log-count axis (a single 5 ms overrun among 100 000 samples
// stays visible). Buckets at or beyond the period are red (the task woke a period or
// more late), those at or beyond p99 orange. The canvas carries data-samples and
// data-nonzero (non-empty buckets) for the end-to-end test.
function drawLatency(cv, c) {
  const g = cv.getContext('2d');
  const W = cv.width, H = cv.height;
  g.clearRect(0, 0, W, H);
  g.font = '11px sans-serif';
  g.fillStyle = '#000';
  const h = c.latency;
  if (!h || !Array.isArray(h.counts) || h.counts.length === 0) {
    cv.dataset.samples = '0';
    cv.dataset.nonzero = '0';
    g.fillText(c.stats && c.stats.data_task === 0 ? 'no data task: no wake-up latency' : 'no latency histogram yet', 10, 20);
    return;
  }
  const n = h.counts.length;
  const L = 44, R = 8, T = 22, B = 30;
  const pw = W - L - R, ph = H - T - B;
  const most = Math.max(1, ...h.counts);
  const ly = (v) => Math.log10(v + 1) / Math.log10(most + 1) * ph;
  const bw = pw / n;
  let nonzero = 0;
  // Log-count grid: 1, 10, 100, ...
  g.strokeStyle = '#e0e0e0';
  g.textAlign = 'right';
  for (let d = 1; d <= most; d *= 10) {
    const y = T + ph - ly(d);
    g.beginPath(); g.moveTo(L, y); g.lineTo(W - R, y); g.stroke();
    g.fillText(d >= 1e6 ? `${d / 1e6}M` : d >= 1e3 ? `${d / 1e3}k` : `${d}`, L - 4, y + 4);
  }
  for (let j = 0; j < n; j++) {
    const k = h.counts[j];
    if (k === 0) continue;
    nonzero++;
    const lower = h.lower_ns[j];
    g.fillStyle = h.period_ns > 0 && lower >= h.period_ns ? '#c62828' : lower >= h.latency_ns.p99 ? '#ef6c00' : '#1565c0';
    const bh = Math.max(1, ly(k));
    g.fillRect(L + j * bw + 1, T + ph - bh, Math.max(1, bw - 2), bh);
  }
  // Bucket edges under the axis, at each bucket's left end: every decade (1u, 10u,
  // 100u, 1m, >=10m).
  g.fillStyle = '#000';
  g.textAlign = 'center';
  g.strokeStyle = '#000';
  g.beginPath(); g.moveTo(L, T + ph); g.lineTo(W - R, T + ph); g.stroke();
  for (let j = 0; j < n; j++) {
    const e = h.lower_ns[j];
    if (e > 0 && Number.isInteger(Math.log10(e))) g.fillText(j === n - 1 ? `>=${edgeText(e)}` : edgeText(e), L + j * bw, T + ph + 14);
  }
  g.textAlign = 'left';
  g.fillText('wake-up latency (bucket edges), count on a log axis', L, H - 4);
  const p = h.latency_ns;
  g.fillText(`${h.samples} samples, overruns ${h.overruns}, p50 ${(p.p50 / 1000).toFixed(1)} us, p99 ${(p.p99 / 1000).toFixed(1)} us, max ${(p.max / 1000).toFixed(1)} us`, L, 13);
  cv.dataset.samples = String(h.samples);
  cv.dataset.nonzero = String(nonzero);
}

function drawPolar(cv, cls, d) {
  const g = cv.getContext('2d');
  const W = cv.width, H = cv.height, cx = W / 2, cy = H / 2;
  g.clearRect(0, 0, W, H);
  const range = d.max_range || 20;
  const k = (Math.min(W, H) / 2 - 10) / range;
  g.strokeStyle = '#ddd';
  for (let r = 5; r <= range; r += 5) { g.beginPath(); g.arc(cx, cy, r * k, 0, 2 * Math.PI); g.stroke(); }
  g.fillStyle = '#c62828';
  g.beginPath();
  if (cls === 'Ladar') {
    for (let i = 0; i < d.beam_count; i++) {
      const r = d.range[i];
      if (!(r > 0) || r > d.max_range) continue;
      const a = d.start_angle + i * d.angle_step;
      g.rect(cx - r * Math.sin(a) * k, cy - r * Math.cos(a) * k, 2, 2);
    }
  } else {
    for (let i = 0; i < d.point_count; i++) g.rect(cx - d.y[i] * k, cy - d.x[i] * k, 2, 2);
  }
  g.fill();
  g.fillStyle = '#000';
  g.fillText(`${cls}: forward is up, rings every 5 m`, 6, 12);
}

// ---------------------------------------------------------------- GDOS
function onGdos(records) {
  for (const r of records) {
    st.log.push(r);
    st.hosts.add(r.host);
    if (/^mode switch |MODE SWITCH|CRASH/.test(r.text)) {
      st.reports.push(r);
      if (st.reports.length > 200) st.reports.shift();
    }
  }
  if (st.log.length > 3000) st.log.splice(0, st.log.length - 3000);
  const sel = $('g-host');
  for (const h of st.hosts) {
    if (![...sel.options].some((o) => o.value === h)) sel.add(new Option(h, h));
  }
  if (!$('g-pause').checked) renderGdos(false);
  if (document.querySelector('#view-reports.active')) renderReports();
}
function gdosFilter() {
  const max = LEVELS.indexOf($('g-level').value);
  const host = $('g-host').value;
  const comp = $('g-comp').value.trim();
  const grep = $('g-grep').value;
  return (r) => (r.level === 'print' || LEVELS.indexOf(r.level) <= max) && (!host || r.host === host) &&
    (!comp || r.name === comp || r.source === comp) && (!grep || r.text.includes(grep));
}
function renderGdos(full) {
  const root = $('gdos');
  if (!root.offsetParent && !full) return;  // hidden: drawn when shown
  const f = gdosFilter();
  const rows = st.log.filter(f).slice(-1000);
  const atBottom = root.scrollTop + root.clientHeight >= root.scrollHeight - 20;
  root.innerHTML = rows.map((r) => `<div class="log lv-${r.level}">${esc(r.time.slice(11, 23))} ${esc(r.host)} ${r.level[0].toUpperCase()} ${esc(r.name || r.source)}: ${esc(r.text)}</div>`).join('');
  if (atBottom || full) root.scrollTop = root.scrollHeight;
}
for (const id of ['g-level', 'g-host', 'g-comp', 'g-grep']) $(id).addEventListener('input', () => renderGdos(true));
$('g-clear').onclick = () => { st.log = []; renderGdos(true); };
function updateGdosTargets() {
  const sel = $('g-target');
  const cur = sel.value;
  const want = [...st.comps.values()].map((c) => c.address);
  if (want.join() === [...sel.options].map((o) => o.value).join()) return;
  sel.replaceChildren(...[...st.comps.values()].map((c) => new Option(`${c.name} ${c.address}`, c.address)));
  if (want.includes(cur)) sel.value = cur;
}
$('g-setlevel').onclick = () => {
  const a = $('g-target').value;
  if (a) send({ op: 'set_param', component: a, name: 'gdosLevel', value: $('g-newlevel').value });
};

function renderReports() {
  const root = $('reports');
  const parts = [];
  parts.push(`<h3>Report files, symbolized by rack-backtrace (${esc(st.reportDir ?? 'rack-gui --reports DIR')})</h3>`);
  if (st.reportFiles.length === 0) parts.push('<p class="hint">No report file of a rackd on this machine (rack-gui --reports DIR names its crash_dir).</p>');
  for (const f of st.reportFiles) parts.push(`<h4>${esc(f.file)}</h4><div class="report" data-testid="report-file">${esc(f.text)}</div>`);
  parts.push('<h3>Reports announced in GDOS (all hosts)</h3>');
  if (st.reports.length === 0) parts.push('<p class="hint">None so far.</p>');
  for (const r of st.reports) parts.push(`<div class="report" data-testid="report-gdos">${esc(r.time)} ${esc(r.host)} ${esc(r.name || r.source)}\n${esc(r.text)}</div>`);
  root.innerHTML = parts.join('');
}

// ---------------------------------------------------------------- map
const canvas = $('map');
const ctx = canvas.getContext('2d');

function onMap(m) {
  const bytes = Uint8Array.from(atob(m.cells), (ch) => ch.charCodeAt(0));
  const off = document.createElement('canvas');
  off.width = m.width;
  off.height = m.height;
  const g = off.getContext('2d');
  const img = g.createImageData(m.width, m.height);
  // Row 0 of the cells is the map's bottom row: flip into image rows.
  for (let iy = 0; iy < m.height; iy++) {
    for (let ix = 0; ix < m.width; ix++) {
      const s = bytes[iy * m.width + ix];
      const v = s === 0 ? 255 : s === 1 ? 30 : 190;
      const o = ((m.height - 1 - iy) * m.width + ix) * 4;
      img.data[o] = img.data[o + 1] = img.data[o + 2] = v;
      img.data[o + 3] = 255;
    }
  }
  g.putImageData(img, 0, 0);
  st.maps.set(m.system, { meta: m, canvas: off });
  updateRobotSelect();
  if (st.view.system === m.system) st.view.fitted = false;
}

function updateRobotSelect() {
  const sel = $('map-robot');
  const systems = [...new Set([...st.robots.map((r) => r.system), ...st.maps.keys()])].sort((a, b) => a - b);
  const have = [...sel.options].map((o) => Number(o.value));
  if (systems.join() !== have.join()) {
    sel.replaceChildren(...systems.map((s) => new Option(`robot ${s}`, s)));
  }
  if (st.view.system === null && systems.length) { st.view.system = systems[0]; st.view.fitted = false; }
  if (st.view.system !== null) sel.value = st.view.system;
}
$('map-robot').onchange = (e) => { st.view.system = Number(e.target.value); st.view.fitted = false; };

function findData(system, cls) {
  let best = null;
  for (const d of st.data.values()) if (d.system === system && d.class === cls && (!best || d.component < best.component)) best = d;
  return best;
}
const isStale = (d, now) => !st.connected || now - d.received > STALE_MS;

// Data older than this is not the robot's present: drawn faded, with a warning.
const STALE_MS = 1500;
function onData(m) {
  m.received = performance.now();
  st.data.set(m.component, m);
  plots.onData(m);
  if (m.class === 'Chassis' && m.system === st.view.system) {
    const c = m.data;
    $('chassis-box').textContent = `vx ${c.vx.toFixed(2)} m/s  ω ${(c.omega * 180 / Math.PI).toFixed(0)}°/s\nbattery ${c.battery ? c.battery.toFixed(1) + ' V' : 'n/a'}\npilot ${pilotName(c.active_pilot, m.names?.active_pilot)}\nwatchdog stops ${c.watchdog_stops}`;
  }
  if (st.selected === m.component && document.querySelector('#view-details.active')) renderDetails();
}
setInterval(() => {
  const c = st.view.system !== null ? findData(st.view.system, 'Chassis') : null;
  if (c && isStale(c, performance.now())) $('chassis-box').textContent = 'chassis: no data (not answering)';
}, 500);
// The chassis' active pilot by its component name: rack-gui names the address field
// through the chassis class's description (m.names.active_pilot: "Pilot(0/0)", a
// tool's "Tool(254/N)"), as the list addresses components; no class ids here.
function pilotName(raw, named) {
  if (!raw) return 'none';
  const c = named ? st.comps.get(named) : null;
  if (c) return c.name;
  if (named?.startsWith('Tool(')) return 'this dashboard (joystick)';
  return named ?? `0x${raw.toString(16)}`;
}

function resizeMap() {
  const r = canvas.getBoundingClientRect();
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(r.width * dpr)), h = Math.max(1, Math.round(r.height * dpr));
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
}
// The map is fitted again when the window (or the phone's orientation) changes.
window.addEventListener('resize', () => { resizeMap(); st.view.fitted = false; });
const mapTools = setupMapTools({ st, $ });
const L = mapTools.layers;

function fitMap() {
  const m = st.maps.get(st.view.system);
  if (!m || canvas.width < 2) return;
  const { width, height, resolution, origin_x, origin_y } = m.meta;
  const wm = width * resolution, hm = height * resolution;
  st.view.scale = Math.min(canvas.width / wm, canvas.height / hm) * 0.95;
  st.view.ox = canvas.width / 2 - (origin_x + wm / 2) * st.view.scale;
  st.view.oy = canvas.height / 2 + (origin_y + hm / 2) * st.view.scale;
  st.view.fitted = true;
}
$('fit').onclick = () => { st.view.fitted = false; };

// map frame (m, y up) <-> canvas pixels
const toPx = (x, y) => [st.view.ox + x * st.view.scale, st.view.oy - y * st.view.scale];
const toWorld = (px, py) => [(px - st.view.ox) / st.view.scale, (st.view.oy - py) / st.view.scale];
st.toPx = toPx;

let lastFrame = 0;
st.frameMs = [];
function draw(now) {
  requestAnimationFrame(draw);
  if (!document.querySelector('#view-map.active')) return;
  resizeMap();
  if (!st.view.fitted) fitMap();
  const t0 = performance.now();
  const s = st.view.system;
  {
    const p0 = findData(s, 'Position') ?? findData(s, 'MCL');
    if (p0 && !isStale(p0, t0)) mapTools.follow(p0.data, canvas);
  }
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.fillStyle = '#9e9e9e';
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  const m = st.maps.get(s);
  const k = st.view.scale || 20;
  if (m && L.map) {
    const { width, height, resolution, origin_x, origin_y } = m.meta;
    const [x0, y0] = toPx(origin_x, origin_y + height * resolution);
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(m.canvas, x0, y0, width * resolution * k, height * resolution * k);
  } else if (!m) {
    ctx.fillStyle = '#333';
    ctx.font = '14px sans-serif';
    ctx.fillText('no map (yet): rack-gui loads the map named by the robot\'s MCL (or --map)', 20, 30);
  }
  // Anything of the robot that has not been refreshed lately is drawn faded, and the
  // view says so: a robot that stopped answering is never shown as if it were there.
  const tnow = performance.now();
  let staleSince = null;
  const fade = (d) => {
    const stale = isStale(d, tnow);
    if (stale) staleSince = Math.max(staleSince ?? 0, tnow - d.received);
    ctx.globalAlpha = stale ? 0.25 : 1;
  };
  const path = findData(s, 'Path');
  if (path && L.path) {
    fade(path);
    const p = path.data;
    ctx.strokeStyle = '#1e88e5';
    ctx.lineWidth = 2;
    ctx.beginPath();
    for (let i = 0; i < p.point_count; i++) {
      const [px, py] = toPx(p.x[i], p.y[i]);
      if (i === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py);
    }
    if (p.closed) ctx.closePath();
    ctx.stroke();
  }
  const mcl = findData(s, 'MCL');
  ctx.globalAlpha = 1;
  if (st.benchParticles) drawParticles(st.benchParticles.x, st.benchParticles.y, st.benchParticles.n);
  const pos = findData(s, 'Position');
  const pose = pos ? pos.data : mcl ? mcl.data : null;
  const scan = findData(s, 'Scan2D');
  if (scan && pose && L.scan) {
    fade(scan);
    const d = scan.data;
    const c = Math.cos(pose.phi), sn = Math.sin(pose.phi);
    ctx.fillStyle = '#e53935';
    ctx.beginPath();
    for (let i = 0; i < d.point_count; i++) {
      const [px, py] = toPx(pose.x + c * d.x[i] - sn * d.y[i], pose.y + sn * d.x[i] + c * d.y[i]);
      ctx.rect(px - 1.5, py - 1.5, 3, 3);
    }
    ctx.fill();
  }
  const pilot = findData(s, 'Pilot');
  if (pilot && pilot.data.mode === 2 && L.target) {
    fade(pilot);
    const [px, py] = toPx(pilot.data.target_x, pilot.data.target_y);
    ctx.strokeStyle = '#6a1b9a';
    ctx.lineWidth = 3;
    ctx.beginPath();
    ctx.moveTo(px - 8, py - 8); ctx.lineTo(px + 8, py + 8); ctx.moveTo(px + 8, py - 8); ctx.lineTo(px - 8, py + 8);
    ctx.stroke();
  }
  if (pose && L.robot) {
    fade(pos ?? mcl);
    drawRobot(pose.x, pose.y, pose.phi, 'rgba(0,137,123,0.55)');
  }
  // Particles and the covariance ellipse on top of the robot: when MCL has converged
  // they lie within its outline.
  if (mcl && L.particles) {
    fade(mcl);
    drawParticles(mcl.data.particle_x, mcl.data.particle_y, mcl.data.shown, mcl.data.particle_phi);
  }
  if (pose && L.ellipse) {
    fade(pos ?? mcl);
    const cov = mcl ? [mcl.data.covariance[0], mcl.data.covariance[1], mcl.data.covariance[4]] : [pose.var_x, 0, pose.var_y];
    drawEllipse(pose.x, pose.y, cov);
  }
  const chassis = findData(s, 'Chassis');
  if (chassis && chassis.data.truth_valid && L.truth) {
    fade(chassis);
    drawRobot(chassis.data.truth_x, chassis.data.truth_y, chassis.data.truth_phi, 'rgba(0,0,0,0.35)');
  }
  ctx.globalAlpha = 1;
  mapTools.drawScale(ctx, st.view.scale, canvas.height);
  st.mapStale = staleSince !== null;
  if (staleSince !== null) {
    ctx.fillStyle = 'rgba(239,108,0,0.9)';
    ctx.fillRect(0, 0, canvas.width, 34);
    ctx.fillStyle = '#fff';
    ctx.font = 'bold 16px sans-serif';
    ctx.fillText(st.connected ? `robot ${s}: no data for ${(staleSince / 1000).toFixed(0)} s: not answering (faded: its last known state)`
      : 'rack-gui not connected: faded: the last known state', 12, 23);
  }
  if (drag && drag.mode === 'pose') {
    const [ax, ay] = toPx(drag.wx, drag.wy);
    ctx.strokeStyle = '#d81b60'; ctx.lineWidth = 3;
    ctx.beginPath(); ctx.moveTo(ax, ay); ctx.lineTo(drag.px, drag.py); ctx.stroke();
  }
  const dt = performance.now() - t0;
  st.frameMs.push(dt);
  if (st.frameMs.length > 120) st.frameMs.shift();
  if (now - lastFrame > 500) {
    lastFrame = now;
    const fresh = (d) => d && !isStale(d, tnow);
    const info = fresh(pos ?? mcl) ? `pose ${pose.x.toFixed(2)}, ${pose.y.toFixed(2)}, ${(pose.phi * 180 / Math.PI).toFixed(0)}°` : 'no current pose';
    $('map-info').textContent = `${info}${fresh(mcl) ? ` | MCL ${mcl.data.particle_count} particles, fit ${mcl.data.fit.toFixed(2)}` : ''}${fresh(pilot) ? ` | pilot status ${PILOT_STATUS[pilot.data.status] ?? pilot.data.status}` : ''} | draw ${dt.toFixed(1)} ms`;
  }
}

const PILOT_STATUS = ['idle', 'driving', 'reached', 'blocked', 'no path', 'preempted', 'no input', 'planning', 'unreachable'];

// All particles in one path and one fill (and their headings in one stroke): tens of
// thousands stay smooth. Each is a 5 px square, big enough to see on a phone; up to
// 5000 of them get a dark rim and a 9 px line along their heading.
function drawParticles(xs, ys, n, phis) {
  const dpr = window.devicePixelRatio || 1;
  const r = 2.5 * dpr, h = 9 * dpr;
  const k = st.view.scale, ox = st.view.ox, oy = st.view.oy;
  ctx.beginPath();
  for (let i = 0; i < n; i++) ctx.rect(ox + xs[i] * k - r, oy - ys[i] * k - r, 2 * r, 2 * r);
  ctx.fillStyle = 'rgba(230,81,0,0.9)';
  ctx.fill();
  // Rims and headings only for the clouds MCL shows (a few thousand): 50 000 particles
  // are a solid cloud anyway, and a second pass over them would double the frame.
  if (n > 5000) { st.particleSizePx = 2 * r / dpr; return; }
  ctx.strokeStyle = 'rgba(90,30,0,0.8)';
  ctx.lineWidth = 1;
  ctx.stroke();
  if (phis) {
    ctx.beginPath();
    for (let i = 0; i < n; i++) {
      const px = ox + xs[i] * k, py = oy - ys[i] * k;
      ctx.moveTo(px, py);
      ctx.lineTo(px + Math.cos(phis[i]) * h, py - Math.sin(phis[i]) * h);
    }
    ctx.strokeStyle = 'rgba(230,81,0,0.7)';
    ctx.lineWidth = 1.5 * dpr;
    ctx.stroke();
  }
  st.particleSizePx = 2 * r / dpr;
}

// The 2-sigma ellipse of the x/y covariance.
function drawEllipse(x, y, [sxx, sxy, syy]) {
  if (!(sxx >= 0 && syy >= 0)) return;
  const tr = sxx + syy, det = sxx * syy - sxy * sxy;
  const disc = Math.sqrt(Math.max(0, tr * tr / 4 - det));
  const l1 = tr / 2 + disc, l2 = Math.max(0, tr / 2 - disc);
  const ang = Math.atan2(l1 - sxx, sxy || 1e-12);
  const [px, py] = toPx(x, y);
  ctx.strokeStyle = '#1a237e';
  ctx.lineWidth = 2;
  ctx.beginPath();
  ctx.ellipse(px, py, Math.max(2, 2 * Math.sqrt(l1) * st.view.scale), Math.max(2, 2 * Math.sqrt(l2) * st.view.scale), -(sxy === 0 ? 0 : ang), 0, 2 * Math.PI);
  ctx.stroke();
}
function drawRobot(x, y, phi, colour) {
  const [px, py] = toPx(x, y);
  const r = Math.max(6, 0.3 * st.view.scale);
  ctx.fillStyle = colour;
  ctx.beginPath();
  ctx.moveTo(px + Math.cos(phi) * r * 1.4, py - Math.sin(phi) * r * 1.4);
  ctx.lineTo(px + Math.cos(phi + 2.5) * r, py - Math.sin(phi + 2.5) * r);
  ctx.lineTo(px + Math.cos(phi - 2.5) * r, py - Math.sin(phi - 2.5) * r);
  ctx.closePath();
  ctx.fill();
}
requestAnimationFrame(draw);

// Zoom about the cursor, pan by dragging, click actions by mode.
let drag = null;
const clickMode = () => document.querySelector('input[name="click"]:checked').value;
function canvasPoint(e) {
  const r = canvas.getBoundingClientRect();
  const dpr = canvas.width / r.width;
  return [(e.clientX - r.left) * dpr, (e.clientY - r.top) * dpr];
}
canvas.addEventListener('wheel', (e) => {
  e.preventDefault();
  const [px, py] = canvasPoint(e);
  const f = Math.exp(-e.deltaY * 0.0015);
  st.view.ox = px - (px - st.view.ox) * f;
  st.view.oy = py - (py - st.view.oy) * f;
  st.view.scale *= f;
}, { passive: false });
canvas.addEventListener('pointerdown', (e) => {
  const [px, py] = canvasPoint(e);
  const [wx, wy] = toWorld(px, py);
  const mode = e.button === 1 ? 'pan' : clickMode();
  drag = { mode, sx: px, sy: py, px, py, wx, wy, ox: st.view.ox, oy: st.view.oy };
  canvas.setPointerCapture(e.pointerId);
  canvas.focus();
});
canvas.addEventListener('pointermove', (e) => {
  if (!drag) return;
  const [px, py] = canvasPoint(e);
  drag.px = px; drag.py = py;
  if (drag.mode === 'pan') {
    st.view.ox = drag.ox + px - drag.sx; st.view.oy = drag.oy + py - drag.sy;
    if (st.view.follow && Math.hypot(px - drag.sx, py - drag.sy) > 5) { st.view.follow = false; $('follow-robot').checked = false; }
  }
});
canvas.addEventListener('pointerup', () => {
  if (!drag) return;
  const d = drag;
  drag = null;
  const s = st.view.system;
  if (s === null) return;
  if (d.mode === 'destination') {
    send({ op: 'set_destination', system: s, x: round3(d.wx), y: round3(d.wy) });
  } else if (d.mode === 'pose') {
    const moved = Math.hypot(d.px - d.sx, d.py - d.sy) > 10;
    const pos = findData(s, 'Position');
    const phi = moved ? Math.atan2(-(d.py - d.sy), d.px - d.sx) : pos ? pos.data.phi : 0;
    send({ op: 'set_pose', system: s, x: round3(d.wx), y: round3(d.wy), phi: round3(phi) });
  }
});
const round3 = (v) => Math.round(v * 1000) / 1000;
$('follow-path').onclick = () => { if (st.view.system !== null) send({ op: 'follow_path', system: st.view.system }); };

// ---------------------------------------------------------------- joystick (dead-man)
// While held, the command is sent ten times a second; letting go sends a release
// (MOVE 0). rack-gui stops the robot itself when the commands stop coming (400 ms),
// and the chassis watchdog stops it should rack-gui die.
const joy = { vx: 0, omega: 0, held: false, timer: null, keys: new Set() };
st.joy = joy;
function joyMax() { const v = Number($('jmax').value); return Number.isFinite(v) && v > 0 ? Math.min(v, 2) : 0.5; }
function joySend() {
  if (st.view.system === null) return;
  send({ op: 'joystick', system: st.view.system, vx: round3(joy.vx), omega: round3(joy.omega) });
}
function joyStart() {
  if (joy.held) return;
  joy.held = true;
  $('joystick').classList.add('active');
  joySend();
  joy.timer = setInterval(joySend, 100);
}
function joyStop() {
  if (!joy.held) return;
  joy.held = false;
  clearInterval(joy.timer);
  joy.vx = joy.omega = 0;
  $('joystick').classList.remove('active');
  const c0 = (pad.clientWidth - 40) / 2;
  $('knob').style.left = `${c0}px`;
  $('knob').style.top = `${c0}px`;
  if (st.view.system !== null) send({ op: 'joystick_release', system: st.view.system });
}
const pad = $('joystick');
function padMove(e) {
  const r = pad.getBoundingClientRect();
  let dx = (e.clientX - r.left - r.width / 2) / (r.width / 2);
  let dy = (e.clientY - r.top - r.height / 2) / (r.height / 2);
  const n = Math.hypot(dx, dy);
  if (n > 1) { dx /= n; dy /= n; }
  joy.vx = -dy * joyMax();
  joy.omega = -dx * 1.0;
  const c = (r.width - 40) / 2;
  $('knob').style.left = `${c + dx * c}px`;
  $('knob').style.top = `${c + dy * c}px`;
}
pad.addEventListener('pointerdown', (e) => { pad.setPointerCapture(e.pointerId); padMove(e); joyStart(); });
pad.addEventListener('pointermove', (e) => { if (joy.held && !joy.keys.size) padMove(e); });
for (const ev of ['pointerup', 'pointercancel', 'lostpointercapture']) pad.addEventListener(ev, () => { if (!joy.keys.size) joyStop(); });
const KEYS = { ArrowUp: [1, 0], KeyW: [1, 0], ArrowDown: [-1, 0], KeyS: [-1, 0], ArrowLeft: [0, 1], KeyA: [0, 1], ArrowRight: [0, -1], KeyD: [0, -1] };
function keyUpdate() {
  let v = 0, w = 0;
  for (const k of joy.keys) { v += KEYS[k][0]; w += KEYS[k][1]; }
  joy.vx = Math.sign(v) * joyMax();
  joy.omega = Math.sign(w) * 1.0;
  if (joy.keys.size) joyStart(); else joyStop();
}
window.addEventListener('keydown', (e) => {
  if (!KEYS[e.code] || !document.querySelector('#view-map.active') || e.target.tagName === 'INPUT' || e.target.tagName === 'SELECT') return;
  e.preventDefault();
  if (!joy.keys.has(e.code)) { joy.keys.add(e.code); keyUpdate(); }
});
window.addEventListener('keyup', (e) => { if (joy.keys.delete(e.code)) keyUpdate(); });
window.addEventListener('blur', () => { joy.keys.clear(); joyStop(); });
document.addEventListener('visibilitychange', () => { if (document.hidden) { joy.keys.clear(); joyStop(); } });

// Drawing speed check (the end-to-end test reports it; timing is never asserted):
// frames of the live map without extra particles (the reference), then with N
// synthetic particles, in the same page and run.
function sampleFrames(frames) {
  return new Promise((resolve) => {
    st.frameMs = [];
    const wait = () => {
      if (st.frameMs.length >= frames) {
        const v = [...st.frameMs].sort((a, b) => a - b);
        resolve({ p50: v[Math.floor(v.length / 2)], p90: v[Math.floor(v.length * 0.9)], max: v[v.length - 1], frames: v.length });
      } else setTimeout(wait, 50);
    };
    wait();
  });
}
st.benchmarkParticles = async (n, frames = 30) => {
  st.benchParticles = null;
  const base = await sampleFrames(frames);
  const x = new Float32Array(n), y = new Float32Array(n);
  const m = st.maps.get(st.view.system);
  const w = m ? m.meta.width * m.meta.resolution : 20, h = m ? m.meta.height * m.meta.resolution : 20;
  const x0 = m ? m.meta.origin_x : 0, y0 = m ? m.meta.origin_y : 0;
  for (let i = 0; i < n; i++) { x[i] = x0 + Math.random() * w; y[i] = y0 + Math.random() * h; }
  st.benchParticles = { x, y, n };
  const withParticles = await sampleFrames(frames);
  st.benchParticles = null;
  return { n, base, withParticles };
};

connect();
