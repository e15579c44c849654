// lockstep's WebGL2 renderer, shared by the viewer (viewer.js) and the
// browser client (lockstep-web's client.js): the frame stream's parser
// (docs/viewer.md), 4x4 math, each collider's triangles, and a renderer
// that draws a world's bodies in a frame's poses. Classic script: its
// functions are globals of the page. No dependencies, no build step.
'use strict';

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

function hue(i) {
  const h = (i * 0.618034) % 1, s = 0.55, l = 0.58;
  const f = (n) => { const k = (n + h * 12) % 12; return l - s * Math.min(l, 1 - l) * Math.max(-1, Math.min(k - 3, 9 - k, 1)); };
  return [f(0), f(8), f(4)];
}
// A body's colour by its kind: static grey, kinematic blue, dynamic a hue of
// its own; dimmed while it sleeps.
function kindColor(i, b, asleep) {
  const c = b.kind === 'static' ? [0.5, 0.53, 0.57] : b.kind === 'kinematic' ? [0.35, 0.55, 0.95] : hue(i);
  return asleep ? c.map((x) => x * 0.45) : c;
}

// A renderer on `canvas`: setBodies(bodies) builds each collider's vertex
// array once (bodies as the /world JSON lists them); drawWorld draws a
// frame's bodies into one viewport.
function createRenderer(canvas) {
  const gl = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true });
  if (!gl) throw new Error('this browser has no WebGL2');
  const R = { gl, draw: [], mesh: shader(gl, MESH_VS, MESH_FS), line: shader(gl, LINE_VS, LINE_FS) };
  const lineBuf = gl.createBuffer(), lineVao = gl.createVertexArray();
  gl.bindVertexArray(lineVao);
  gl.bindBuffer(gl.ARRAY_BUFFER, lineBuf);
  const lp = gl.getAttribLocation(R.line, 'aPos');
  gl.enableVertexAttribArray(lp);
  gl.vertexAttribPointer(lp, 3, gl.FLOAT, false, 12, 0);
  gl.bindVertexArray(null);

  // One vertex array per collider.
  R.setBodies = (bodies) => {
    R.draw = bodies.map((b) => b.colliders.map((c) => {
      const data = new Float32Array(buildGeometry(c.geometry));
      const vao = gl.createVertexArray();
      gl.bindVertexArray(vao);
      const buf = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, buf);
      gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
      const ap = gl.getAttribLocation(R.mesh, 'aPos'), an = gl.getAttribLocation(R.mesh, 'aNormal');
      gl.enableVertexAttribArray(ap); gl.vertexAttribPointer(ap, 3, gl.FLOAT, false, 24, 0);
      gl.enableVertexAttribArray(an); gl.vertexAttribPointer(an, 3, gl.FLOAT, false, 24, 12);
      let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
      for (let i = 0; i < data.length; i += 6) for (let k = 0; k < 3; k++) {
        lo[k] = Math.min(lo[k], data[i + k]); hi[k] = Math.max(hi[k], data[i + k]);
      }
      return { vao, count: data.length / 6, local: poseMat(c.local, 0), trigger: c.trigger, lo, hi };
    }));
    gl.bindVertexArray(null);
  };

  // Resizes the canvas to its box on screen; returns [width, height] in
  // device pixels.
  R.fit = () => {
    const dpr = window.devicePixelRatio || 1;
    const W = Math.max(1, Math.floor(canvas.clientWidth * dpr)), H = Math.max(1, Math.floor(canvas.clientHeight * dpr));
    if (canvas.width !== W || canvas.height !== H) { canvas.width = W; canvas.height = H; }
    return [W, H];
  };

  R.lines = (vp, pts, color, mode) => {
    if (!pts.length) return;
    gl.useProgram(R.line);
    gl.uniformMatrix4fv(gl.getUniformLocation(R.line, 'uVP'), false, vp);
    gl.uniform4f(gl.getUniformLocation(R.line, 'uColor'), ...color);
    gl.bindVertexArray(lineVao);
    gl.bindBuffer(gl.ARRAY_BUFFER, lineBuf);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array(pts), gl.STREAM_DRAW);
    gl.drawArrays(mode, 0, pts.length / 3);
  };

  // Draws frame `f` (flags, poses, contacts) with view-projection `vp`
  // into the viewport [x, y, w, h]. o.pose(i) gives body i's pose as
  // [array, offset] (default: the frame's), o.color(i, asleep) its colour,
  // o.ghosts extra translucent bodies [[i, pose7, colour, alpha]];
  // o.contacts and o.aabbs draw those overlays. Returns the bodies drawn.
  R.drawWorld = (vp, f, [x, y, w, h], o) => {
    const pose = o.pose || ((i) => [f.poses, i * 7]);
    gl.viewport(x, y, w, h); gl.scissor(x, y, w, h);
    gl.clearColor(BG[0], BG[1], BG[2], 1); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.useProgram(R.mesh);
    gl.uniformMatrix4fv(gl.getUniformLocation(R.mesh, 'uVP'), false, vp);
    const uModel = gl.getUniformLocation(R.mesh, 'uModel'), uColor = gl.getUniformLocation(R.mesh, 'uColor');
    let drawn = 0;
    // Opaque colliders first; triggers and ghosts after, blended, without
    // writing depth: [collider, model matrix, colour, alpha].
    const translucent = [];
    const draw = (d, m, c, a) => {
      gl.uniformMatrix4fv(uModel, false, mul(m, d.local));
      gl.uniform4f(uColor, c[0], c[1], c[2], a);
      gl.bindVertexArray(d.vao); gl.drawArrays(gl.TRIANGLES, 0, d.count);
    };
    const nb = Math.min(R.draw.length, f.flags.length);
    for (let i = 0; i < nb; i++) {
      if (!(f.flags[i] & 1)) continue;
      const [poses, off] = pose(i);
      const m = poseMat(poses, off), c = o.color(i, (f.flags[i] & 2) !== 0);
      for (const d of R.draw[i]) {
        if (d.trigger) translucent.push([d, m, c, 0.25]); else draw(d, m, c, 1);
      }
      drawn++;
    }
    for (const [i, p, c, a] of o.ghosts || []) {
      const m = poseMat(p, 0);
      for (const d of R.draw[i]) translucent.push([d, m, c, a]);
    }
    gl.enable(gl.BLEND); gl.blendFunc(gl.SRC_ALPHA, gl.ONE_MINUS_SRC_ALPHA); gl.depthMask(false);
    for (const [d, m, c, a] of translucent) draw(d, m, c, a);
    gl.disable(gl.BLEND); gl.depthMask(true);
    if (o.contacts && f.contacts.length) {
      const seg = [], dots = [];
      for (let k = 0; k < f.contacts.length; k += 6) {
        const p = [f.contacts[k], f.contacts[k + 1], f.contacts[k + 2]];
        const n = [f.contacts[k + 3], f.contacts[k + 4], f.contacts[k + 5]];
        dots.push(...p);
        seg.push(...p, p[0] + n[0] * 0.3, p[1] + n[1] * 0.3, p[2] + n[2] * 0.3);
      }
      gl.disable(gl.DEPTH_TEST);
      R.lines(vp, dots, [1, 0.3, 0.3, 1], gl.POINTS);
      R.lines(vp, seg, [1, 0.85, 0.2, 1], gl.LINES);
      gl.enable(gl.DEPTH_TEST);
    }
    if (o.aabbs) {
      const seg = [];
      for (let i = 0; i < nb; i++) {
        if (!(f.flags[i] & 1)) continue;
        const [poses, off] = pose(i);
        const m = poseMat(poses, off);
        for (const d of R.draw[i]) {
          const mm = mul(m, d.local), lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
          for (let c = 0; c < 8; c++) {
            const p = xform(mm, [c & 1 ? d.hi[0] : d.lo[0], c & 2 ? d.hi[1] : d.lo[1], c & 4 ? d.hi[2] : d.lo[2]]);
            for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], p[k]); hi[k] = Math.max(hi[k], p[k]); }
          }
          const v = (c) => [c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]];
          for (const [a, b] of [[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]]) seg.push(...v(a), ...v(b));
        }
      }
      R.lines(vp, seg, [0.4, 0.9, 0.5, 1], gl.LINES);
    }
    return drawn;
  };

  // Pixels that differ from the background in the last drawn frame.
  R.litPixels = () => {
    const w = gl.drawingBufferWidth, h = gl.drawingBufferHeight;
    const px = new Uint8Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
    let n = 0;
    for (let i = 0; i < px.length; i += 4) {
      if (Math.abs(px[i] - BG[0] * 255) + Math.abs(px[i + 1] - BG[1] * 255) + Math.abs(px[i + 2] - BG[2] * 255) > 12) n++;
    }
    return n;
  };
  return R;
}

// The view-projection of an orbit camera {yaw, pitch, dist, target}.
function orbitCamera(c, aspect) {
  const eye = [c.target[0] + c.dist * Math.cos(c.pitch) * Math.sin(c.yaw), c.target[1] + c.dist * Math.sin(c.pitch),
    c.target[2] + c.dist * Math.cos(c.pitch) * Math.cos(c.yaw)];
  return mul(perspective(0.8, aspect, Math.max(0.01, c.dist * 0.005), c.dist * 50 + 1000), lookAt(eye, c.target, [0, 1, 0]));
}

// A world point on screen in a view {vp, x, w, h} (CSS pixels), or null
// behind the camera.
function project(v, p) {
  const x = v.vp[0] * p[0] + v.vp[4] * p[1] + v.vp[8] * p[2] + v.vp[12];
  const y = v.vp[1] * p[0] + v.vp[5] * p[1] + v.vp[9] * p[2] + v.vp[13];
  const w = v.vp[3] * p[0] + v.vp[7] * p[1] + v.vp[11] * p[2] + v.vp[15];
  if (w <= 0) return null;
  return [v.x + (x / w * 0.5 + 0.5) * v.w, (1 - (y / w * 0.5 + 0.5)) * v.h];
}
