// Edits of a host file's text in place: one value on one line (or one inserted line),
// so that comments and layout survive. Understands the layout the host files use
// (configs/): a block list `components:` whose items are block maps or one-line flow
// maps, tasks as `{priority: N, ...}` or a block, `params:` as a block map or a one-line
// flow map (edited in place in the map). Plain functions of the text: no DOM.

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

// The flow map `{...}` that opens at line[open]: its closing brace and its top-level
// pairs, each {key, keyStart, valueStart, valueEnd} (positions in `line`; the value
// trimmed), or null when it does not close on this line. Quotes ("..." with
// backslash escapes, '...' with '') and nested maps and lists are skipped whole.
export function flowMapAt(line, open) {
  if (line[open] !== '{') return null;
  const pairs = [];
  let depth = 0, quote = null, start = open + 1;
  const addPair = (endAt) => {
    const raw = line.slice(start, endAt);
    if (!raw.trim()) return;
    let colon = -1, d = 0, q = null;
    for (let i = 0; i < raw.length; i++) {
      const ch = raw[i];
      if (q) { if (q === '"' && ch === '\\') i++; else if (ch === q) q = null; continue; }
      if (ch === '"' || ch === "'") q = ch;
      else if (ch === '{' || ch === '[') d++;
      else if (ch === '}' || ch === ']') d--;
      else if (ch === ':' && d === 0 && (i + 1 === raw.length || /\s/.test(raw[i + 1]))) { colon = i; break; }
    }
    if (colon < 0) return;
    const keyStart = start + raw.length - raw.trimStart().length;
    let valueStart = start + colon + 1;
    while (valueStart < endAt && /\s/.test(line[valueStart])) valueStart++;
    let valueEnd = endAt;
    while (valueEnd > valueStart && /\s/.test(line[valueEnd - 1])) valueEnd--;
    pairs.push({ key: unquote(raw.slice(0, colon).trim()), keyStart, valueStart, valueEnd });
  };
  for (let i = open + 1; i < line.length; i++) {
    const ch = line[i];
    if (quote) {
      if (quote === '"' && ch === '\\') i++;
      else if (ch === quote) { if (quote === "'" && line[i + 1] === "'") i++; else quote = null; }
      continue;
    }
    if (ch === '"' || ch === "'") quote = ch;
    else if (ch === '{' || ch === '[') depth++;
    else if ((ch === '}' || ch === ']') && depth > 0) depth--;
    else if (ch === '}' && depth === 0) { addPair(i); return { close: i, pairs }; }
    else if (ch === ',' && depth === 0) { addPair(i); start = i + 1; }
  }
  return null;
}

// Sets (or removes) `name` in the flow map `params: {...}` on line `index`: the value
// replaced in place, a new pair appended before the closing brace, a removed pair
// taken out with its comma; the rest of the line (other values, comments) as it was.
function setFlowParam(lines, index, comp, name, v) {
  const line = lines[index];
  let open = -1;
  if (comp.flow) {  // - {name: x, ..., params: {...}}
    const outer = flowMapAt(line, line.indexOf('{'));
    const p = outer?.pairs.find((x) => x.key === 'params');
    if (!p) {
      if (!outer || v === null) return outer ? { text: lines.join('\n') } : { error: `cannot read line ${index + 1}: edit the text` };
      const before = line.slice(0, outer.close).replace(/\s+$/, '');
      lines[index] = `${before}, params: {${name}: ${v}}${line.slice(before.length).replace(/^\s*/, '')}`;
      return { text: lines.join('\n') };
    }
    open = p.valueStart;
  } else {  // params: {...}
    const kv = splitValue(line);
    open = kv ? kv.prefix.length : -1;
  }
  const map = open >= 0 ? flowMapAt(line, open) : null;
  if (!map) return { error: `the params on line ${index + 1} are not one {...} on that line: edit the text` };
  const i = map.pairs.findIndex((x) => x.key === name);
  if (v === null) {  // remove
    if (i < 0) return { text: lines.join('\n') };
    const pr = map.pairs[i];
    let from = pr.keyStart, to = pr.valueEnd;
    if (i + 1 < map.pairs.length) to = map.pairs[i + 1].keyStart;  // "a: 1, " up to the next key
    else if (i > 0) from = map.pairs[i - 1].valueEnd;              // ", a: 1" after the previous value
    lines[index] = line.slice(0, from) + line.slice(to);
    return { text: lines.join('\n') };
  }
  if (i >= 0) {
    const pr = map.pairs[i];
    lines[index] = line.slice(0, pr.valueStart) + v + line.slice(pr.valueEnd);
    return { text: lines.join('\n') };
  }
  const last = map.pairs[map.pairs.length - 1];
  lines[index] = last
    ? `${line.slice(0, last.valueEnd)}, ${name}: ${v}${line.slice(last.valueEnd)}`
    : `${line.slice(0, map.close)}${name}: ${v}${line.slice(map.close)}`;
  return { text: lines.join('\n') };
}

// Sets (or, with '', removes) parameter `prm` of `comp`: {text} or {error}. Parameters
// written on one line (`params: {a: 1, b: 2}`, or a component written as one flow map)
// are edited in place in that map.
export function setParam(text, comp, prm, value) {
  const lines = text.split('\n');
  if (comp.flow) return setFlowParam(lines, comp.start, comp, prm.name, value === '' ? null : yamlValue(prm, value));
  if (comp.paramsFlow) return setFlowParam(lines, comp.paramsLine, comp, prm.name, value === '' ? null : yamlValue(prm, value));
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
