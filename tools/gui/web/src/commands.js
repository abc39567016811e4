// Class-command panel (issue 21 item 4), in the Component view: every command the
// component's class describes (GET_CLASS through rack-gui's "class" message), by
// name with its summary, its body's fields as a form (arrays as comma-separated
// values), a "send" button, and the answer shown beside it: OK, the component's
// ERROR reason, or rack-gui's refusal (a field that does not fit its kind: nothing
// is sent). Fields left empty are sent as 0, and the result line says what was sent.
import { unitOf } from './numbers.js';

export function setupCommands({ st, send }) {
  const waiting = new Map();  // request id -> result element

  function esc(s) { return String(s).replace(/[&<>"]/g, (ch) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[ch])); }

  // Fills `el` with the panel of component `address` (asks for its class when unknown).
  function render(el, address) {
    if (!el) return;
    const cls = st.classes.get(address);
    if (!cls) {
      el.innerHTML = '<h3>Commands</h3><p class="hint">asking the component for its class description…</p>';
      send({ op: 'get_class', component: address });
      return;
    }
    const parts = [`<h3>Commands</h3>`];
    if (cls.commands.length === 0) parts.push(`<p class="hint">class ${esc(cls.class)} describes no commands</p>`);
    for (const c of cls.commands) {
      parts.push(`<form class="cmd" data-testid="cmd-${esc(c.name)}" data-cmd="${esc(c.name)}"><div class="cmdhead"><button type="submit">${esc(c.name)}</button> <span class="hint">${esc(c.summary)}${c.body ? '' : ' (no body)'}</span></div>`);
      if (c.body) {
        parts.push('<div class="cmdfields">');
        for (const f of c.body.fields) {
          if (f.name.endsWith('_')) continue;  // padding
          const unit = unitOf(f.name);
          const hint = `${f.kind}${f.count > 1 ? `[${f.count}]` : ''}${unit ? ', ' + unit : ''}`;
          parts.push(`<label>${esc(f.name)} <input name="${esc(f.name)}" placeholder="${esc(hint)}" size="${f.kind === 'char' ? 16 : 8}" data-kind="${esc(f.kind)}"></label>`);
        }
        parts.push('</div>');
      }
      parts.push('<div class="cmdresult" data-testid="cmd-result"></div></form>');
    }
    el.innerHTML = parts.join('');
    for (const form of el.querySelectorAll('form.cmd')) {
      form.onsubmit = (e) => {
        e.preventDefault();
        const fields = {};
        for (const input of form.querySelectorAll('input[name]')) {
          if (input.value.trim() !== '') fields[input.name] = input.value.trim();
        }
        const out = form.querySelector('.cmdresult');
        out.className = 'cmdresult';
        out.textContent = 'sent, waiting for the answer…';
        const id = send({ op: 'command', component: address, name: form.dataset.cmd, fields });
        if (id !== null) waiting.set(id, out);
      };
    }
  }

  // rack-gui's "result" for a command request: true when it was one of ours.
  function onResult(m) {
    if (m.op !== 'command' || !waiting.has(m.id)) return false;
    const out = waiting.get(m.id);
    waiting.delete(m.id);
    out.className = `cmdresult ${m.ok ? 'good' : 'bad'}`;
    out.textContent = (m.ok ? 'answered: ' : 'failed: ') + m.text + (out.dataset.extra ?? '');
    return true;
  }
  // The reply's details (its type and body), before the result.
  function onCommandResult(m) {
    const out = waiting.get(m.id);
    if (out) out.dataset.extra = m.body_bytes ? ` (reply body ${m.body_bytes} bytes: ${m.body_hex}${m.body_bytes > 64 ? '…' : ''})` : '';
  }
  return { render, onResult, onCommandResult };
}
