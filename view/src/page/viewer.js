// lockstep viewer: a small WebGL2 renderer for the frames the viewer serves
// (the formats are in docs/viewer.md). No dependencies, no build step.
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
  litPixels() {
    const gl = S.gl, w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const px = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    let n = 0;
    for (let i = 0; i < px.length; i += 4) {
      if (Math.abs(px[i] - BG[0] * 255) + Math.abs(px[i + 1] - BG[1] * 255) + Math.abs(px[i + 2] - BG[2] * 255) > 12) n++;
    }
    return n;
  },
  pose(body) {
    const f = S.frames[S.frame];
    return f ? Array.from(f.poses.subarray(body * 7, body * 7 + 7)) : null;
  },
  setFrame(i) { setFrame(i); },
  bodyIndex(name) { return S.world ? S.world.bodies.findIndex((b) => b.name === name) : -1; },
};

// ---- frames ----------------------------------------------------------------
function parseFrames(buf) {
  const dv = new DataView(buf);
  const magic = String.fromCharCode(...new Uint8Array(buf, 0, 4));
  if (magic !== 'LSVF' || dv.getUint32(4, true) !== 1) throw new Error('not a version-1 frame stream');
  const nf = dv.getUint32(8, true), nb = dv.getUint32(12, true);
  let o = 16;
  const frames = [];
  for (let i = 0; i < nf; i++) {
    const tick = Number(dv.getBigUint64(o, true)); o += 8;
    const flags = new Uint8Array(nb), poses = new Float32Array(nb * 7);
    for (let b = 0; b < nb; b++) {
      flags[b] = dv.getUint8(o); o += 1;
      for (let k = 0; k < 7; k++) { poses[b * 7 + k] = dv.getFloat32(o, true); o += 4; }
    }
    const nc = dv.getUint32(o, true); o += 4;
    const contacts = new Float32Array(nc * 6);
    for (let k = 0; k < nc * 6; k++) { contacts[k] = dv.getFloat32(o, true); o += 4; }
    frames.push({ tick, flags, poses, contacts });
  }
  return { frames, nb };
}

// ---- math (column-major 4x4) ----------------------------------------------
function mul(a, b) {
  const r = new Float32Array(16);
  for (let c = 0; c < 4; c++) for (let i = 0; i < 4; i++) {
    let s = 0;
    for (let k = 0; k < 4; k++) s += a[k * 4 + i] * b[c * 4 + k];
    r[c * 4 + i] = s;
  }
  return r;
}
function poseMat(p, o) { // p: [x y z qx qy qz qw] at offset o
  const x = p[o + 3], y = p[o + 4], z = p[o + 5], w = p[o + 6];
  return new Float32Array([
    1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w), 0,
    2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w), 0,
    2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y), 0,
    p[o], p[o + 1], p[o + 2], 1]);
}
function perspective(fovy, aspect, near, far) {
  const f = 1 / Math.tan(fovy / 2), nf = 1 / (near - far);
  return new Float32Array([f / aspect, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) * nf, -1, 0, 0, 2 * far * near * nf, 0]);
}
function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
function cross(a, b) { return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]; }
function norm(a) { const l = Math.hypot(a[0], a[1], a[2]) || 1; return [a[0] / l, a[1] / l, a[2] / l]; }
function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
function lookAt(eye, at, up) {
  const z = norm(sub(eye, at)), x = norm(cross(up, z)), y = cross(z, x);
  return new Float32Array([x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0,
    -dot(x, eye), -dot(y, eye), -dot(z, eye), 1]);
}
function xform(m, v) {
  return [m[0] * v[0] + m[4] * v[1] + m[8] * v[2] + m[12], m[1] * v[0] + m[5] * v[1] + m[9] * v[2] + m[13],
    m[2] * v[0] + m[6] * v[1] + m[10] * v[2] + m[14]];
}

// ---- geometry --------------------------------------------------------------
// Each builder returns interleaved position+normal triangles and the
// positions alone (for bounding boxes).
function boxMesh(h) {
  const out = [];
  const faces = [[0, 1, 2], [0, 2, 1], [1, 2, 0], [1, 0, 2], [2, 0, 1], [2, 1, 0]];
  for (const [a, b, c] of faces) for (const s of [1, -1]) {
    const n = [0, 0, 0]; n[a] = s;
    const corner = (u, v) => { const p = [0, 0, 0]; p[a] = s * h[a]; p[b] = u * h[b]; p[c] = v * h[c]; return p; };
    const q = [corner(-1, -1), corner(1, -1), corner(1, 1), corner(-1, 1)];
    const tri = (i, j, k) => { for (const p of [q[i], q[j], q[k]]) out.push(...p, ...n); };
    // Orientation does not matter: back faces are not culled.
    tri(0, 1, 2); tri(0, 2, 3);
  }
  return out;
}
function roundMesh(radius, half) { // sphere (half 0) or capsule along y
  const out = [], seg = 24, rings = 16;
  const pt = (i, j) => {
    const th = (i / rings) * Math.PI, ph = (j / seg) * 2 * Math.PI;
    const n = [Math.sin(th) * Math.cos(ph), Math.cos(th), Math.sin(th) * Math.sin(ph)];
    const off = i <= rings / 2 ? half : -half;
    return { p: [n[0] * radius, n[1] * radius + off, n[2] * radius], n };
  };
  for (let i = 0; i < rings; i++) for (let j = 0; j < seg; j++) {
    const a = pt(i, j), b = pt(i + 1, j), c = pt(i + 1, j + 1), d = pt(i, j + 1);
    for (const v of [a, b, c, a, c, d]) out.push(...v.p, ...v.n);
    if (half > 0 && i === rings / 2 - 1) { // cylinder band between the hemispheres
      const e = pt(i + 1, j), f = pt(i + 1, j + 1);
      const lo = (v) => ({ p: [v.p[0], v.p[1] - 2 * half, v.p[2]], n: v.n });
      for (const v of [e, lo(e), lo(f), e, lo(f), f]) out.push(...v.p, ...v.n);
    }
  }
  return out;
}
function triMesh(vs, ids) {
  const out = [];
  for (const [i, j, k] of ids) {
    const a = vs[i], b = vs[j], c = vs[k];
    const n = norm(cross(sub(b, a), sub(c, a)));
    for (const p of [a, b, c]) out.push(...p, ...n);
  }
  return out;
}
function buildGeometry(g) {
  switch (g.type) {
    case 'box': return boxMesh(g.half_extents);
    case 'sphere': return roundMesh(g.radius, 0);
    case 'capsule': return roundMesh(g.radius, g.half_height);
    default: return triMesh(g.vertices, g.indices);
  }
}

// ---- GL --------------------------------------------------------------------
const BG = [0.082, 0.094, 0.114];
function shader(gl, vs, fs) {
  const p = gl.createProgram();
  for (const [type, src] of [[gl.VERTEX_SHADER, vs], [gl.FRAGMENT_SHADER, fs]]) {
    const s = gl.createShader(type);
    gl.shaderSource(s, src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    gl.attachShader(p, s);
  }
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
  return p;
}
const MESH_VS = `#version 300 es
uniform mat4 uVP, uModel; in vec3 aPos; in vec3 aNormal; out vec3 vN;
void main() { vN = mat3(uModel) * aNormal; gl_Position = uVP * uModel * vec4(aPos, 1.0); }`;
const MESH_FS = `#version 300 es
precision mediump float; uniform vec4 uColor; in vec3 vN; out vec4 o;
void main() {
  vec3 n = normalize(vN); if (!gl_FrontFacing) n = -n;
  float l = 0.3 + 0.55 * max(dot(n, normalize(vec3(0.4, 1.0, 0.3))), 0.0) + 0.15 * (0.5 + 0.5 * n.y);
  o = vec4(uColor.rgb * l, uColor.a);
}`;
const LINE_VS = `#version 300 es
uniform mat4 uVP; in vec3 aPos; void main() { gl_Position = uVP * vec4(aPos, 1.0); gl_PointSize = 5.0; }`;
const LINE_FS = `#version 300 es
precision mediump float; uniform vec4 uColor; out vec4 o; void main() { o = uColor; }`;

function setupGL() {
  const canvas = $('gl');
  const gl = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true });
  if (!gl) throw new Error('this browser has no WebGL2');
  S.gl = gl;
  S.mesh = shader(gl, MESH_VS, MESH_FS);
  S.line = shader(gl, LINE_VS, LINE_FS);
  S.lineBuf = gl.createBuffer();
  S.lineVao = gl.createVertexArray();
  gl.bindVertexArray(S.lineVao);
  gl.bindBuffer(gl.ARRAY_BUFFER, S.lineBuf);
  const lp = gl.getAttribLocation(S.line, 'aPos');
  gl.enableVertexAttribArray(lp);
  gl.vertexAttribPointer(lp, 3, gl.FLOAT, false, 12, 0);
  // One vertex array per collider.
  S.draw = S.world.bodies.map((b) => b.colliders.map((c) => {
    const data = new Float32Array(buildGeometry(c.geometry));
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const buf = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buf);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
    const ap = gl.getAttribLocation(S.mesh, 'aPos'), an = gl.getAttribLocation(S.mesh, 'aNormal');
    gl.enableVertexAttribArray(ap); gl.vertexAttribPointer(ap, 3, gl.FLOAT, false, 24, 0);
    gl.enableVertexAttribArray(an); gl.vertexAttribPointer(an, 3, gl.FLOAT, false, 24, 12);
    let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (let i = 0; i < data.length; i += 6) for (let k = 0; k < 3; k++) {
      lo[k] = Math.min(lo[k], data[i + k]); hi[k] = Math.max(hi[k], data[i + k]);
    }
    return { vao, count: data.length / 6, local: poseMat(c.local, 0), trigger: c.trigger, lo, hi };
  }));
  gl.bindVertexArray(null);
}

function hue(i) {
  const h = (i * 0.618034) % 1, s = 0.55, l = 0.58;
  const f = (n) => { const k = (n + h * 12) % 12; return l - s * Math.min(l, 1 - l) * Math.max(-1, Math.min(k - 3, 9 - k, 1)); };
  return [f(0), f(8), f(4)];
}
function bodyColor(i, b, asleep) {
  let c = b.kind === 'static' ? [0.5, 0.53, 0.57] : b.kind === 'kinematic' ? [0.35, 0.55, 0.95] : hue(i);
  if (S.diverging.has(i)) c = [0.98, 0.22, 0.2];
  if (i === S.picked) c = [1.0, 0.88, 0.3];
  if (asleep) c = c.map((x) => x * 0.45);
  return c;
}

// The pose of body i in the current frame, for the given side.
function poseOf(f, i, side) {
  if (side === 'minority' && S.frame === S.desyncFrame && S.diverging.has(i)) return [S.diverging.get(i), 0];
  return [f.poses, i * 7];
}

function drawWorld(vp, side, x, y, w, h) {
  const gl = S.gl, f = S.frames[S.frame];
  gl.viewport(x, y, w, h); gl.scissor(x, y, w, h);
  gl.clearColor(BG[0], BG[1], BG[2], 1); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.useProgram(S.mesh);
  gl.uniformMatrix4fv(gl.getUniformLocation(S.mesh, 'uVP'), false, vp);
  const uModel = gl.getUniformLocation(S.mesh, 'uModel'), uColor = gl.getUniformLocation(S.mesh, 'uColor');
  let drawn = 0;
  // Opaque colliders first; triggers and ghosts after, blended, without
  // writing depth: [body, collider, model matrix, colour, alpha].
  const translucent = [];
  const draw = (d, m, c, a) => {
    gl.uniformMatrix4fv(uModel, false, mul(m, d.local));
    gl.uniform4f(uColor, c[0], c[1], c[2], a);
    gl.bindVertexArray(d.vao); gl.drawArrays(gl.TRIANGLES, 0, d.count);
  };
  for (let i = 0; i < S.nb; i++) {
    if (!(f.flags[i] & 1)) continue;
    const [poses, o] = poseOf(f, i, side);
    const m = poseMat(poses, o), c = bodyColor(i, S.world.bodies[i], (f.flags[i] & 2) !== 0);
    for (const d of S.draw[i]) {
      if (d.trigger) translucent.push([i, d, m, c, 0.25]); else draw(d, m, c, 1);
    }
    drawn++;
  }
  if (side === 'overlay' && S.frame === S.desyncFrame) {
    for (const [i, p] of S.diverging) {
      const m = poseMat(p, 0);
      for (const d of S.draw[i]) translucent.push([i, d, m, [1.0, 0.35, 0.3], 0.4]);
    }
  }
  gl.enable(gl.BLEND); gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA); gl.depthMask(false);
  for (const [, d, m, c, a] of translucent) draw(d, m, c, a);
  gl.disable(gl.BLEND); gl.depthMask(true);
  drawOverlays(vp, f, side);
  return drawn;
}

function lines(vp, pts, color, mode) {
  if (!pts.length) return;
  const gl = S.gl;
  gl.useProgram(S.line);
  gl.uniformMatrix4fv(gl.getUniformLocation(S.line, 'uVP'), false, vp);
  gl.uniform4f(gl.getUniformLocation(S.line, 'uColor'), ...color);
  gl.bindVertexArray(S.lineVao);
  gl.bindBuffer(gl.ARRAY_BUFFER, S.lineBuf);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(pts), gl.STREAM_DRAW);
  gl.drawArrays(mode, 0, pts.length / 3);
}

function drawOverlays(vp, f, side) {
  const gl = S.gl;
  if ($('ov-contacts').checked && f.contacts.length) {
    const seg = [], dots = [];
    for (let k = 0; k < f.contacts.length; k += 6) {
      const p = [f.contacts[k], f.contacts[k + 1], f.contacts[k + 2]];
      const n = [f.contacts[k + 3], f.contacts[k + 4], f.contacts[k + 5]];
      dots.push(...p);
      seg.push(...p, p[0] + n[0] * 0.3, p[1] + n[1] * 0.3, p[2] + n[2] * 0.3);
    }
    gl.disable(gl.DEPTH_TEST);
    lines(vp, dots, [1, 0.3, 0.3, 1], gl.POINTS);
    lines(vp, seg, [1, 0.85, 0.2, 1], gl.LINES);
    gl.enable(gl.DEPTH_TEST);
  }
  if ($('ov-aabbs').checked) {
    const seg = [];
    for (let i = 0; i < S.nb; i++) {
      if (!(f.flags[i] & 1)) continue;
      const [poses, o] = poseOf(f, i, side);
      const m = poseMat(poses, o);
      for (const d of S.draw[i]) {
        const mm = mul(m, d.local), lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
        for (let c = 0; c < 8; c++) {
          const p = xform(mm, [c & 1 ? d.hi[0] : d.lo[0], c & 2 ? d.hi[1] : d.lo[1], c & 4 ? d.hi[2] : d.lo[2]]);
          for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], p[k]); hi[k] = Math.max(hi[k], p[k]); }
        }
        const v = (c) => [c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]];
        for (const [a, b] of [[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]]) seg.push(...v(a), ...v(b));
      }
    }
    lines(vp, seg, [0.4, 0.9, 0.5, 1], gl.LINES);
  }
}

function camera(aspect) {
  const c = S.cam;
  const eye = [c.target[0] + c.dist * Math.cos(c.pitch) * Math.sin(c.yaw), c.target[1] + c.dist * Math.sin(c.pitch),
    c.target[2] + c.dist * Math.cos(c.pitch) * Math.cos(c.yaw)];
  return mul(perspective(0.8, aspect, Math.max(0.01, c.dist * 0.005), c.dist * 50 + 1000), lookAt(eye, c.target, [0, 1, 0]));
}

function render() {
  const gl = S.gl, canvas = gl.canvas, dpr = window.devicePixelRatio || 1;
  const W = Math.max(1, Math.floor(canvas.clientWidth * dpr)), H = Math.max(1, Math.floor(canvas.clientHeight * dpr));
  if (canvas.width !== W || canvas.height !== H) { canvas.width = W; canvas.height = H; }
  gl.enable(gl.DEPTH_TEST); gl.enable(gl.SCISSOR_TEST);
  const split = S.world.kind === 'bundle' && S.mode === 'side';
  const views = split ? [['majority', 0, Math.floor(W / 2)], ['minority', Math.floor(W / 2), W - Math.floor(W / 2)]]
    : [[S.world.kind === 'bundle' ? 'overlay' : 'majority', 0, W]];
  let drawn = 0;
  S.views = [];
  for (const [side, x, w] of views) {
    const vp = camera(w / H);
    drawn = Math.max(drawn, drawWorld(vp, side, x, 0, w, H));
    S.views.push({ side, vp, x: x / dpr, w: w / dpr, h: H / dpr });
  }
  gl.disable(gl.SCISSOR_TEST);
  S.bodiesDrawn = drawn;
  S.framesDrawn++;
  drawLabels(split);
}

function project(v, p) {
  const x = v.vp[0] * p[0] + v.vp[4] * p[1] + v.vp[8] * p[2] + v.vp[12];
  const y = v.vp[1] * p[0] + v.vp[5] * p[1] + v.vp[9] * p[2] + v.vp[13];
  const w = v.vp[3] * p[0] + v.vp[7] * p[1] + v.vp[11] * p[2] + v.vp[15];
  if (w <= 0) return null;
  return [v.x + (x / w * 0.5 + 0.5) * v.w, (1 - (y / w * 0.5 + 0.5)) * v.h];
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
