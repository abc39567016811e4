// The "Configuration" view (issue 25): the host files of the directories rack-gui
// serves (--config DIR) as a deployment graph (drawn by graphviz on the server, shown
// as an image), the allocation per CPU with configuration priority inversions, and a
// host-file editor: forms built from each class's description (rackd --list-classes
// --json), validation by rackd --check on every change (errors on their line), a
// diff against the file on disk, and saving only a file rackd accepted.
//
// Edits change the text in place (one value on one line), so comments and layout of
// the file survive; the text itself can be edited freely too. The protocol
// (config_files, config_graph, config_classes, config_load, config_part, config_check,
// config_save)
// is described in tools/gui/config_service.h.
import { componentAt, setParam, setTaskPriority } from './yaml_edit.js';
import { lineDiff } from './diff.js';

import './config.css';

const MAX_SEND = 60 * 1024;  // rack-gui refuses WebSocket messages over 64 KiB: larger texts go in parts
// Characters per part (config_part): at most 6 bytes each once in JSON (a \u00XX
// escape), so a part stays under MAX_SEND whatever the text holds.
const PART_CHARS = 8 * 1024;

export function setupConfig(send) {
  const el = (tag, attrs = {}, text) => {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
    if (text !== undefined) e.textContent = text;
    return e;
  };
  // The tab and the view, added to the page's tabs and main area.
  const tab = el('button', { 'data-view': 'config', 'data-testid': 'tab-config' }, 'Configuration');
  document.getElementById('tabs')?.appendChild(tab);
  const view = el('section', { id: 'view-config', class: 'view' });
  view.innerHTML = `
    <div class="toolbar">
      <label>directory <select id="cfg-dir" data-testid="cfg-dir"></select></label>
      <label title="what the network says: stale hosts, state, utilisation, worst wake-up latency, and the data flows that run (each producer's subscribers), every 5 s"><input type="checkbox" id="cfg-live" data-testid="cfg-live"> live</label>
      <label>host file <select id="cfg-file" data-testid="cfg-file"></select></label>
      <button id="cfg-save" data-testid="cfg-save" disabled>Save</button>
      <button id="cfg-revert" data-testid="cfg-revert">Revert</button>
      <span id="cfg-status" data-testid="cfg-status" class="cfg-status"></span>
    </div>
    <div class="cfg-body">
      <div class="cfg-left">
        <div class="cfg-graph" data-testid="cfg-graph-box"><p class="hint">rack-gui --config DIR serves the host files of DIR here.</p></div>
        <p id="cfg-flows" data-testid="cfg-flows" class="hint"></p>
        <h4>Allocation per CPU</h4>
        <pre id="cfg-alloc" data-testid="cfg-alloc" class="cfg-alloc"></pre>
      </div>
      <div class="cfg-right">
        <div class="cfg-editor">
          <pre id="cfg-gutter" class="cfg-gutter" aria-hidden="true"></pre>
          <textarea id="cfg-text" data-testid="cfg-text" spellcheck="false" wrap="off"></textarea>
        </div>
        <ul id="cfg-errors" data-testid="cfg-errors" class="cfg-errors"></ul>
        <div id="cfg-form" data-testid="cfg-form" class="cfg-form"></div>
        <h4>Changes against the file on disk</h4>
        <pre id="cfg-diff" data-testid="cfg-diff" class="cfg-diff"></pre>
      </div>
    </div>`;
  document.querySelector('main')?.appendChild(view);
  const $ = (id) => view.querySelector(`#${id}`);
  const text = $('cfg-text');
  const gutter = $('cfg-gutter');

  const cs = {
    dirs: [],
    dir: null,
    file: null,
    disk: '',          // the file as loaded or last saved
    diskVersion: '',   // config_load's disk_version of it: a save against another one is refused
    classes: null,     // impl -> description
    errors: [],        // of the last check: {line, column, message}
    checked: null,     // the text the last check was about
    valid: false,
    pending: new Map(),  // request id -> what it was for
    checkTimer: null,
    shown: false,
  };
  window.__rackConfig = cs;  // the end-to-end test reads it

  const request = (obj) => {
    const id = send(obj);
    if (id !== null) cs.pending.set(id, obj);
    return id;
  };
  const status = (msg, good) => {
    const s = $('cfg-status');
    s.textContent = msg;
    s.className = 'cfg-status ' + (good === true ? 'good' : good === false ? 'bad' : '');
  };

  // ------------------------------------------------------------ editor
  function renderGutter() {
    const n = text.value.split('\n').length;
    const bad = new Map();
    for (const e of cs.errors) if (e.line > 0) bad.set(e.line, (bad.get(e.line) ? bad.get(e.line) + '\n' : '') + e.message);
    const frag = document.createDocumentFragment();
    for (let i = 1; i <= n; i++) {
      const span = document.createElement('span');
      span.textContent = String(i);
      if (bad.has(i)) {
        span.className = 'err';
        span.title = bad.get(i);
        span.dataset.testid = `cfg-error-line-${i}`;
      }
      frag.appendChild(span);
      frag.appendChild(document.createTextNode('\n'));
    }
    gutter.replaceChildren(frag);
    gutter.scrollTop = text.scrollTop;
  }
  text.addEventListener('scroll', () => { gutter.scrollTop = text.scrollTop; });

  function renderErrors() {
    const ul = $('cfg-errors');
    ul.replaceChildren();
    for (const e of cs.errors) {
      const li = document.createElement('li');
      li.textContent = e.line > 0 ? `line ${e.line}:${e.column}: ${e.message}` : e.message;
      li.dataset.line = String(e.line);
      li.onclick = () => goToLine(e.line, e.column);
      ul.appendChild(li);
    }
    renderGutter();
  }
  function goToLine(line, column) {
    if (!(line > 0)) return;
    const lines = text.value.split('\n');
    let at = 0;
    for (let i = 0; i < line - 1 && i < lines.length; i++) at += lines[i].length + 1;
    at += Math.max(0, (column || 1) - 1);
    text.focus();
    text.setSelectionRange(at, at);
    const lh = parseFloat(getComputedStyle(text).lineHeight) || 16;
    text.scrollTop = Math.max(0, (line - 5) * lh);
    renderForm();
  }

  function renderDiff() {
    const d = $('cfg-diff');
    d.replaceChildren();
    if (text.value === cs.disk) { d.textContent = 'no changes'; return; }
    for (const row of lineDiff(cs.disk, text.value)) {
      const line = document.createElement('div');
      line.className = row.kind === '+' ? 'add' : row.kind === '-' ? 'del' : row.kind === '@' ? 'hunk' : 'ctx';
      line.textContent = row.kind === '@' ? row.text : `${row.kind === ' ' ? ' ' : row.kind} ${row.text}`;
      d.appendChild(line);
    }
  }

  function updateSave() {
    const ready = cs.file && cs.valid && cs.checked === text.value && text.value !== cs.disk;
    $('cfg-save').disabled = !ready;
  }

  function changed() {
    renderDiff();
    cs.valid = false;
    updateSave();
    renderGutter();
    status('checking…');
    clearTimeout(cs.checkTimer);
    cs.checkTimer = setTimeout(check, 300);
  }
  text.addEventListener('input', () => { changed(); renderForm(); });
  text.addEventListener('click', () => renderForm());
  text.addEventListener('keyup', (e) => { if (e.key.startsWith('Arrow') || e.key === 'PageUp' || e.key === 'PageDown') renderForm(); });

  function check() {
    if (!cs.file) return;
    sendText('config_check');
  }

  // config_check / config_save with the text on screen: in one message when it fits,
  // else in parts (config_part, one at a time, each after the previous one's answer)
  // and then the op names the upload. A part refused ends the upload (its error shows).
  function sendText(op) {
    const body = text.value;
    const whole = { op, file: cs.file, text: body, base_version: cs.diskVersion };
    if (new TextEncoder().encode(JSON.stringify(whole)).length <= MAX_SEND) { request(whole); return; }
    const parts = [];
    for (let i = 0; i < body.length;) {
      let end = Math.min(i + PART_CHARS, body.length);
      const c = body.charCodeAt(end - 1);
      if (end < body.length && c >= 0xd800 && c <= 0xdbff) end -= 1;  // never split a surrogate pair
      parts.push(body.slice(i, end));
      i = end;
    }
    const upload = Math.random().toString(36).slice(2, 10) + Date.now().toString(36);
    const file = cs.file;
    const sendPart = (i) => {
      const obj = { op: 'config_part', upload, index: i, count: parts.length, text: parts[i] };
      const id = send(obj);
      if (id === null) return;
      cs.pending.set(id, { ...obj, after: () => {
        if (i + 1 < parts.length) { sendPart(i + 1); return; }
        const last = send({ op, file, upload, base_version: whole.base_version });
        if (last !== null) cs.pending.set(last, whole);  // its answer is about this text
      } });
    };
    sendPart(0);
  }

  // ------------------------------------------------------------ forms
  function renderForm() {
    const box = $('cfg-form');
    const lineNo = text.value.slice(0, text.selectionStart).split('\n').length;
    const comp = componentAt(text.value, lineNo);
    if (!comp) {
      box.innerHTML = '<p class="hint">Put the cursor into a component to edit it with a form.</p>';
      return;
    }
    if (box.dataset.key === `${comp.start}:${comp.name}:${cs.classes ? 1 : 0}` && box.contains(document.activeElement)) return;
    box.dataset.key = `${comp.start}:${comp.name}:${cs.classes ? 1 : 0}`;
    box.replaceChildren();
    const desc = cs.classes?.get(comp.impl);
    const h = document.createElement('h4');
    h.textContent = `${comp.name} (${comp.impl || '?'})` + (desc?.summary ? `: ${desc.summary}` : '');
    box.appendChild(h);
    const table = document.createElement('table');
    const row = (label, input, doc) => {
      const tr = document.createElement('tr');
      const th = document.createElement('th');
      th.textContent = label;
      const td = document.createElement('td');
      td.appendChild(input);
      const tdoc = document.createElement('td');
      tdoc.className = 'doc';
      tdoc.textContent = doc;
      tr.append(th, td, tdoc);
      table.appendChild(tr);
    };
    for (const task of ['command_task', 'data_task']) {
      if (task === 'data_task' && desc && desc.data_task === 'none') continue;
      const input = document.createElement('input');
      input.type = 'text';
      input.size = 6;
      input.dataset.testid = `cfg-form-${task}-priority`;
      input.value = comp.tasks[task]?.priority ?? '';
      input.placeholder = task === 'command_task' ? '30' : '40';
      input.onchange = () => apply(() => setTaskPriority(text.value, comp, task, input.value.trim()));
      row(`${task} priority`, input, task === 'command_task' ? 'SCHED_FIFO 1..99' : 'SCHED_FIFO 1..99, 0: normal scheduling');
    }
    if (!desc) {
      const p = document.createElement('p');
      p.className = 'hint';
      p.textContent = cs.classes ? `class '${comp.impl}' has no description (a plug-in: its parameters come with rackd --check)` : 'loading the class descriptions…';
      box.append(table, p);
      return;
    }
    for (const prm of desc.parameters || []) {
      let input;
      if (prm.kind === 'bool' || prm.choices?.length) {
        input = document.createElement('select');
        const values = prm.kind === 'bool' ? ['true', 'false'] : prm.choices;
        input.appendChild(new Option(`(default ${prm.default})`, ''));
        for (const v of values) input.appendChild(new Option(v, v));
      } else {
        input = document.createElement('input');
        input.type = 'text';
        input.size = prm.kind === 'string' ? 24 : 10;
        input.placeholder = prm.required ? 'required' : prm.default;
      }
      input.dataset.testid = `cfg-form-param-${prm.name}`;
      input.value = comp.params[prm.name]?.value ?? '';
      input.onchange = () => apply(() => setParam(text.value, comp, prm, input.value));
      const range = prm.kind === 'int' || prm.kind === 'float'
        ? ` [${prm.min ?? '-inf'}..${prm.max ?? 'inf'}${prm.unit ? ' ' + prm.unit : ''}]` : (prm.unit ? ` [${prm.unit}]` : '');
      row(`${prm.name}${prm.required ? ' *' : ''}`, input, `${prm.kind}${range}: ${prm.doc}${prm.init_only ? ' (init only)' : ''}`);
    }
    box.appendChild(table);
  }
  function apply(edit) {
    const r = edit();
    if (r.error) { status(r.error, false); return; }
    const pos = text.selectionStart;
    text.value = r.text;
    text.setSelectionRange(Math.min(pos, r.text.length), Math.min(pos, r.text.length));
    changed();
  }

  // ------------------------------------------------------------ files, graph
  $('cfg-dir').onchange = () => { cs.dir = $('cfg-dir').value; fillFiles(); graph(); };
  $('cfg-file').onchange = () => load($('cfg-file').value);
  $('cfg-save').onclick = () => {
    if (!cs.file) return;
    status('saving…');
    sendText('config_save');
  };
  $('cfg-revert').onclick = () => { if (cs.file) { text.value = cs.disk; changed(); renderForm(); } };

  // The directory choice that draws what runs, from discovery alone (no host files).
  const kDiscovery = ':discovery';
  function fillFiles() {
    const sel = $('cfg-file');
    sel.replaceChildren(new Option('(choose a host file)', ''));
    const d = cs.dirs.find((x) => x.dir === cs.dir);
    for (const f of d?.files || []) sel.appendChild(new Option(f.name, f.file));
  }
  function load(file) {
    if (!file) return;
    if (text.value !== cs.disk && !confirm('Discard the changes to ' + cs.file + '?')) {
      $('cfg-file').value = cs.file;
      return;
    }
    request({ op: 'config_load', file });
  }
  function graph() {
    if (!cs.dir || cs.graphPending) return;
    const req = cs.dir === kDiscovery ? { op: 'config_graph', live: true }
      : { op: 'config_graph', dir: cs.dir, live: $('cfg-live').checked };
    cs.graphPending = request(req) !== null;
  }
  $('cfg-live').onchange = () => graph();
  // Live: refreshed every 5 s while the view is shown.
  setInterval(() => {
    if (($('cfg-live').checked || cs.dir === kDiscovery) && view.classList.contains('active')) graph();
  }, 5000);

  function renderGraph(m) {
    const box = view.querySelector('.cfg-graph');
    box.replaceChildren();
    if (m.svg) {
      // As an image: the SVG can hold nothing that runs.
      const img = document.createElement('img');
      img.alt = 'deployment graph';
      img.dataset.testid = 'cfg-graph';
      img.src = 'data:image/svg+xml;charset=utf-8,' + encodeURIComponent(m.svg);
      box.appendChild(img);
    } else {
      const p = document.createElement('p');
      p.className = 'hint';
      p.textContent = m.svg_error || 'no picture';
      const pre = document.createElement('pre');
      pre.dataset.testid = 'cfg-graph';
      pre.textContent = m.dot;
      box.append(p, pre);
    }
    const alloc = $('cfg-alloc');
    alloc.replaceChildren();
    for (const line of (m.allocation || '').split('\n')) {
      const div = document.createElement('div');
      div.textContent = line;
      if (/^\s*!/.test(line)) div.className = 'flag';
      if (/error:|STALE/.test(line)) div.className = 'bad';
      alloc.appendChild(div);
    }
    // Live: how the flows that run compare with the files' (green in the graph: runs
    // but no file declares it; grey and dotted: declared but not running).
    const lf = m.deployment?.live_flows;
    const files = m.deployment?.flows || [];
    $('cfg-flows').textContent = !Array.isArray(lf) ? ''
      : `live flows: ${lf.length} running, ${lf.filter((f) => !f.in_files).length} of them in no host file; ` +
        `${files.filter((f) => f.running === false).length} of the files' flows not running`;
    cs.deployment = m.deployment;
  }

  // ------------------------------------------------------------ replies
  function handle(m) {
    const req = m.id !== undefined ? cs.pending.get(m.id) : undefined;
    if (m.id !== undefined) cs.pending.delete(m.id);
    if (m.ok === false) {
      if (req?.op === 'config_graph') cs.graphPending = false;
      status(m.error || 'refused', false);
      return;
    }
    switch (m.op) {
      case 'config_files':
        cs.dirs = m.dirs || [];
        $('cfg-dir').replaceChildren(...cs.dirs.map((d) => new Option(d.dir, d.dir)),
          new Option('(what runs: discovery, no host files)', kDiscovery));
        if (!cs.dir) cs.dir = cs.dirs.length ? cs.dirs[0].dir : kDiscovery;
        if (cs.dir) $('cfg-dir').value = cs.dir;
        fillFiles();
        graph();
        if (!cs.dirs.length) status('rack-gui serves no host files: start it with --config DIR');
        break;
      case 'config_classes':
        cs.classes = new Map((m.classes || []).map((c) => [c.impl, c]));
        renderForm();
        break;
      case 'config_graph':
        cs.graphPending = false;
        renderGraph(m);
        if (m.live_error) status(m.live_error, false);
        break;
      case 'config_load':
        cs.file = m.file;
        cs.disk = m.text;
        cs.diskVersion = m.disk_version ?? '';
        text.value = m.text;
        $('cfg-file').value = m.file;
        cs.errors = [];
        renderErrors();
        changed();
        renderForm();
        break;
      case 'config_part':
        req?.after?.();
        break;
      case 'config_check':
      case 'config_save': {
        if (req && req.file !== cs.file) break;  // about another file
        cs.errors = m.errors || [];
        renderErrors();
        if (req) cs.checked = req.text;
        cs.valid = m.valid === true && cs.checked === text.value;
        if (m.op === 'config_save' && m.saved) {
          cs.disk = req.text;
          cs.diskVersion = m.disk_version ?? '';
          renderDiff();
          status(`saved ${cs.file} (rackd --check: valid)`, true);
          graph();
        } else if (m.disk_changed) {
          // The diff is against the text loaded, which is no longer on disk.
          status(m.save_error || `${cs.file} changed on disk since it was loaded: load it again before saving`, false);
        } else if (cs.checked !== text.value) {
          status('checking…');
        } else if (m.valid) {
          status('valid (rackd --check)', true);
        } else {
          status(`${cs.errors.length} error(s) (rackd --check)` + (m.op === 'config_save' ? ': not saved' : ''), false);
        }
        updateSave();
        break;
      }
      default: break;
    }
  }

  return {
    handle,
    show() {
      if (!cs.shown) {
        cs.shown = request({ op: 'config_files' }) !== null;
        if (cs.shown) request({ op: 'config_classes' });
      } else {
        cs.graphPending = false;  // a reply lost with a connection is not waited for
        graph();
      }
      renderGutter();
    },
  };
}
