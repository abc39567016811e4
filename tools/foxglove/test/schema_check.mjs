// A message against the JSON schema of its channel (the checks of test/*.mjs).

// Every key of the message is a property of its schema, with the schema's JSON type.
export function matchesSchema(message, schema, where) {
  const type = (v) => (Array.isArray(v) ? 'array' : v === null ? 'null' : Number.isInteger(v) ? 'integer' : typeof v);
  const ok = (v, s) => {
    if (!s || !s.type) return true;
    const t = type(v);
    if (s.type === 'number') return t === 'integer' || t === 'number';
    if (s.type === 'integer') return t === 'integer';
    return t === s.type;
  };
  for (const [k, v] of Object.entries(message)) {
    const p = schema.properties?.[k];
    if (!p) return `${where}: key '${k}' is not in schema ${schema.title}`;
    if (!ok(v, p)) return `${where}: key '${k}' is ${type(v)}, schema says ${p.type}`;
    if (p.type === 'object' && p.properties && typeof v === 'object') {
      const inner = matchesSchema(v, p, `${where}.${k}`);
      if (inner) return inner;
    }
  }
  return '';
}
