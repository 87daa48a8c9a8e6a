// Canvas replay of one recorded run, inlined into the report page by ayllu-sim's report module.
//
// Reads the JSON in <script id="data"> ({recording, coverage, colours}), draws the arena at the
// current time, and keeps the side panel, the timeline and the controls in step. Promises:
// after the first frame is on the canvas, body[data-status] is "drawn" and body[data-canvas]
// holds the canvas's page rectangle "x,y,w,h" in CSS pixels (a screenshot test reads both);
// nothing here touches the network. Arena coordinates are metres, y up; the canvas is y down.
(function () {
  'use strict';

  const data = JSON.parse(document.getElementById('data').textContent);
  const rec = data.recording;
  const meta = rec.meta;
  const frames = rec.frames;
  const [arenaW, arenaH] = meta.arena;
  const dt = meta.frame_dt > 0 ? meta.frame_dt : 1;
  const lastT = frames.length ? frames[frames.length - 1].t : 0;
  const endT = Math.max(lastT, 0);

  // Cool colours for robots so they never read as the warm-coloured targets.
  const ROBOT_COLOURS = ['#1f77b4', '#2ca02c', '#9467bd', '#17becf', '#8c564b', '#e377c2',
    '#393b79', '#637939', '#7b4173', '#3182bd', '#006d77', '#5254a3'];
  const robotColour = (i) => ROBOT_COLOURS[i % ROBOT_COLOURS.length];
  const DEAD = '#a9a9a9';
  const OBSERVED = '#1a9850';
  const KILL = '#c81e1e';

  // Targets: warm colour and size by priority rank (target 1 is the highest priority).
  const prios = rec.targets.map((t) => t.priority);
  const pMin = Math.min(...prios, 0);
  const pMax = Math.max(...prios, 1);
  const prioShare = (p) => (pMax > pMin ? (p - pMin) / (pMax - pMin) : 1);
  function targetColour(p) {
    const s = prioShare(p);
    const mix = (a, b) => Math.round(a + (b - a) * s);
    return `rgb(${mix(246, 192)},${mix(190, 40)},${mix(70, 30)})`;
  }
  const targetIndex = new Map(rec.targets.map((t, i) => [t.id, i]));

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
    const margin = 26;
    const aspect = arenaH > 0 && arenaW > 0 ? arenaH / arenaW : 1;
    let w = avail;
    let h = Math.round((w - 2 * margin) * aspect + 2 * margin);
    if (h > 620) {
      h = 620;
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
  }

  const X = (x) => view.ox + x * view.s;
  const Y = (y) => view.h - view.oy - y * view.s;

  // ---- state at a time ------------------------------------------------------------------------

  function frameIndex(time) {
    if (!frames.length) return -1;
    return Math.max(0, Math.min(frames.length - 1, Math.floor(time / dt + 1e-9)));
  }

  function lerpAngle(a, b, u) {
    let d = b - a;
    while (d > Math.PI) d -= 2 * Math.PI;
    while (d < -Math.PI) d += 2 * Math.PI;
    return a + d * u;
  }

  // Positions interpolate between frames so playback is smooth; discrete state (drive, claims,
  // observing) is the frame's own, never interpolated.
  function stateAt(time) {
    const i = frameIndex(time);
    if (i < 0) return null;
    const f = frames[i];
    const g = frames[Math.min(i + 1, frames.length - 1)];
    const u = g.t > f.t ? Math.max(0, Math.min(1, (time - f.t) / (g.t - f.t))) : 0;
    const robots = f.robots.map((r, k) => {
      const q = g.robots[k] || r;
      if (!r.alive || !q.alive) return Object.assign({}, r);
      return Object.assign({}, r, {
        x: r.x + (q.x - r.x) * u,
        y: r.y + (q.y - r.y) * u,
        theta: lerpAngle(r.theta, q.theta, u),
      });
    });
    const targets = f.targets.map((p, k) => {
      const q = g.targets[k] || p;
      return [p[0] + (q[0] - p[0]) * u, p[1] + (q[1] - p[1]) * u];
    });
    return { index: i, frame: f, robots, targets };
  }

  // ---- drawing ------------------------------------------------------------------------------

  function label(text, x, y, colour, opts) {
    const o = opts || {};
    ctx.font = (o.bold ? 'bold ' : '') + (o.size || 12) + 'px "DejaVu Sans", Arial, sans-serif';
    ctx.textAlign = o.align || 'left';
    ctx.textBaseline = 'middle';
    // A white halo keeps labels readable over wedges and lines.
    ctx.lineWidth = 3;
    ctx.strokeStyle = 'rgba(255,255,255,0.85)';
    ctx.strokeText(text, x, y);
    ctx.fillStyle = colour;
    ctx.fillText(text, x, y);
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

  function drawTrails(st) {
    const span = Math.max(1, Math.round(8 / dt));
    const from = Math.max(0, st.index - span);
    rec.robots.forEach((_, k) => {
      ctx.beginPath();
      let started = false;
      for (let i = from; i <= st.index; i++) {
        const r = frames[i].robots[k];
        if (!r) continue;
        if (!started) {
          ctx.moveTo(X(r.x), Y(r.y));
          started = true;
        } else {
          ctx.lineTo(X(r.x), Y(r.y));
        }
      }
      const now = st.robots[k];
      if (started && now) ctx.lineTo(X(now.x), Y(now.y));
      ctx.strokeStyle = withAlpha(robotColour(k), 0.3);
      ctx.lineWidth = 2;
      ctx.setLineDash([]);
      ctx.stroke();
    });
  }

  function draw() {
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
      label('T' + info.id, X(p[0]) + rad + 6, Y(p[1]) - 6, '#6b1d12', { bold: true, size: 13 });
      label('w ' + fmtNum(info.priority), X(p[0]) + rad + 6, Y(p[1]) + 8, '#8a4b3c', { size: 11 });
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
      const left = Math.cos(r.theta) >= 0;
      const lx = left ? cx - rad - 4 : cx + rad + 4;
      const align = left ? 'right' : 'left';
      label('R' + info.id + (r.alive ? '' : ' dead'), lx, cy - 7, r.alive ? c : '#777', { bold: true, size: 13, align });
      let ly = cy + 8;
      if (r.alive && r.claims.length) {
        label('claims ' + r.claims.map((id) => 'T' + id).join(','), lx, ly, c, { size: 11, align, bold: true });
        ly += 13;
      }
      if (r.alive && r.inhibited.length) {
        label('inhib ' + r.inhibited.map((id) => 'T' + id).join(','), lx, ly, '#6b7280', { size: 11, align });
      }
    });
    return st;
  }

  function fmtNum(v) {
    return Number.isInteger(v) ? String(v) : v.toFixed(2);
  }

  // ---- timeline -----------------------------------------------------------------------------

  const replayCoverage = (data.coverage.find((c) => c.name === meta.controller) || data.coverage[0]) || null;

  function drawTimeline() {
    const w = view.w;
    const h = 58;
    const top = 6;
    const bottom = h - 16;
    tctx.clearRect(0, 0, w, h);
    tctx.fillStyle = '#fbfbfc';
    tctx.fillRect(0, 0, w, h);
    const tx = (time) => 8 + (endT > 0 ? time / endT : 0) * (w - 16);
    if (replayCoverage && replayCoverage.t.length) {
      const colour = replayCoverage.colour || '#1f5fbf';
      tctx.beginPath();
      tctx.moveTo(tx(replayCoverage.t[0]), bottom);
      replayCoverage.t.forEach((time, i) => {
        tctx.lineTo(tx(time), bottom - (bottom - top) * replayCoverage.weighted[i]);
      });
      tctx.lineTo(tx(replayCoverage.t[replayCoverage.t.length - 1]), bottom);
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
      tctx.fillText('A_w(t) ' + replayCoverage.name, 10, 1);
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
    drawTimeline();
    updatePanel(st);
    slider.value = String(t);
    const i = frameIndex(t);
    clock.textContent = `t = ${t.toFixed(1)} s / ${endT.toFixed(1)} s · frame ${i + 1}/${frames.length}`;
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

  slider.min = '0';
  slider.max = String(endT);
  slider.step = String(dt);
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
  window.addEventListener('resize', () => { layout(); render(); publishCanvas(); });

  function publishCanvas() {
    const r = arena.getBoundingClientRect();
    document.body.dataset.canvas = [r.left + window.scrollX, r.top + window.scrollY, r.width, r.height]
      .map((v) => Math.round(v)).join(',');
  }

  // "#t=42.5" in the address opens the replay at that time.
  const m = /(?:^|[#&])t=([0-9.]+)/.exec(window.location.hash);
  layout();
  setTime(m ? Number(m[1]) : 0);
  publishCanvas();
  document.body.dataset.status = 'drawn';
})();
