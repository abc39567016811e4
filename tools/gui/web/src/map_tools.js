// Map tools (issue 21 item 4): the legend, which is also the layer switch (a checkbox
// per layer, its colour beside it), a scale bar, the cursor's map coordinates, and
// follow-robot mode (the view keeps the robot's pose in its centre). main.js draws
// the layers that are on; this module owns their state and the overlays.

// Layer -> [label, colour]: the colours main.js draws them in.
export const LAYERS = {
  map: ['occupancy map', '#1e1e1e'],
  path: ['path', '#1e88e5'],
  scan: ['laser scan', '#e53935'],
  particles: ['MCL particles', '#e65100'],
  ellipse: ['2σ ellipse', '#1a237e'],
  robot: ['robot (estimate)', '#00897b'],
  truth: ['true pose (simulator)', '#555555'],
  target: ['destination', '#6a1b9a'],
};

export function setupMapTools({ st, $ }) {
  const layers = Object.fromEntries(Object.keys(LAYERS).map((k) => [k, true]));
  st.layers = layers;
  const legend = $('map-legend');
  legend.replaceChildren(...Object.entries(LAYERS).map(([key, [label, colour]]) => {
    const l = document.createElement('label');
    l.dataset.testid = `layer-${key}`;
    const box = document.createElement('input');
    box.type = 'checkbox';
    box.checked = true;
    box.onchange = () => { layers[key] = box.checked; };
    const sw = document.createElement('span');
    sw.className = 'swatch';
    sw.style.background = colour;
    l.append(box, sw, document.createTextNode(label));
    return l;
  }));
  $('legend-toggle').onclick = () => legend.classList.toggle('collapsed');
  // On a phone the legend starts folded (one tap shows it): the map comes first.
  if (window.matchMedia('(max-width: 700px)').matches) legend.classList.add('collapsed');

  // Follow mode: the view's centre follows the robot (zoom stays the user's).
  const follow = $('follow-robot');
  st.view.follow = false;
  follow.onchange = () => { st.view.follow = follow.checked; };

  // Cursor coordinates in the map frame (metres), below the map.
  const cursor = $('map-cursor');
  const canvas = $('map');
  canvas.addEventListener('pointermove', (e) => {
    const r = canvas.getBoundingClientRect();
    const dpr = canvas.width / r.width;
    const px = (e.clientX - r.left) * dpr, py = (e.clientY - r.top) * dpr;
    if (!st.view.scale) return;
    const x = (px - st.view.ox) / st.view.scale, y = (st.view.oy - py) / st.view.scale;
    st.cursor = { x, y };
    cursor.textContent = `cursor x ${x.toFixed(2)} m, y ${y.toFixed(2)} m`;
  });
  canvas.addEventListener('pointerleave', () => { cursor.textContent = 'cursor: off the map'; });

  return {
    layers,
    // Called by the draw loop before drawing: follow mode re-centres on `pose`.
    follow(pose, canvasEl) {
      if (!st.view.follow || !pose) return;
      st.view.ox = canvasEl.width / 2 - pose.x * st.view.scale;
      st.view.oy = canvasEl.height / 2 + pose.y * st.view.scale;
    },
    // The scale bar (a round length of 60..160 css px) in the bottom-left corner.
    drawScale(ctx, scale, H) {
      if (!(scale > 0)) return;
      const dpr = window.devicePixelRatio || 1;
      const target = 120 * dpr / scale;  // metres in ~120 css px
      const p = 10 ** Math.floor(Math.log10(target));
      const m = [1, 2, 5, 10].map((k) => k * p).reduce((best, v) => (Math.abs(v - target) < Math.abs(best - target) ? v : best));
      const len = m * scale;
      const x = 12 * dpr, y = H - 14 * dpr;
      ctx.globalAlpha = 1;
      ctx.fillStyle = 'rgba(255,255,255,0.8)';
      ctx.fillRect(x - 6 * dpr, y - 20 * dpr, len + 12 * dpr + 50 * dpr, 28 * dpr);
      ctx.strokeStyle = '#000';
      ctx.lineWidth = 2 * dpr;
      ctx.beginPath();
      ctx.moveTo(x, y - 6 * dpr); ctx.lineTo(x, y); ctx.lineTo(x + len, y); ctx.lineTo(x + len, y - 6 * dpr);
      ctx.stroke();
      ctx.fillStyle = '#000';
      ctx.font = `${12 * dpr}px sans-serif`;
      const text = m >= 1 ? `${m} m` : `${Math.round(m * 100)} cm`;
      ctx.fillText(text, x + len + 6 * dpr, y);
      st.scaleBar = { metres: m, px: len / dpr };
    },
  };
}
