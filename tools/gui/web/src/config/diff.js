// A line diff of two texts for the editor: rows {kind, text}, kind ' ' (context),
// '-' (only in a), '+' (only in b) or '@' (a hunk header "@@ -l,n +l,n @@"), with
// `context` unchanged lines around each change. Longest common subsequence of lines
// after the common head and tail are cut off; beyond kMaxCells the middle is shown as
// replaced whole (still correct, less minimal).
const kMaxCells = 4_000_000;

export function lineDiff(a, b, context = 2) {
  const x = a.split('\n');
  const y = b.split('\n');
  let head = 0;
  while (head < x.length && head < y.length && x[head] === y[head]) head++;
  let tail = 0;
  while (tail < x.length - head && tail < y.length - head && x[x.length - 1 - tail] === y[y.length - 1 - tail]) tail++;
  const xs = x.slice(head, x.length - tail);
  const ys = y.slice(head, y.length - tail);
  const ops = [];  // {kind, text, ai, bi}
  for (let i = 0; i < head; i++) ops.push({ kind: ' ', text: x[i], ai: i, bi: i });
  if (xs.length * ys.length <= kMaxCells) {
    const n = xs.length, m = ys.length;
    const L = Array.from({ length: n + 1 }, () => new Uint32Array(m + 1));
    for (let i = n - 1; i >= 0; i--) for (let j = m - 1; j >= 0; j--) {
      L[i][j] = xs[i] === ys[j] ? L[i + 1][j + 1] + 1 : Math.max(L[i + 1][j], L[i][j + 1]);
    }
    let i = 0, j = 0;
    while (i < n || j < m) {
      if (i < n && j < m && xs[i] === ys[j]) { ops.push({ kind: ' ', text: xs[i], ai: head + i, bi: head + j }); i++; j++; }
      else if (i < n && (j === m || L[i + 1][j] >= L[i][j + 1])) { ops.push({ kind: '-', text: xs[i], ai: head + i, bi: head + j }); i++; }
      else { ops.push({ kind: '+', text: ys[j], ai: head + i, bi: head + j }); j++; }
    }
  } else {
    xs.forEach((t, i) => ops.push({ kind: '-', text: t, ai: head + i, bi: head }));
    ys.forEach((t, j) => ops.push({ kind: '+', text: t, ai: head + xs.length, bi: head + j }));
  }
  for (let i = 0; i < tail; i++) {
    ops.push({ kind: ' ', text: x[x.length - tail + i], ai: x.length - tail + i, bi: y.length - tail + i });
  }
  // Hunks: changes with `context` lines around them.
  const keep = new Array(ops.length).fill(false);
  ops.forEach((o, k) => {
    if (o.kind === ' ') return;
    for (let d = Math.max(0, k - context); d <= Math.min(ops.length - 1, k + context); d++) keep[d] = true;
  });
  const rows = [];
  for (let k = 0; k < ops.length; k++) {
    if (!keep[k]) continue;
    if (k === 0 || !keep[k - 1]) {
      let e = k;
      while (e < ops.length && keep[e]) e++;
      const part = ops.slice(k, e);
      const na = part.filter((o) => o.kind !== '+').length;
      const nb = part.filter((o) => o.kind !== '-').length;
      rows.push({ kind: '@', text: `@@ -${ops[k].ai + 1},${na} +${ops[k].bi + 1},${nb} @@` });
    }
    rows.push({ kind: ops[k].kind, text: ops[k].text });
  }
  return rows;
}
