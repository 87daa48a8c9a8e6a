// Canvas replay of the runs of a study, inlined into the report page by ayllu-sim's report module.
//
// Reads the JSON in <script id="data"> ({colours, runs: [{setting, controller, seed}]}) to fill
// the three menus, and the run chosen from <script id="run-N"> (a Replay of report/replay.rs:
// decimated, delta-coded poses and exact state changes); draws the arena at the current time,
// and keeps the side panel, the timeline and the controls in step. Promises: each time a run's
// frame is on the canvas, body[data-status] is "drawn", body[data-run] is that run's
// "setting|controller|seed", body[data-canvas] holds the canvas's page rectangle "x,y,w,h" in CSS
// pixels, body[data-walls] the arena's inner walls "x,y,w,h" and body[data-labels] every label
// drawn in the arena "text@x,y,w,h;..." (canvas CSS pixels; each is kept inside the walls), and
// body[data-robots] the robots' drawn positions "x,y;..." (arena metres);
// nothing here touches the network. Arena coordinates are metres, y up; the canvas is y down.
(function () {
  'use strict';

  const data = JSON.parse(document.getElementById('data').textContent);
  const runs = data.runs;
  // The run on screen, set by load(): everything that draws reads these.
  let current = -1;
  let rec = null;
  let meta = null;
  let arenaW = 1;
  let arenaH = 1;
  let dt = 1; // seconds between recorded frames
  let nFrames = 0;
  let endT = 0;
  let samples = []; // the recorded frame of each pose sample
  let poses = []; // per robot: [x, y, theta] per sample
  let paths = []; // per target: [x, y] per sample
  let states = []; // per robot: [frame, alive, drive, claims, inhibited, observing] at each change
  let coverage = []; // [t, A_w] at each change of who observes what

  // Cool colours for robots so they never read as the warm-coloured targets.
  const ROBOT_COLOURS = ['#1f77b4', '#2ca02c', '#9467bd', '#17becf', '#8c564b', '#e377c2',
    '#393b79', '#637939', '#7b4173', '#3182bd', '#006d77', '#5254a3'];
  const robotColour = (i) => ROBOT_COLOURS[i % ROBOT_COLOURS.length];
  const DEAD = '#a9a9a9';
  const OBSERVED = '#1a9850';
  const KILL = '#c81e1e';

  // Targets: warm colour and size by priority rank (target 1 is the highest priority).
  let pMin = 0;
  let pMax = 1;
  const prioShare = (p) => (pMax > pMin ? (p - pMin) / (pMax - pMin) : 1);
  function targetColour(p) {
    const s = prioShare(p);
    const mix = (a, b) => Math.round(a + (b - a) * s);
    return `rgb(${mix(246, 192)},${mix(190, 40)},${mix(70, 30)})`;
  }
  let targetIndex = new Map();

  const arena = document.getElementById('arena');
  const ctx = arena.getContext('2d');
  const timeline = document.getElementById('timeline');
  const tctx = timeline.getContext('2d');
  const slider = document.getElementById('slider');
  const playBtn = document.getElementById('play');
  const speedSel = document.getElementById('speed');
  const clock = document.getElementById('clock');
  const robotsBody = document.getElementById('robots-state');
  const targetsBody = document.getElementById('targets-state');
  const settingSel = document.getElementById('run-setting');
  const controllerSel = document.getElementById('run-controller');
  const seedSel = document.getElementById('run-seed');
  const facts = document.getElementById('run-facts');

  let t = 0;
  let playing = false;
  let lastWall = null;
  let view = { w: 0, h: 0, s: 1, ox: 0, oy: 0 };
  let panelFrame = -1;

  // ---- geometry -----------------------------------------------------------------------------

  function layout() {
    const dpr = window.devicePixelRatio || 1;
    // Leave room for the side panel; keep the arena's aspect ratio and a bounded height so
    // the controls stay on screen.
    const avail = Math.max(360, Math.min(780, window.innerWidth - 32 - 16 - 360));
    // Width decides, not the window's height: headless browsers report different heights for
    // the same window size, and a screenshot test must find the canvas where the DOM said.
    const maxH = 620;
    const margin = 26;
    const aspect = arenaH > 0 && arenaW > 0 ? arenaH / arenaW : 1;
    let w = avail;
    let h = Math.round((w - 2 * margin) * aspect + 2 * margin);
    if (h > maxH) {
      h = maxH;
      w = Math.round((h - 2 * margin) / aspect + 2 * margin);
    }
    arena.style.width = w + 'px';
    arena.style.height = h + 'px';
    arena.width = Math.round(w * dpr);
    arena.height = Math.round(h * dpr);
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    const s = Math.min((w - 2 * margin) / (arenaW || 1), (h - 2 * margin) / (arenaH || 1));
    view = { w, h, s, ox: (w - s * arenaW) / 2, oy: (h - s * arenaH) / 2 };

    timeline.style.width = w + 'px';
    timeline.style.height = '58px';
    timeline.width = Math.round(w * dpr);
    timeline.height = Math.round(58 * dpr);
    tctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    document.querySelector('.controls').style.width = w + 'px';
    document.querySelector('.replay-note').style.maxWidth = Math.max(w, 360) + 'px';
  }

  const X = (x) => view.ox + x * view.s;
  const Y = (y) => view.h - view.oy - y * view.s;

  // ---- runs ---------------------------------------------------------------------------------

  const ALPHABET = 'ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/';
  const DIGIT = new Map(Array.from(ALPHABET).map((c, i) => [c, i]));

  // The integers of a replay.rs code: one character for a delta within ±31, '/' and four
  // base-64 digits for anything else.
  function decode(text) {
    const out = [];
    const digit = (i) => {
      const d = DIGIT.get(text[i]);
      if (d === undefined) throw new Error(`bad replay code at character ${i}`);
      return d;
    };
    for (let i = 0; i < text.length;) {
      if (text[i] === '/') {
        let v = 0;
        for (let k = 1; k <= 4; k++) v = v * 64 + digit(i + k);
        out.push(v - (1 << 23));
        i += 5;
      } else {
        out.push(digit(i) - 31);
        i += 1;
      }
    }
    return out;
  }

  // Deltas back to positions: centimetres to metres, 1/256 turns to radians.
  function integrate(text, width) {
    const d = decode(text);
    const acc = new Array(width).fill(0);
    const out = [];
    for (let i = 0; i + width <= d.length; i += width) {
      const p = [];
      for (let c = 0; c < width; c++) {
        acc[c] += d[i + c];
        p.push(c === 2 ? (((acc[c] % 256) + 256) % 256) / 256 * 2 * Math.PI : acc[c] / 100);
      }
      out.push(p);
    }
    return out;
  }

  // A robot's state changes: frames since the previous change, alive, drive, then claims,
  // inhibited and observing, each as its length and its target ids.
  function changes(text) {
    const d = decode(text);
    const out = [];
    let frame = 0;
    let i = 0;
    const list = () => {
      const n = d[i++];
      const ids = d.slice(i, i + n);
      i += n;
      return ids;
    };
    while (i < d.length) {
      frame += d[i];
      const alive = d[i + 1];
      const drive = d[i + 2];
      i += 3;
      out.push([frame, alive, drive, list(), list(), list()]);
    }
    return out;
  }

  // The last change at or before `frame` (changes are in frame order).
  function stateIn(list, frame) {
    let lo = 0;
    let hi = list.length - 1;
    if (hi < 0 || list[0][0] > frame) return null;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (list[mid][0] <= frame) lo = mid; else hi = mid - 1;
    }
    return list[lo];
  }

  // A_w over time, a step at every frame where someone's observations change.
  function coverageSteps() {
    const total = rec.targets.reduce((sum, tg) => sum + tg.priority, 0) || 1;
    const changes = Array.from(new Set([0].concat(...states.map((l) => l.map((c) => c[0]))))).sort((a, b) => a - b);
    return changes.map((f) => {
      const seen = new Set();
      states.forEach((l) => {
        const c = stateIn(l, f);
        if (c && c[1]) c[5].forEach((id) => seen.add(id));
      });
      const w = rec.targets.reduce((sum, tg) => sum + (seen.has(tg.id) ? tg.priority : 0), 0);
      return [f * dt, w / total];
    });
  }

  function load(index) {
    const raw = JSON.parse(document.getElementById('run-' + index).textContent);
    current = index;
    rec = raw;
    meta = raw.meta;
    [arenaW, arenaH] = meta.arena;
    dt = meta.frame_dt > 0 ? meta.frame_dt : 1;
    nFrames = raw.frames;
    endT = Math.max(0, (nFrames - 1) * dt);
    const every = Math.max(1, raw.every);
    samples = [];
    for (let f = 0; f < nFrames; f += every) samples.push(f);
    if (nFrames > 0 && samples[samples.length - 1] !== nFrames - 1) samples.push(nFrames - 1);
    poses = raw.poses.map((text) => integrate(text, 3));
    paths = raw.paths.map((text) => integrate(text, 2));
    states = raw.states.map(changes);
    const prios = rec.targets.map((tg) => tg.priority);
    pMin = Math.min(...prios, 0);
    pMax = Math.max(...prios, 1);
    targetIndex = new Map(rec.targets.map((tg, i) => [tg.id, i]));
    coverage = coverageSteps();
    panelFrame = -1;
    fillFacts();
  }

  // ---- state at a time ------------------------------------------------------------------------

  function frameIndex(time) {
    if (!nFrames || !samples.length) return -1;
    return Math.max(0, Math.min(nFrames - 1, Math.floor(time / dt + 1e-9)));
  }

  // The pose sample at or before `time`.
  function sampleIndex(time) {
    const every = Math.max(1, rec.every);
    return Math.max(0, Math.min(samples.length - 1, Math.floor(time / (dt * every) + 1e-9)));
  }

  function lerpAngle(a, b, u) {
    let d = b - a;
    while (d > Math.PI) d -= 2 * Math.PI;
    while (d < -Math.PI) d += 2 * Math.PI;
    return a + d * u;
  }

  // Positions interpolate between pose samples so playback is smooth; discrete state (alive,
  // drive, claims, observing) is the recorded frame's own, never interpolated.
  function stateAt(time) {
    const i = frameIndex(time);
    if (i < 0) return null;
    const s = sampleIndex(time);
    const g = Math.min(s + 1, samples.length - 1);
    const ts = samples[s] * dt;
    const tg = samples[g] * dt;
    const u = tg > ts ? Math.max(0, Math.min(1, (time - ts) / (tg - ts))) : 0;
    const robots = rec.robots.map((_, k) => {
      const c = stateIn(states[k] || [], i) || [i, 1, 0, [], [], []];
      const p = poses[k][s];
      const q = poses[k][g] || p;
      const alive = c[1] === 1;
      const moving = alive && u > 0;
      return {
        x: moving ? p[0] + (q[0] - p[0]) * u : p[0],
        y: moving ? p[1] + (q[1] - p[1]) * u : p[1],
        theta: moving ? lerpAngle(p[2], q[2], u) : p[2],
        alive,
        drive: c[2],
        claims: c[3],
        inhibited: c[4],
        observing: c[5],
      };
    });
    const targets = paths.map((path) => {
      const p = path[s];
      const q = path[g] || p;
      return [p[0] + (q[0] - p[0]) * u, p[1] + (q[1] - p[1]) * u];
    });
    return { index: i, sample: s, frame: { robots }, robots, targets };
  }

  // ---- drawing ------------------------------------------------------------------------------

  const fontOf = (o) => (o.bold ? 'bold ' : '') + (o.size || 12) + 'px "DejaVu Sans", Arial, sans-serif';

  function label(text, x, y, colour, opts) {
    const o = opts || {};
    ctx.font = fontOf(o);
    ctx.textAlign = o.align || 'left';
    ctx.textBaseline = 'middle';
    // A white halo keeps labels readable over wedges and lines.
    ctx.lineWidth = 3;
    ctx.strokeStyle = 'rgba(255,255,255,0.85)';
    ctx.strokeText(text, x, y);
    ctx.fillStyle = colour;
    ctx.fillText(text, x, y);
  }

  // Every label drawn in the arena this frame: [text, x, y, w, h] in canvas CSS pixels.
  let labelBoxes = [];
  const HALO = 1.5; // half the halo's line width: ink beyond the glyphs

  // Label lines stacked beside a thing drawn at (x, y) with radius `rad`: on its `side` ('left'
  // or 'right') unless they would cross the wall there, then on the other; then moved inside
  // the walls, since a thing in a corner has no free side. Each line's box is kept for
  // data-labels. lines: [{text, colour, size, bold}].
  function labelBlock(lines, x, y, rad, side) {
    if (!lines.length) return;
    const pad = 2;
    const wl = X(0) + pad;
    const wr = X(arenaW) - pad;
    const wt = Y(arenaH) + pad;
    const wb = Y(0) - pad;
    const widths = lines.map((ln) => {
      ctx.font = fontOf(ln);
      return ctx.measureText(ln.text).width + 2 * HALO;
    });
    const heights = lines.map((ln) => (ln.size || 12) + 2 * HALO);
    const bw = Math.max(...widths);
    const bh = heights.reduce((a, b) => a + b, 0);
    const gap = rad + 4;
    const onRight = (r) => (r ? x + gap : x - gap - bw);
    let right = side === 'right';
    if (right && onRight(true) + bw > wr) right = false;
    else if (!right && onRight(false) < wl) right = true;
    const left = Math.max(wl, Math.min(wr - bw, onRight(right)));
    let top = Math.max(wt, Math.min(wb - bh, y - heights[0] / 2 - 7));
    lines.forEach((ln, i) => {
      // Text reads away from the thing: left-aligned on its right, right-aligned on its left.
      const lx = right ? left : left + bw - widths[i];
      label(ln.text, right ? lx + HALO : lx + widths[i] - HALO, top + heights[i] / 2, ln.colour,
        Object.assign({}, ln, { align: right ? 'left' : 'right' }));
      labelBoxes.push([ln.text, lx, top, widths[i], heights[i]]);
      top += heights[i];
    });
  }

  function drawArena() {
    ctx.fillStyle = '#eceae4';
    ctx.fillRect(0, 0, view.w, view.h);
    ctx.fillStyle = '#ffffff';
    ctx.fillRect(X(0), Y(arenaH), arenaW * view.s, arenaH * view.s);
    // 1 m grid, and a bolder line every 5 m.
    for (let gx = 1; gx < arenaW; gx++) {
      ctx.strokeStyle = gx % 5 === 0 ? '#dfe3ea' : '#f0f2f5';
      ctx.lineWidth = 1;
      ctx.beginPath();
      ctx.moveTo(X(gx), Y(0));
      ctx.lineTo(X(gx), Y(arenaH));
      ctx.stroke();
    }
    for (let gy = 1; gy < arenaH; gy++) {
      ctx.strokeStyle = gy % 5 === 0 ? '#dfe3ea' : '#f0f2f5';
      ctx.beginPath();
      ctx.moveTo(X(0), Y(gy));
      ctx.lineTo(X(arenaW), Y(gy));
      ctx.stroke();
    }
    ctx.strokeStyle = '#3a3f47';
    ctx.lineWidth = 5;
    ctx.strokeRect(X(0) - 2.5, Y(arenaH) - 2.5, arenaW * view.s + 5, arenaH * view.s + 5);
    // Scale bar, bottom left outside the walls.
    const bar = arenaW >= 10 ? 5 : 1;
    const bx = X(0);
    const by = view.h - 8;
    ctx.strokeStyle = '#3a3f47';
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.moveTo(bx, by - 4);
    ctx.lineTo(bx, by);
    ctx.lineTo(bx + bar * view.s, by);
    ctx.lineTo(bx + bar * view.s, by - 4);
    ctx.stroke();
    label(bar + ' m', bx + bar * view.s + 6, by - 2, '#3a3f47', { size: 11 });
  }

  function wedge(x, y, theta, fov, range, fill) {
    ctx.beginPath();
    ctx.moveTo(X(x), Y(y));
    // Canvas angles run clockwise because y is flipped.
    ctx.arc(X(x), Y(y), range * view.s, -theta - fov / 2, -theta + fov / 2);
    ctx.closePath();
    ctx.fillStyle = fill;
    ctx.fill();
  }

  function withAlpha(hex, a) {
    const n = parseInt(hex.slice(1), 16);
    return `rgba(${(n >> 16) & 255},${(n >> 8) & 255},${n & 255},${a})`;
  }

  // The last 8 s of each robot's path, through its pose samples.
  function drawTrails(st) {
    const every = Math.max(1, rec.every);
    const span = Math.max(1, Math.round(8 / (dt * every)));
    const from = Math.max(0, st.sample - span);
    rec.robots.forEach((_, k) => {
      ctx.beginPath();
      for (let i = from; i <= st.sample; i++) {
        const p = poses[k][i];
        if (i === from) ctx.moveTo(X(p[0]), Y(p[1])); else ctx.lineTo(X(p[0]), Y(p[1]));
      }
      const now = st.robots[k];
      if (now) ctx.lineTo(X(now.x), Y(now.y));
      ctx.strokeStyle = withAlpha(robotColour(k), 0.3);
      ctx.lineWidth = 2;
      ctx.setLineDash([]);
      ctx.stroke();
    });
  }

  function draw() {
    labelBoxes = [];
    drawArena();
    const st = stateAt(t);
    if (!st) {
      label('this recording has no frames', view.w / 2, view.h / 2, '#5b6575', { size: 16, align: 'center' });
      return null;
    }
    // Walls block the camera: nothing of a robot's view or path is drawn past them.
    ctx.save();
    ctx.beginPath();
    ctx.rect(X(0), Y(arenaH), arenaW * view.s, arenaH * view.s);
    ctx.clip();
    drawTrails(st);

    // Fields of view under everything else: the camera's reach light, the observe range darker.
    st.robots.forEach((r, k) => {
      if (!r.alive) return;
      const c = robotColour(k);
      wedge(r.x, r.y, r.theta, meta.camera_fov, meta.camera_range, withAlpha(c, 0.07));
      wedge(r.x, r.y, r.theta, meta.camera_fov, Math.min(meta.observe_range, meta.camera_range),
        withAlpha(c, 0.17));
      ctx.beginPath();
      ctx.moveTo(X(r.x), Y(r.y));
      ctx.arc(X(r.x), Y(r.y), meta.camera_range * view.s, -r.theta - meta.camera_fov / 2,
        -r.theta + meta.camera_fov / 2);
      ctx.closePath();
      ctx.strokeStyle = withAlpha(c, 0.3);
      ctx.lineWidth = 1;
      ctx.stroke();
    });

    // Drive lines: solid when the robot also claims the target it drives to, dashed when not.
    st.robots.forEach((r, k) => {
      if (!r.alive || !r.drive) return;
      const ti = targetIndex.get(r.drive);
      if (ti === undefined) return;
      const p = st.targets[ti];
      const claimed = r.claims.includes(r.drive);
      ctx.setLineDash(claimed ? [] : [6, 5]);
      ctx.strokeStyle = robotColour(k);
      ctx.lineWidth = claimed ? 2.5 : 1.8;
      ctx.beginPath();
      ctx.moveTo(X(r.x), Y(r.y));
      ctx.lineTo(X(p[0]), Y(p[1]));
      ctx.stroke();
      ctx.setLineDash([]);
    });

    ctx.restore();

    // Targets.
    const observers = rec.targets.map(() => []);
    st.robots.forEach((r, k) => {
      if (!r.alive) return;
      r.observing.forEach((id) => {
        const ti = targetIndex.get(id);
        if (ti !== undefined) observers[ti].push(rec.robots[k].id);
      });
    });
    rec.targets.forEach((info, ti) => {
      const p = st.targets[ti];
      if (!p) return;
      const rad = Math.max(info.radius * view.s, 6 + 6 * prioShare(info.priority));
      ctx.beginPath();
      ctx.arc(X(p[0]), Y(p[1]), rad, 0, 2 * Math.PI);
      ctx.fillStyle = targetColour(info.priority);
      ctx.fill();
      ctx.lineWidth = 1.5;
      ctx.strokeStyle = '#6b1d12';
      ctx.stroke();
      if (observers[ti].length) {
        ctx.beginPath();
        ctx.arc(X(p[0]), Y(p[1]), rad + 4, 0, 2 * Math.PI);
        ctx.strokeStyle = OBSERVED;
        ctx.lineWidth = 3;
        ctx.stroke();
      }
      labelBlock([
        { text: 'T' + info.id, colour: '#6b1d12', bold: true, size: 13 },
        { text: 'w ' + fmtNum(info.priority), colour: '#8a4b3c', size: 11 },
      ], X(p[0]), Y(p[1]), rad + 2, 'right');
    });

    // Robots on top.
    st.robots.forEach((r, k) => {
      const info = rec.robots[k];
      const rad = Math.max(info.radius * view.s, 8);
      const cx = X(r.x);
      const cy = Y(r.y);
      const c = r.alive ? robotColour(k) : DEAD;
      ctx.beginPath();
      ctx.arc(cx, cy, rad, 0, 2 * Math.PI);
      ctx.fillStyle = c;
      ctx.fill();
      ctx.lineWidth = 2;
      ctx.strokeStyle = r.alive ? '#ffffff' : '#6f6f6f';
      ctx.stroke();
      if (r.alive) {
        ctx.beginPath();
        ctx.moveTo(cx, cy);
        ctx.lineTo(cx + Math.cos(-r.theta) * rad * 1.9, cy + Math.sin(-r.theta) * rad * 1.9);
        ctx.strokeStyle = '#1d2430';
        ctx.lineWidth = 2.5;
        ctx.stroke();
      } else {
        ctx.strokeStyle = KILL;
        ctx.lineWidth = 3;
        ctx.beginPath();
        ctx.moveTo(cx - rad, cy - rad);
        ctx.lineTo(cx + rad, cy + rad);
        ctx.moveTo(cx + rad, cy - rad);
        ctx.lineTo(cx - rad, cy + rad);
        ctx.stroke();
      }
      // Labels go on the side the robot faces away from, where its view and drive line are not.
      const lines = [{ text: 'R' + info.id + (r.alive ? '' : ' dead'), colour: r.alive ? c : '#777', bold: true, size: 13 }];
      if (r.alive && r.claims.length) {
        lines.push({ text: 'claims ' + r.claims.map((id) => 'T' + id).join(','), colour: c, size: 11, bold: true });
      }
      if (r.alive && r.inhibited.length) {
        lines.push({ text: 'inhib ' + r.inhibited.map((id) => 'T' + id).join(','), colour: '#6b7280', size: 11 });
      }
      labelBlock(lines, cx, cy, rad, Math.cos(r.theta) >= 0 ? 'left' : 'right');
    });
    return st;
  }

  function fmtNum(v) {
    return Number.isInteger(v) ? String(v) : v.toFixed(2);
  }

  // ---- timeline -----------------------------------------------------------------------------

  function drawTimeline() {
    const w = view.w;
    const h = 58;
    const top = 6;
    const bottom = h - 16;
    tctx.clearRect(0, 0, w, h);
    tctx.fillStyle = '#fbfbfc';
    tctx.fillRect(0, 0, w, h);
    const tx = (time) => 8 + (endT > 0 ? time / endT : 0) * (w - 16);
    if (coverage.length) {
      const colour = data.colours[meta.controller] || '#1f5fbf';
      const y = (w) => bottom - (bottom - top) * w;
      // A step function: A_w holds until the next change of who observes what.
      tctx.beginPath();
      tctx.moveTo(tx(0), bottom);
      coverage.forEach(([time, weighted], i) => {
        if (i > 0) tctx.lineTo(tx(time), y(coverage[i - 1][1]));
        tctx.lineTo(tx(time), y(weighted));
      });
      tctx.lineTo(tx(endT), y(coverage[coverage.length - 1][1]));
      tctx.lineTo(tx(endT), bottom);
      tctx.closePath();
      tctx.fillStyle = withAlpha(colour, 0.22);
      tctx.fill();
      tctx.strokeStyle = colour;
      tctx.lineWidth = 1;
      tctx.stroke();
      tctx.fillStyle = '#5b6575';
      tctx.font = '10px "DejaVu Sans", Arial, sans-serif';
      tctx.textAlign = 'left';
      tctx.textBaseline = 'top';
      tctx.fillText('A_w(t) ' + meta.controller, 10, 1);
    }
    // Time ticks.
    const step = niceStep(endT / 8);
    tctx.fillStyle = '#5b6575';
    tctx.font = '10px "DejaVu Sans", Arial, sans-serif';
    tctx.textBaseline = 'top';
    for (let s = 0; step > 0 && s <= endT + 1e-9; s += step) {
      tctx.fillRect(tx(s), bottom, 1, 3);
      // Keep the first and last labels inside the strip.
      tctx.textAlign = tx(s) < 20 ? 'left' : tx(s) > w - 20 ? 'right' : 'center';
      tctx.fillText(fmtNum(Math.round(s * 10) / 10) + ' s', tx(s), bottom + 4);
    }
    // Kill events.
    rec.events.forEach((e) => {
      tctx.fillStyle = KILL;
      tctx.fillRect(tx(e.t) - 1, top - 4, 2, bottom - top + 4);
      tctx.font = 'bold 10px "DejaVu Sans", Arial, sans-serif';
      tctx.textAlign = 'left';
      tctx.textBaseline = 'top';
      tctx.fillText('✕ R' + e.robot + ' ' + e.kind, tx(e.t) + 3, top - 4);
    });
    // Cursor.
    tctx.fillStyle = '#1d2430';
    tctx.fillRect(tx(t) - 1, 0, 2, bottom + 2);
  }

  function niceStep(raw) {
    if (!(raw > 0)) return 0;
    const p = Math.pow(10, Math.floor(Math.log10(raw)));
    for (const m of [1, 2, 5, 10]) if (raw <= m * p) return m * p;
    return 10 * p;
  }

  function seekFromTimeline(ev) {
    const r = timeline.getBoundingClientRect();
    const u = Math.max(0, Math.min(1, (ev.clientX - r.left - 8) / (r.width - 16)));
    setTime(u * endT);
  }

  // ---- side panel ---------------------------------------------------------------------------

  const tList = (ids, cls) => (ids.length
    ? ids.map((id) => `<span class="${cls || ''}">T${id}</span>`).join(', ')
    : '<span class="none">–</span>');

  function updatePanel(st) {
    if (!st || st.index === panelFrame) return;
    panelFrame = st.index;
    robotsBody.innerHTML = st.frame.robots.map((r, k) => {
      const id = rec.robots[k].id;
      const swatch = `<span class="swatch" style="background:${r.alive ? robotColour(k) : DEAD}"></span>`;
      const claimed = r.drive && r.claims.includes(r.drive);
      const drive = !r.alive ? '<span class="none">dead</span>'
        : r.drive ? `T${r.drive}${claimed ? '' : ' <span class="none">(no claim)</span>'}`
          : '<span class="none">wander</span>';
      return `<tr class="${r.alive ? '' : 'dead'}"><td>${swatch}R${id}</td><td>${drive}</td>`
        + `<td>${tList(r.claims, 'claim')}</td><td>${tList(r.inhibited)}</td><td>${tList(r.observing)}</td></tr>`;
    }).join('');
    targetsBody.innerHTML = rec.targets.map((info, ti) => {
      const by = [];
      st.frame.robots.forEach((r, k) => {
        if (r.alive && r.observing.includes(info.id)) by.push('R' + rec.robots[k].id);
      });
      const claimers = [];
      st.frame.robots.forEach((r, k) => {
        if (r.alive && r.claims.includes(info.id)) claimers.push('R' + rec.robots[k].id);
      });
      const swatch = `<span class="swatch" style="background:${targetColour(info.priority)}"></span>`;
      return `<tr><td>${swatch}T${info.id}</td><td>${fmtNum(info.priority)}</td>`
        + `<td>${by.length ? by.join(', ') : '<span class="none">unobserved</span>'}</td>`
        + `<td>${claimers.length ? claimers.join(', ') : '<span class="none">–</span>'}</td></tr>`;
    }).join('');
  }

  // ---- controls -----------------------------------------------------------------------------

  function render() {
    const st = draw();
    // Where the robots are drawn (arena metres), for a test to compare with the report's data.
    document.body.dataset.robots = st ? st.robots.map((r) => `${r.x.toFixed(4)},${r.y.toFixed(4)}`).join(';') : '';
    drawTimeline();
    updatePanel(st);
    slider.value = String(t);
    const i = frameIndex(t);
    clock.textContent = `t = ${t.toFixed(1)} s / ${endT.toFixed(1)} s · frame ${i + 1}/${nFrames}`;
    const b = document.body.dataset;
    b.labels = labelBoxes.map(([text, x, y, w, h]) => text + '@' + [x, y, w, h].map((v) => v.toFixed(1)).join(','))
      .join(';');
    b.walls = [X(0), Y(arenaH), arenaW * view.s, arenaH * view.s].map((v) => v.toFixed(1)).join(',');
  }

  function setTime(time) {
    t = Math.max(0, Math.min(endT, time));
    render();
  }

  function setPlaying(on) {
    playing = on && endT > 0;
    playBtn.textContent = playing ? '❚❚ Pause' : '▶ Play';
    lastWall = null;
    if (playing) requestAnimationFrame(tick);
  }

  function tick(now) {
    if (!playing) return;
    if (lastWall !== null) {
      const advance = ((now - lastWall) / 1000) * Number(speedSel.value);
      t = Math.min(endT, t + advance);
      render();
      if (t >= endT) {
        setPlaying(false);
        return;
      }
    }
    lastWall = now;
    requestAnimationFrame(tick);
  }

  slider.addEventListener('input', () => setTime(Number(slider.value)));
  playBtn.addEventListener('click', () => {
    if (!playing && t >= endT) t = 0;
    setPlaying(!playing);
  });
  document.getElementById('back').addEventListener('click', () => { setPlaying(false); setTime(t - dt); });
  document.getElementById('fwd').addEventListener('click', () => { setPlaying(false); setTime(t + dt); });
  let dragging = false;
  timeline.addEventListener('mousedown', (e) => { dragging = true; seekFromTimeline(e); });
  window.addEventListener('mousemove', (e) => { if (dragging) seekFromTimeline(e); });
  window.addEventListener('mouseup', () => { dragging = false; });
  document.addEventListener('keydown', (e) => {
    if (e.target && (e.target.tagName === 'INPUT' || e.target.tagName === 'SELECT')) return;
    if (e.key === ' ') { e.preventDefault(); playBtn.click(); }
    if (e.key === 'ArrowRight') { setPlaying(false); setTime(t + dt); }
    if (e.key === 'ArrowLeft') { setPlaying(false); setTime(t - dt); }
  });
  window.addEventListener('resize', () => { if (current >= 0) { layout(); render(); publishCanvas(); } });

  function publishCanvas() {
    const r = arena.getBoundingClientRect();
    document.body.dataset.canvas = [r.left + window.scrollX, r.top + window.scrollY, r.width, r.height]
      .map((v) => Math.round(v)).join(',');
  }

  // ---- choosing a run ------------------------------------------------------------------------

  const keyOf = (r) => `${r.setting}|${r.controller}|${r.seed}`;
  const distinct = (xs) => xs.filter((x, i) => xs.indexOf(x) === i);

  function fillMenu(sel, values, want) {
    sel.textContent = '';
    values.forEach((v) => {
      const o = document.createElement('option');
      o.value = String(v);
      o.textContent = String(v);
      sel.appendChild(o);
    });
    sel.value = values.map(String).includes(String(want)) ? String(want) : String(values[0]);
  }

  // Each menu lists what the menus before it leave; a choice is kept when the new setting (or
  // controller) has it, so switching setting compares the same controller and seed.
  function fillMenus(want) {
    fillMenu(settingSel, distinct(runs.map((r) => r.setting)), want.setting);
    const inSetting = runs.filter((r) => r.setting === settingSel.value);
    fillMenu(controllerSel, distinct(inSetting.map((r) => r.controller)), want.controller);
    const inBoth = inSetting.filter((r) => r.controller === controllerSel.value);
    fillMenu(seedSel, distinct(inBoth.map((r) => r.seed)), want.seed);
  }

  function fillFacts() {
    const events = rec.events.length ? rec.events.map((e) => `R${e.robot} ${e.kind} at ${e.t.toFixed(1)} s`).join('; ')
      : 'none';
    const every = Math.max(1, rec.every);
    const rows = [
      ['setting', rec.setting],
      ['controller', meta.controller],
      ['seed', String(meta.seed)],
      ['radio loss', `${fmtNum(Math.round(meta.loss * 1000) / 10)} %`],
      ['arena', `${fmtNum(arenaW)} × ${fmtNum(arenaH)} m`],
      ['robots / targets', `${rec.robots.length} / ${rec.targets.length}`],
      ['camera', `${Math.round(meta.camera_fov * 180 / Math.PI)}° field of view, ${fmtNum(meta.camera_range)} m range`],
      ['observe range', `${fmtNum(meta.observe_range)} m`],
      ['run length', `${fmtNum(meta.duration)} s, a frame every ${fmtNum(dt)} s`],
      ['positions', every > 1 ? `every ${fmtNum(Math.round(every * dt * 100) / 100)} s (decimated), interpolated`
        : 'every frame'],
      ['events', events],
    ];
    facts.textContent = '';
    rows.forEach(([k, v]) => {
      const dt_ = document.createElement('dt');
      dt_.textContent = k;
      const dd = document.createElement('dd');
      dd.textContent = v;
      facts.append(dt_, dd);
    });
  }

  // Draw run `index` at `time` (kept when the new run is long enough).
  function show(index, time) {
    document.body.dataset.status = 'loading';
    setPlaying(false);
    load(index);
    layout();
    slider.min = '0';
    slider.max = String(endT);
    slider.step = String(dt);
    setTime(time);
    publishCanvas();
    document.body.dataset.run = keyOf(runs[index]);
    document.body.dataset.status = 'drawn';
  }

  function onMenu() {
    fillMenus({ setting: settingSel.value, controller: controllerSel.value, seed: seedSel.value });
    const i = runs.findIndex((r) => r.setting === settingSel.value && r.controller === controllerSel.value
      && String(r.seed) === seedSel.value);
    if (i >= 0) show(i, t);
  }
  [settingSel, controllerSel, seedSel].forEach((sel) => sel.addEventListener('change', onMenu));

  // "#run=3&t=42.5" in the address opens the fourth run at that time (both optional).
  const hashRun = /(?:^|[#&])run=([0-9]+)/.exec(window.location.hash);
  const hashT = /(?:^|[#&])t=([0-9.]+)/.exec(window.location.hash);
  if (!runs.length) {
    layout();
    label('this report has no recorded run', view.w / 2, view.h / 2, '#5b6575', { size: 16, align: 'center' });
    publishCanvas();
    document.body.dataset.status = 'drawn';
    return;
  }
  const first = hashRun && Number(hashRun[1]) < runs.length ? Number(hashRun[1]) : 0;
  fillMenus(runs[first]);
  show(first, hashT ? Number(hashT[1]) : 0);
})();
