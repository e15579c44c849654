// lockstep viewer: the page around the renderer (render.js) for the frames
// the viewer serves (the formats are in docs/viewer.md). No dependencies,
// no build step.
'use strict';

const $ = (id) => document.getElementById(id);
const S = {
  world: null, frames: [], nb: 0, frame: 0, playing: false, speed: 1, acc: 0,
  picked: -1, framesDrawn: 0, bodiesDrawn: 0, error: null, ready: false,
  mode: 'side', diverging: new Map(), // body -> minority pose (Float32Array(7))
  cam: { yaw: 0.7, pitch: 0.45, dist: 20, target: [0, 0, 0] },
  dirty: true,
};

// ---- page state for tests and tools ---------------------------------------
window.lockstepViewer = {
  status() {
    return {
      ready: S.ready, error: S.error, kind: S.world && S.world.kind,
      frames: S.frames.length, frame: S.frame,
      tick: S.frames.length ? S.frames[S.frame].tick : null,
      bodies: S.nb, bodiesDrawn: S.bodiesDrawn, framesDrawn: S.framesDrawn,
      diverging: [...S.diverging.keys()], picked: S.picked,
      live: S.live, following: S.follow, rooms: S.rooms || null,
    };
  },
  // Pixels that differ from the background in the last drawn frame.
  litPixels() { return S.R.litPixels(); },
  pose(body) {
    const f = S.frames[S.frame];
    return f ? Array.from(f.poses.subarray(body * 7, body * 7 + 7)) : null;
  },
  setFrame(i) { setFrame(i); },
  bodyIndex(name) { return S.world ? S.world.bodies.findIndex((b) => b.name === name) : -1; },
};


// ---- drawing (render.js draws) ---------------------------------------------
function setupGL() {
  if (!S.R) S.R = createRenderer($('gl'));
  S.R.setBodies(S.world.bodies);
}

function bodyColor(i, b, asleep) {
  if (i === S.picked) return asleep ? [0.45, 0.4, 0.13] : [1.0, 0.88, 0.3];
  if (S.diverging.has(i)) return asleep ? [0.44, 0.1, 0.09] : [0.98, 0.22, 0.2];
  return kindColor(i, b, asleep);
}

// The pose of body i in the current frame, for the given side.
function poseOf(f, i, side) {
  if (side === 'minority' && S.frame === S.desyncFrame && S.diverging.has(i)) return [S.diverging.get(i), 0];
  return [f.poses, i * 7];
}

function drawWorld(vp, side, x, y, w, h) {
  const f = S.frames[S.frame], ghosts = [];
  if (side === 'overlay' && S.frame === S.desyncFrame) {
    for (const [i, p] of S.diverging) ghosts.push([i, p, [1.0, 0.35, 0.3], 0.4]);
  }
  return S.R.drawWorld(vp, f, [x, y, w, h], {
    pose: (i) => poseOf(f, i, side),
    color: (i, asleep) => bodyColor(i, S.world.bodies[i], asleep),
    ghosts, contacts: $('ov-contacts').checked, aabbs: $('ov-aabbs').checked,
  });
}

function render() {
  const gl = S.R.gl, [W, H] = S.R.fit(), dpr = window.devicePixelRatio || 1;
  gl.enable(gl.DEPTH_TEST); gl.enable(gl.SCISSOR_TEST);
  const split = S.world.kind === 'bundle' && S.mode === 'side';
  const views = split ? [['majority', 0, Math.floor(W / 2)], ['minority', Math.floor(W / 2), W - Math.floor(W / 2)]]
    : [[S.world.kind === 'bundle' ? 'overlay' : 'majority', 0, W]];
  let drawn = 0;
  S.views = [];
  for (const [side, x, w] of views) {
    const vp = orbitCamera(S.cam, w / H);
    drawn = Math.max(drawn, drawWorld(vp, side, x, 0, w, H));
    S.views.push({ side, vp, x: x / dpr, w: w / dpr, h: H / dpr });
  }
  gl.disable(gl.SCISSOR_TEST);
  S.bodiesDrawn = drawn;
  S.framesDrawn++;
  drawLabels(split);
}

function drawLabels(split) {
  const c = $('labels'), dpr = window.devicePixelRatio || 1;
  c.width = c.clientWidth * dpr; c.height = c.clientHeight * dpr;
  const ctx = c.getContext('2d');
  ctx.scale(dpr, dpr);
  ctx.font = '12px system-ui, sans-serif';
  const f = S.frames[S.frame];
  if (split) {
    ctx.fillStyle = '#ffd0d0';
    const d = S.world.desync;
    ctx.fillText(`slot ${d.reference} (${d.majority ? 'majority' : 'reference'})`, 10, 18);
    ctx.fillText(`diverging: slot ${d.suspects.map((s) => s.slot).join(', ')}` +
      (S.frame === S.desyncFrame ? '' : ' (its values are known at the desync tick only)'), S.views[1].x + 10, 18);
  }
  if (!$('ov-names').checked) return;
  ctx.fillStyle = '#e8eef5';
  for (const v of S.views) for (let i = 0; i < S.nb; i++) {
    if (!(f.flags[i] & 1) || S.world.bodies[i].kind === 'static') continue;
    const [poses, o] = poseOf(f, i, v.side === 'minority' ? 'minority' : 'majority');
    const p = project(v, [poses[o], poses[o + 1], poses[o + 2]]);
    if (p && p[0] >= v.x && p[0] < v.x + v.w) ctx.fillText(S.world.bodies[i].name, p[0] + 4, p[1] - 4);
  }
}

// ---- UI --------------------------------------------------------------------
function setFrame(i) {
  if (!S.frames.length) return;
  S.frame = Math.max(0, Math.min(S.frames.length - 1, i | 0));
  $('slider').value = S.frame;
  $('tick').textContent = `tick ${S.frames[S.frame].tick} (${S.frame + 1}/${S.frames.length})`;
  S.dirty = true;
  showState();
}

async function showState() {
  if (S.picked < 0) return;
  const want = [S.frame, S.picked];
  const at = S.live ? `room=${encodeURIComponent(S.room)}&tick=${S.frames[want[0]].tick}` : `frame=${want[0]}`;
  const r = await fetch(`/state?${at}&body=${want[1]}`);
  if (S.frame !== want[0] || S.picked !== want[1]) return;
  $('state').classList.remove('muted');
  $('state').textContent = r.ok ? JSON.stringify(await r.json(), null, 1) : 'not present at this tick';
}

function pick(i) {
  S.picked = i;
  for (const el of $('bodies').children) el.classList.toggle('picked', Number(el.dataset.i) === i);
  S.dirty = true;
  showState();
}

function listBodies() {
  const q = $('search').value.trim().toLowerCase();
  const list = $('bodies');
  list.textContent = '';
  S.world.bodies.forEach((b, i) => {
    const handle = `${b.handle}:${b.generation}`;
    if (q && !b.name.toLowerCase().includes(q) && !handle.includes(q)) return;
    const el = document.createElement('div');
    el.dataset.i = i;
    el.textContent = b.name || '(unnamed)';
    const k = document.createElement('span');
    k.className = 'k';
    k.textContent = `${handle} ${b.kind} ${b.colliders.map((c) => c.shape).join('+')}`;
    el.appendChild(k);
    if (S.diverging.has(i)) el.classList.add('diverging');
    if (i === S.picked) el.classList.add('picked');
    el.onclick = () => pick(i);
    list.appendChild(el);
  });
}

function showDesync() {
  const d = S.world.desync;
  $('desync-box').hidden = false;
  const box = $('desync');
  const head = document.createElement('div');
  head.textContent = `tick ${d.tick}: compared with slot ${d.reference}` + (d.majority ? ' (majority)' : ' (no majority)');
  box.appendChild(head);
  for (const s of d.suspects) {
    const el = document.createElement('div');
    el.textContent = `slot ${s.slot}: ${s.bodies_differing} bodies differ` + (s.contacts_differ ? ', contacts differ' : '');
    box.appendChild(el);
    for (const b of s.bodies) {
      const f0 = b.fields[0];
      const row = document.createElement('div');
      row.className = 'field';
      const name = document.createElement('span');
      name.className = 'name';
      name.textContent = b.name;
      name.onclick = () => { setFrame(S.desyncFrame); pick(b.body); };
      row.appendChild(name);
      const pre = document.createElement('pre');
      pre.textContent = f0 ? `first differing field: ${f0.name}\n majority: ${f0.expected.join(', ')}\n slot ${s.slot}:  ${f0.got.join(', ')}`
        + (b.fields.length > 1 ? `\n(${b.fields.length - 1} more: ${b.fields.slice(1).map((x) => x.name).join(', ')})` : '')
        : 'no field dump came';
      row.appendChild(pre);
      box.appendChild(row);
    }
  }
}

function bindInput() {
  const slider = $('slider');
  slider.max = S.frames.length - 1;
  slider.addEventListener('input', () => {
    setFrame(Number(slider.value));
    if (S.live) { S.follow = S.frame === S.frames.length - 1; $('play').innerHTML = S.follow ? '&#10074;&#10074;' : '&#9654;'; }
  });
  $('play').onclick = () => {
    if (S.live) { // live: follow the newest frame, or hold still
      S.follow = !S.follow;
      if (S.follow) setFrame(S.frames.length - 1);
      $('play').innerHTML = S.follow ? '&#10074;&#10074;' : '&#9654;';
      return;
    }
    S.playing = !S.playing; $('play').innerHTML = S.playing ? '&#10074;&#10074;' : '&#9654;';
  };
  $('back').onclick = () => setFrame(S.frame - 1);
  $('fwd').onclick = () => setFrame(S.frame + 1);
  $('speed').onchange = () => { S.speed = Number($('speed').value); };
  $('search').addEventListener('input', listBodies);
  for (const id of ['ov-contacts', 'ov-aabbs', 'ov-names']) $(id).onchange = () => { S.dirty = true; };
  for (const r of document.querySelectorAll('input[name=mode]')) r.onchange = () => { S.mode = r.value; S.dirty = true; };
  const canvas = $('labels').parentElement;
  let drag = null;
  canvas.addEventListener('pointerdown', (e) => { drag = { x: e.clientX, y: e.clientY, moved: false, pan: e.shiftKey }; });
  window.addEventListener('pointerup', (e) => {
    if (drag && !drag.moved) clickPick(e);
    drag = null;
  });
  window.addEventListener('pointermove', (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    if (Math.abs(dx) + Math.abs(dy) > 2) drag.moved = true;
    drag.x = e.clientX; drag.y = e.clientY;
    const c = S.cam;
    if (drag.pan) {
      const s = c.dist * 0.002, r = [Math.cos(c.yaw), 0, -Math.sin(c.yaw)];
      c.target = [c.target[0] - r[0] * dx * s, c.target[1] + dy * s, c.target[2] - r[2] * dx * s];
    } else {
      c.yaw -= dx * 0.008;
      c.pitch = Math.max(-1.5, Math.min(1.5, c.pitch + dy * 0.008));
    }
    S.dirty = true;
  });
  canvas.addEventListener('wheel', (e) => { e.preventDefault(); S.cam.dist *= Math.exp(e.deltaY * 0.001); S.dirty = true; }, { passive: false });
  window.addEventListener('resize', () => { S.dirty = true; });
  window.addEventListener('keydown', (e) => {
    if (e.target.tagName === 'INPUT' && e.target.type === 'search') return;
    if (e.key === ' ') { $('play').click(); e.preventDefault(); }
    if (e.key === 'ArrowRight') setFrame(S.frame + 1);
    if (e.key === 'ArrowLeft') setFrame(S.frame - 1);
  });
}

function clickPick(e) {
  const rect = $('labels').getBoundingClientRect(), mx = e.clientX - rect.left, my = e.clientY - rect.top;
  const f = S.frames[S.frame];
  let best = -1, bd = 30;
  for (const v of S.views || []) {
    if (mx < v.x || mx >= v.x + v.w) continue;
    for (let i = 0; i < S.nb; i++) {
      if (!(f.flags[i] & 1) || S.world.bodies[i].kind === 'static') continue;
      const [poses, o] = poseOf(f, i, v.side);
      const p = project(v, [poses[o], poses[o + 1], poses[o + 2]]);
      if (p) { const d = Math.hypot(p[0] - mx, p[1] - my); if (d < bd) { bd = d; best = i; } }
    }
  }
  if (best >= 0) pick(best);
}

function frameCamera() {
  const f = S.frames[0];
  let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  const take = (i) => { for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], f.poses[i * 7 + k]); hi[k] = Math.max(hi[k], f.poses[i * 7 + k]); } };
  const movers = S.world.bodies.map((b, i) => i).filter((i) => S.world.bodies[i].kind !== 'static' && (f.flags[i] & 1));
  (movers.length ? movers : S.world.bodies.map((b, i) => i)).forEach(take);
  if (!isFinite(lo[0])) { lo = [0, 0, 0]; hi = [0, 0, 0]; }
  S.cam.target = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2];
  S.cam.dist = Math.max(6, 1.6 * Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) + 4);
}

let last = 0;
function loop(t) {
  if (S.playing && S.frames.length > 1) {
    S.acc += (last ? t - last : 0) * S.speed * (S.world.tick_rate || 60) / 1000;
    if (S.acc >= 1) {
      const n = Math.floor(S.acc); S.acc -= n;
      if (S.frame + n >= S.frames.length - 1) { setFrame(S.frames.length - 1); S.playing = false; $('play').innerHTML = '&#9654;'; } else setFrame(S.frame + n);
    }
  }
  last = t;
  if (S.dirty) { S.dirty = false; render(); }
  requestAnimationFrame(loop);
}

const MAX_LIVE_FRAMES = 3600;

// The rooms of a live server, as links; refreshed every second.
async function roomList() {
  const w = await (await fetch('/world')).json();
  S.rooms = w.rooms.map((r) => r.name);
  $('title').textContent = 'live rooms';
  $('summary').textContent = w.rooms.length ? `${w.rooms.length} room(s) open: pick one` : 'no room is open yet';
  const list = $('bodies');
  list.textContent = '';
  for (const r of w.rooms) {
    const a = document.createElement('div');
    a.textContent = `${r.name} (${r.ticks} ticks)`;
    a.onclick = () => { location.search = '?room=' + encodeURIComponent(r.name); };
    list.appendChild(a);
  }
  setTimeout(roomList, 1000);
}

// A live room: new frames are polled for (the server answers when one is
// closed, or after a second), appended, and followed while the slider is
// at the newest frame.
async function poll() {
  try {
    const last = S.frames[S.frames.length - 1];
    const q = `room=${encodeURIComponent(S.room)}` + (last ? `&after=${last.tick}` : '');
    const r = await fetch(`/frames?${q}`);
    if (r.status === 404) { $('summary').textContent = `room ${S.room}: the match is over`; S.ended = true; return; }
    if (!r.ok) throw new Error(await r.text());
    const parsed = parseFrames(await r.arrayBuffer());
    if (parsed.nb > S.nb) { // bodies were added: fetch their geometry
      S.world = await (await fetch(`/world?room=${encodeURIComponent(S.room)}`)).json();
      S.nb = parsed.nb; setupGL(); listBodies();
    }
    if (parsed.frames.length) {
      const follow = S.follow || !S.frames.length;
      S.frames.push(...parsed.frames);
      const drop = Math.max(0, S.frames.length - MAX_LIVE_FRAMES);
      if (drop) { S.frames.splice(0, drop); S.frame = Math.max(0, S.frame - drop); }
      $('slider').max = S.frames.length - 1;
      if (follow) setFrame(S.frames.length - 1); else setFrame(S.frame);
      $('summary').textContent = `live room ${S.room}: ${S.nb} bodies, tick ${S.frames[S.frames.length - 1].tick} at ${S.world.tick_rate} Hz`;
      if (!S.ready) { frameCamera(); render(); S.ready = true; requestAnimationFrame(loop); }
    }
  } catch (e) {
    S.error = String(e && e.message || e);
    $('summary').textContent = `error: ${S.error}`;
    return;
  }
  setTimeout(poll, 0);
}

async function main() {
  try {
    S.room = new URLSearchParams(location.search).get('room');
    const q = S.room ? `?room=${encodeURIComponent(S.room)}` : '';
    const wr = await fetch('/world' + q);
    if (!wr.ok) throw new Error(await wr.text());
    S.world = await wr.json();
    if (S.world.kind === 'rooms') { roomList(); return; }
    $('title').textContent = S.world.title;
    if (S.world.kind === 'live') {
      S.live = true; S.follow = true; S.nb = S.world.bodies.length;
      setupGL(); bindInput(); listBodies();
      $('play').innerHTML = '&#10074;&#10074;';
      poll();
      return;
    }
    const parsed = parseFrames(await (await fetch('/frames')).arrayBuffer());
    S.frames = parsed.frames; S.nb = parsed.nb;
    if (!S.frames.length) throw new Error('no frames');
    $('summary').textContent = `${S.world.kind}: ${S.nb} bodies, ticks ${S.frames[0].tick}–${S.frames[S.frames.length - 1].tick} at ${S.world.tick_rate} Hz`;
    if (S.world.desync) {
      const d = S.world.desync;
      S.desyncFrame = d.frame;
      for (const s of d.suspects) for (const b of s.bodies) S.diverging.set(b.body, new Float32Array(b.minority_pose));
      showDesync();
    }
    setupGL();
    bindInput();
    listBodies();
    frameCamera();
    setFrame(S.world.desync ? S.world.desync.frame : 0);
    render();
    S.ready = true;
    requestAnimationFrame(loop);
  } catch (e) {
    S.error = String(e && e.message || e);
    $('summary').textContent = `error: ${S.error}`;
  }
}
main();
