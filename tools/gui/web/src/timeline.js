// The Timeline panel: draws a task timeline that `rackctl trace --out FILE` wrote (the
// Chrome JSON trace event format; README "Task timeline"). Perfetto's UI cannot be
// embedded offline, so this is a plain 2-D canvas: one row per task (the file's
// thread_name tracks, in their sort order), a box per cycle ("X" events, the colour
// telling data-task loops from command handlers, red when it failed), red marks for
// overruns, orange for mode switches, ticks for messages, and lines for the flow
// events that join a send to its receive. Wheel: zoom at the pointer; drag: pan.
//
// parseTrace() is a plain function of the parsed JSON (no DOM), so it can be checked
// on its own.

export function parseTrace(doc) {
  const events = Array.isArray(doc) ? doc : doc && Array.isArray(doc.traceEvents) ? doc.traceEvents : null;
  if (!events) throw new Error('not a Chrome JSON trace: no traceEvents array');
  const tracks = new Map();  // tid -> {name, sort, slices, marks}
  const track = (tid) => {
    if (!tracks.has(tid)) tracks.set(tid, { tid, name: `thread ${tid}`, sort: 1e9, slices: [], marks: [] });
    return tracks.get(tid);
  };
  const flowStarts = new Map();
  const flows = [];
  let t0 = Infinity, t1 = -Infinity;
  for (const e of events) {
    if (!e || typeof e !== 'object' || typeof e.ph !== 'string') continue;
    const ts = Number(e.ts);
    if (e.ph === 'M') {
      if (e.name === 'thread_name' && e.args) track(e.tid).name = String(e.args.name);
      if (e.name === 'thread_sort_index' && e.args) track(e.tid).sort = Number(e.args.sort_index);
      continue;
    }
    if (!Number.isFinite(ts)) continue;
    if (e.ph === 'X') {
      const dur = Math.max(0, Number(e.dur) || 0);
      track(e.tid).slices.push({ ts, dur, name: e.name, ok: !e.args || e.args.ok !== false, args: e.args || {} });
      t0 = Math.min(t0, ts); t1 = Math.max(t1, ts + dur);
    } else if (e.ph === 'i' || e.ph === 'I') {
      const kind = e.cat === 'overrun' ? 'overrun' : e.cat === 'modeswitch' ? 'modeswitch' : e.cat === 'message' ? 'message' : e.cat === 'wake' ? 'wake' : 'other';
      track(e.tid).marks.push({ ts, kind, name: e.name, args: e.args || {} });
      t0 = Math.min(t0, ts); t1 = Math.max(t1, ts);
    } else if (e.ph === 's') {
      flowStarts.set(e.id, { tid: e.tid, ts });
    } else if (e.ph === 'f' && flowStarts.has(e.id)) {
      const s = flowStarts.get(e.id);
      flows.push({ from: s.tid, fromTs: s.ts, to: e.tid, toTs: ts });
    }
  }
  const list = [...tracks.values()].sort((a, b) => a.sort - b.sort || a.tid - b.tid);
  const other = doc && doc.otherData ? doc.otherData : {};
  return { tracks: list, flows, t0: Number.isFinite(t0) ? t0 : 0, t1: Number.isFinite(t1) ? t1 : 1, info: other };
}

const ROW = 22, LABEL = 170;

export function setupTimeline() {
  const canvas = document.getElementById('tl-canvas');
  const input = document.getElementById('tl-file');
  const info = document.getElementById('tl-info');
  const tip = document.getElementById('tl-tip');
  if (!canvas || !input) return;
  let trace = null;
  let view = { t0: 0, t1: 1 };

  const draw = () => {
    const wrap = canvas.parentElement;
    const w = wrap.clientWidth, h = Math.max(wrap.clientHeight, trace ? trace.tracks.length * ROW + 30 : 100);
    const dpr = window.devicePixelRatio || 1;
    canvas.width = w * dpr; canvas.height = h * dpr;
    canvas.style.width = `${w}px`; canvas.style.height = `${h}px`;
    const g = canvas.getContext('2d');
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, w, h);
    if (!trace) return;
    const x = (ts) => LABEL + ((ts - view.t0) / (view.t1 - view.t0)) * (w - LABEL - 8);
    const rowOf = new Map(trace.tracks.map((t, i) => [t.tid, i]));
    g.font = '11px system-ui, sans-serif';
    trace.tracks.forEach((t, i) => {
      const y = 20 + i * ROW;
      g.fillStyle = i % 2 ? '#fafafa' : '#f0f0f0';
      g.fillRect(0, y, w, ROW);
      g.fillStyle = '#263238';
      g.fillText(t.name, 4, y + 15);
      for (const s of t.slices) {
        if (s.ts + s.dur < view.t0 || s.ts > view.t1) continue;
        const a = Math.max(LABEL, x(s.ts)), b = Math.max(a + 1, x(s.ts + s.dur));
        g.fillStyle = !s.ok ? '#c62828' : s.name === 'loop' ? '#1e88e5' : '#7cb342';
        g.fillRect(a, y + 4, b - a, ROW - 8);
      }
      for (const m of t.marks) {
        if (m.ts < view.t0 || m.ts > view.t1) continue;
        const px = x(m.ts);
        if (m.kind === 'overrun' || m.kind === 'modeswitch') {
          g.fillStyle = m.kind === 'overrun' ? '#c62828' : '#ef6c00';
          g.beginPath(); g.moveTo(px, y + 2); g.lineTo(px - 4, y + ROW - 2); g.lineTo(px + 4, y + ROW - 2); g.fill();
        } else if (m.kind === 'message') {
          g.fillStyle = '#455a64';
          g.fillRect(px, y + ROW - 5, 1, 4);
        } else if (m.kind === 'wake') {
          g.fillStyle = '#8e24aa';
          g.fillRect(px, y + 1, 1, 4);
        }
      }
    });
    g.strokeStyle = 'rgba(96,125,139,0.5)';
    for (const f of trace.flows) {
      if (Math.max(f.fromTs, f.toTs) < view.t0 || Math.min(f.fromTs, f.toTs) > view.t1) continue;
      const ya = 20 + rowOf.get(f.from) * ROW + ROW / 2, yb = 20 + rowOf.get(f.to) * ROW + ROW / 2;
      if (!Number.isFinite(ya) || !Number.isFinite(yb)) continue;
      g.beginPath(); g.moveTo(x(f.fromTs), ya); g.lineTo(x(f.toTs), yb); g.stroke();
    }
    // Time axis (ms since the trace start).
    g.fillStyle = '#263238';
    const span = view.t1 - view.t0;
    // 1, 2 or 5 times a power of ten: at most about 10 labels, whatever the span.
    const p10 = 10 ** Math.floor(Math.log10(span / 10));
    const step = [1, 2, 5, 10].map((k) => k * p10).find((v) => span / v <= 10) ?? 10 * p10;
    for (let t = Math.ceil(view.t0 / step) * step; t <= view.t1; t += step) {
      const px = x(t);
      g.fillRect(px, 14, 1, 5);
      g.fillText(`${(t / 1000).toFixed(step < 1000 ? 3 : 1)} ms`, px + 2, 12);
    }
  };

  const load = (text, name) => {
    try {
      trace = parseTrace(JSON.parse(text));
      view = { t0: trace.t0, t1: trace.t1 };
      const slices = trace.tracks.reduce((n, t) => n + t.slices.length, 0);
      const overruns = trace.tracks.reduce((n, t) => n + t.marks.filter((m) => m.kind === 'overrun').length, 0);
      info.textContent = `${name}: ${trace.tracks.length} tasks, ${slices} cycles, ${overruns} overruns, ${trace.flows.length} hand-offs` +
        (trace.info.dropped_events ? `, ${trace.info.dropped_events} events dropped` : '');
      info.className = '';
    } catch (err) {
      trace = null;
      info.textContent = `${name}: ${err.message}`;
      info.className = 'bad';
    }
    draw();
  };
  input.onchange = () => {
    const f = input.files && input.files[0];
    if (!f) return;
    f.text().then((t) => load(t, f.name));
  };
  canvas.onwheel = (e) => {
    if (!trace) return;
    e.preventDefault();
    const w = canvas.clientWidth - LABEL - 8;
    const at = view.t0 + ((e.offsetX - LABEL) / w) * (view.t1 - view.t0);
    const k = e.deltaY > 0 ? 1.25 : 0.8;
    view = { t0: at - (at - view.t0) * k, t1: at + (view.t1 - at) * k };
    draw();
  };
  let dragFrom = null;
  canvas.onmousedown = (e) => { dragFrom = { x: e.offsetX, v: { ...view } }; };
  window.addEventListener('mouseup', () => { dragFrom = null; });
  canvas.onmousemove = (e) => {
    if (!trace) return;
    const w = canvas.clientWidth - LABEL - 8;
    if (dragFrom) {
      const dt = ((e.offsetX - dragFrom.x) / w) * (dragFrom.v.t1 - dragFrom.v.t0);
      view = { t0: dragFrom.v.t0 - dt, t1: dragFrom.v.t1 - dt };
      draw();
      return;
    }
    // Tooltip: the cycle under the pointer.
    const row = Math.floor((e.offsetY - 20) / ROW);
    const t = trace.tracks[row];
    const at = view.t0 + ((e.offsetX - LABEL) / w) * (view.t1 - view.t0);
    const s = t && t.slices.find((c) => at >= c.ts && at <= c.ts + c.dur);
    tip.textContent = s ? `${t.name}: ${s.name} at ${(s.ts / 1000).toFixed(3)} ms, ${s.dur.toFixed(1)} us` +
      (s.args.wake_latency_us !== undefined ? `, woke ${s.args.wake_latency_us} us late` : '') : '';
  };
  window.addEventListener('resize', () => { if (document.querySelector('#view-timeline.active')) draw(); });
  draw.load = load;  // a live trace (main.js: rack-gui's "trace" message)
  draw.loaded = () => trace;
  return draw;
}
