// Edits of a host file's text in place: one value on one line (or one inserted line),
// so that comments and layout survive. Understands the layout the host files use
// (configs/): a block list `components:` whose items are block maps or one-line flow
// maps, tasks as `{priority: N, ...}` or a block, `params:` as a block map (a flow
// map's values are shown, and edited in the text). Plain functions of the text: no DOM.

const indentOf = (line) => line.length - line.trimStart().length;
const isBlank = (line) => /^\s*(#.*)?$/.test(line);

// A line `key: value  # comment` split into [prefix, value, suffix]; quoted values
// may hold '#'.
export function splitValue(line) {
  const m = /^(\s*(?:-\s+)?[^\s:#][^:#]*:[ \t]*)(.*)$/.exec(line);
  if (!m) return null;
  const prefix = m[1];
  const rest = m[2];
  let end = rest.length;
  if (rest.startsWith('"') || rest.startsWith("'")) {
    const q = rest[0];
    let i = 1;
    while (i < rest.length) {
      if (q === '"' && rest[i] === '\\') { i += 2; continue; }
      if (rest[i] === q) { if (q === "'" && rest[i + 1] === "'") { i += 2; continue; } break; }
      i++;
    }
    end = Math.min(i + 1, rest.length);
  } else {
    const c = rest.search(/\s#/);
    if (c >= 0) end = c;
    else if (rest.startsWith('#')) end = 0;
  }
  const value = rest.slice(0, end).replace(/\s+$/, '');
  return { prefix, value, suffix: rest.slice(value.length) };
}

function unquote(v) {
  if (v.startsWith('"')) { try { return JSON.parse(v); } catch { return v; } }
  if (v.startsWith("'") && v.endsWith("'")) return v.slice(1, -1).replace(/''/g, "'");
  return v;
}

// Pairs of a one-line flow map `{a: 1, b: {c: 2}}` at the top level (values as text).
function flowPairs(text) {
  const out = {};
  const body = text.trim().replace(/^\{/, '').replace(/\}\s*$/, '');
  let depth = 0, start = 0, quote = null;
  const parts = [];
  for (let i = 0; i < body.length; i++) {
    const ch = body[i];
    if (quote) { if (ch === quote) quote = null; continue; }
    if (ch === '"' || ch === "'") quote = ch;
    else if (ch === '{' || ch === '[') depth++;
    else if (ch === '}' || ch === ']') depth--;
    else if (ch === ',' && depth === 0) { parts.push(body.slice(start, i)); start = i + 1; }
  }
  parts.push(body.slice(start));
  for (const p of parts) {
    const c = p.indexOf(':');
    if (c < 0) continue;
    out[p.slice(0, c).trim()] = p.slice(c + 1).trim();
  }
  return out;
}

// The component whose lines hold line `lineNo` (1-based), or null:
// {start, end (exclusive, 0-based lines), keyIndent, name, impl, flow, tasks, params, paramsLine, paramsFlow}
export function componentAt(text, lineNo) {
  const lines = text.split('\n');
  const top = lines.findIndex((l) => /^components:/.test(l));
  if (top < 0 || lineNo - 1 <= top) return null;
  let itemIndent = -1;
  for (let i = top + 1; i < lines.length; i++) {
    if (isBlank(lines[i])) continue;
    const m = /^(\s*)-\s/.exec(lines[i]);
    if (m) itemIndent = m[1].length;
    break;
  }
  if (itemIndent < 0) return null;
  const isItem = (l) => indentOf(l) === itemIndent && /^\s*-\s/.test(l);
  const ends = (l) => !isBlank(l) && (indentOf(l) < itemIndent || (indentOf(l) === itemIndent && !/^\s*-\s/.test(l)));
  let start = -1;
  for (let i = Math.min(lineNo - 1, lines.length - 1); i > top; i--) {
    if (isItem(lines[i])) { start = i; break; }
    if (ends(lines[i])) return null;
  }
  if (start < 0) return null;
  let end = start + 1;
  while (end < lines.length && !isItem(lines[end]) && !ends(lines[end])) end++;
  while (end > start + 1 && isBlank(lines[end - 1])) end--;
  const comp = { start, end, keyIndent: itemIndent + 2, name: '', impl: '', flow: false, tasks: {}, params: {}, paramsLine: -1, paramsFlow: false };
  const first = lines[start].slice(itemIndent + 1).trimStart();
  if (first.startsWith('{')) {  // a one-line flow map
    comp.flow = true;
    const pairs = flowPairs(first.replace(/\s#.*$/, ''));
    comp.name = unquote(pairs.name || '');
    comp.impl = unquote(pairs.class || '');
    for (const task of ['command_task', 'data_task']) {
      if (pairs[task]) comp.tasks[task] = { line: start, flow: true, priority: flowPairs(pairs[task]).priority };
    }
    if (pairs.params) {
      comp.paramsFlow = true;
      comp.paramsLine = start;
      for (const [k, v] of Object.entries(flowPairs(pairs.params))) comp.params[k] = { value: unquote(v), line: start };
    }
    return comp;
  }
  // Block map: keys at keyIndent (the first after "- ").
  let key = null, keyLine = -1;
  for (let i = start; i < end; i++) {
    const l = i === start ? ' '.repeat(itemIndent) + '  ' + lines[i].slice(itemIndent + 1).trimStart() : lines[i];
    if (isBlank(l)) continue;
    const ind = indentOf(l);
    if (ind === comp.keyIndent) {
      const kv = splitValue(l);
      if (!kv) continue;
      key = l.trim().split(':')[0].trim();
      keyLine = i;
      const v = kv.value;
      if (key === 'name') comp.name = unquote(v);
      else if (key === 'class') comp.impl = unquote(v);
      else if (key === 'command_task' || key === 'data_task') {
        comp.tasks[key] = { line: i, flow: v.startsWith('{'), priority: v.startsWith('{') ? flowPairs(v).priority : undefined, keyLine: i, last: i };
      } else if (key === 'params') {
        comp.paramsLine = i;
        comp.paramsFlow = v.startsWith('{');
        if (comp.paramsFlow) for (const [k, pv] of Object.entries(flowPairs(v))) comp.params[k] = { value: unquote(pv), line: i };
        comp.paramsLast = i;
      }
    } else if (ind > comp.keyIndent && keyLine >= 0) {
      const kv = splitValue(l);
      if ((key === 'command_task' || key === 'data_task') && comp.tasks[key]) {
        comp.tasks[key].last = i;
        if (kv && /^\s*priority:/.test(l)) { comp.tasks[key].priority = kv.value; comp.tasks[key].line = i; comp.tasks[key].block = true; }
      } else if (key === 'params' && !comp.paramsFlow) {
        comp.paramsLast = i;
        if (comp.paramIndent === undefined) comp.paramIndent = ind;
        if (kv && ind === comp.paramIndent) {
          comp.params[l.trim().split(':')[0].trim()] = { value: unquote(kv.value), line: i };
        }
      }
    }
  }
  return comp;
}

// A value as YAML: numbers and booleans as typed, plain words plain, anything else quoted.
export function yamlValue(prm, value) {
  if (prm.kind === 'string') {
    if (/^[A-Za-z_/.][A-Za-z0-9_./()-]*$/.test(value) && !/^(true|false|yes|no|on|off|null|~)$/i.test(value) &&
        !/[()]/.test(value)) return value;
    return JSON.stringify(value);
  }
  return value;
}

function replaceValue(line, value) {
  const kv = splitValue(line);
  return kv ? kv.prefix + value + kv.suffix : line;
}

// Sets (or, with '', removes) parameter `prm` of `comp`: {text} or {error}.
export function setParam(text, comp, prm, value) {
  const lines = text.split('\n');
  if (comp.flow || comp.paramsFlow) return { error: `'${comp.name}' writes its params in one line ({...}): edit them in the text` };
  const have = comp.params[prm.name];
  if (value === '') {
    if (!have) return { text };
    lines.splice(have.line, 1);
    return { text: lines.join('\n') };
  }
  const v = yamlValue(prm, value);
  if (have) {
    lines[have.line] = replaceValue(lines[have.line], v);
    return { text: lines.join('\n') };
  }
  if (comp.paramsLine >= 0) {
    const ind = comp.paramIndent ?? comp.keyIndent + 2;
    lines.splice((comp.paramsLast ?? comp.paramsLine) + 1, 0, `${' '.repeat(ind)}${prm.name}: ${v}`);
    return { text: lines.join('\n') };
  }
  lines.splice(comp.end, 0, `${' '.repeat(comp.keyIndent)}params:`, `${' '.repeat(comp.keyIndent + 2)}${prm.name}: ${v}`);
  return { text: lines.join('\n') };
}

// Sets the priority of `task` ('command_task' | 'data_task') of `comp`: {text} or {error}.
export function setTaskPriority(text, comp, task, value) {
  if (value === '') return { error: 'give a priority (the form does not remove it; edit the text)' };
  const lines = text.split('\n');
  const t = comp.tasks[task];
  if (t && t.flow) {
    const line = lines[t.line];
    const key = line.indexOf(`${task}:`);
    const open = line.indexOf('{', key);
    if (key < 0 || open < 0) return { error: `cannot find ${task} on line ${t.line + 1}: edit the text` };
    const close = line.indexOf('}', open);
    const inner = line.slice(open + 1, close < 0 ? line.length : close);
    const replaced = /priority:\s*[^,}]*/.test(inner)
      ? inner.replace(/priority:\s*[^,}]*?(\s*)(?=,|$)/, `priority: ${value}$1`)
      : `priority: ${value}${inner.trim() ? ', ' : ''}${inner.trimStart()}`;
    lines[t.line] = line.slice(0, open + 1) + replaced + line.slice(close < 0 ? line.length : close);
    return { text: lines.join('\n') };
  }
  if (t && t.block) {
    lines[t.line] = replaceValue(lines[t.line], value);
    return { text: lines.join('\n') };
  }
  if (t) {  // a block without priority
    lines.splice(t.keyLine + 1, 0, `${' '.repeat(comp.keyIndent + 2)}priority: ${value}`);
    return { text: lines.join('\n') };
  }
  if (comp.flow) return { error: `'${comp.name}' is written in one line ({...}): edit it in the text` };
  const at = comp.paramsLine >= 0 ? comp.paramsLine : comp.end;
  lines.splice(at, 0, `${' '.repeat(comp.keyIndent)}${task}: {priority: ${value}}`);
  return { text: lines.join('\n') };
}
