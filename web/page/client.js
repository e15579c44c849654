// lockstep's browser client: the page around the game's module
// (/client.wasm, lockstep-web's export_client!). It connects with
// WebTransport, moves bytes between the connection and the module, runs
// the module whenever something arrives or its timer is due, reads the
// keyboard, and draws with the viewer's renderer (render.js). The module
// does the rest: the protocol, the rules, the simulation, the hashes
// (docs/browser.md). The query string says where to join:
//   ?server=https://HOST:PORT/lockstep&cert=SHA256HEX&room=R&name=N[&token=T][&bot=SEED]
'use strict';

const $ = (id) => document.getElementById(id);
const query = new URLSearchParams(location.search);
const utf8 = new TextEncoder();
const text = new TextDecoder();

// Each game key (lockstep_web::Keys) and the keyboard keys bound to it.
const KEYS = {
  ArrowUp: 1, KeyW: 1, ArrowDown: 2, KeyS: 2, ArrowLeft: 4, KeyA: 4, ArrowRight: 8, KeyD: 8,
  Space: 16, Enter: 32, KeyE: 32, ShiftLeft: 64, ShiftRight: 64,
};

const S = {
  module: null, wt: null, writer: null, datagrams: null, timer: 0, keys: 0,
  error: null, closed: false, at: {}, steps: [], framesDrawn: 0, drawnTick: -1,
  R: null, world: null, nb: 0, own: -1, cam: null,
};

// ---- the module's memory -------------------------------------------------
function put(bytes) {
  const at = S.module.lockstep_buffer(bytes.length); // may grow the memory
  new Uint8Array(S.module.memory.buffer, at, bytes.length).set(bytes);
}
function output(len) {
  return new Uint8Array(S.module.memory.buffer, S.module.lockstep_output(), len).slice();
}
function status() {
  return S.module ? JSON.parse(text.decode(output(S.module.lockstep_status()))) : { phase: 'loading' };
}

// ---- for tests and tools ---------------------------------------------------
function stepFigures() {
  const v = Float64Array.from(S.steps).sort();
  const at = (p) => (v.length ? v[Math.min(v.length - 1, Math.floor(p * v.length))] : null);
  return { count: v.length, median: at(0.5), p90: at(0.9), max: v.length ? v[v.length - 1] : null };
}
window.lockstep = {
  // The module's status (docs/browser.md) and the page's own: milestones
  // in ms since the page's time origin, the step's cost, frames drawn.
  state() {
    return Object.assign(status(), {
      pageError: S.error, connected: !!S.writer, at: S.at, step: stepFigures(),
      framesDrawn: S.framesDrawn, isolated: self.crossOriginIsolated === true,
      statusText: $('status').textContent,
    });
  },
  stepTimes() { return S.steps.slice(); },
};

// ---- the loop ----------------------------------------------------------------
// Runs whatever is due: inputs and timers (pump), every bundle that is
// ready (step, timed alone, then report), then sends what the module
// queued and sets the timer for its next wake-up.
function run() {
  if (!S.module) return;
  try {
    const wake = S.module.lockstep_pump(performance.now());
    for (;;) {
      const t0 = performance.now();
      const tick = S.module.lockstep_step();
      const t1 = performance.now();
      if (tick < 0) break;
      S.steps.push(t1 - t0);
      S.module.lockstep_report();
      if (S.at.firstTick === undefined) S.at.firstTick = t1;
    }
    send();
    clearTimeout(S.timer);
    if (wake >= 0) S.timer = setTimeout(run, Math.max(0, wake - performance.now()));
  } catch (e) {
    fail(e);
  }
}

function send() {
  if (!S.writer) return;
  const n = S.module.lockstep_take_stream();
  if (n > 0) S.writer.write(output(n)).catch(fail);
  for (let d = S.module.lockstep_take_datagram(); d >= 0; d = S.module.lockstep_take_datagram()) {
    S.datagrams.write(output(d)).catch(() => {}); // a lost datagram is the protocol's business
  }
  const s = status();
  if (s.phase === 'ended' && !S.closed) {
    S.closed = true;
    S.writer.close().catch(() => {});
    setTimeout(() => S.wt.close(), 500);
  }
}

function fail(e) {
  if (S.error === null) S.error = String((e && e.message) || e);
  showStatus();
}

function hexBytes(hex) {
  const b = new Uint8Array(hex.length / 2);
  for (let i = 0; i < b.length; i++) b[i] = parseInt(hex.substr(2 * i, 2), 16);
  return b;
}

async function readStream(reader) {
  let why = 'the server ended the stream';
  try {
    for (;;) {
      const { value, done } = await reader.read();
      if (done) break;
      put(value);
      S.module.lockstep_stream(value.length, performance.now());
      if (S.at.welcome === undefined && status().joined) S.at.welcome = performance.now();
      run();
    }
  } catch (e) {
    why = String((e && e.message) || e);
  }
  ended(why);
}

async function readDatagrams(reader) {
  try {
    for (;;) {
      const { value, done } = await reader.read();
      if (done) return;
      put(value);
      S.module.lockstep_datagram(value.length, performance.now());
      run();
    }
  } catch (e) {
    // The stream's end says why.
  }
}

function ended(why) {
  const bytes = utf8.encode(why);
  put(bytes);
  S.module.lockstep_stream_ended(bytes.length);
  clearTimeout(S.timer);
  showStatus();
}

// ---- status ------------------------------------------------------------------
function showStatus() {
  const s = status(), el = $('status');
  let line;
  if (S.error) line = `error: ${S.error}`;
  else if (s.ended) {
    const what = { refused: 'refused', closed: 'match over', failed: 'failed', left: 'left' }[s.ended.kind];
    line = `${what}: ${s.ended.reason}${s.ended.detail ? ` (${s.ended.detail})` : ''}` +
      (s.ticksApplied ? ` after ${s.ticksApplied} ticks, ${s.reportsSent} hashes reported, ${s.desyncs} desyncs` : '');
  } else if (s.phase === 'playing') {
    line = `slot ${s.slot} · tick ${s.lastTick ?? '-'} · ${s.reportsSent} hashes reported · ` +
      (s.desyncs ? `DESYNC: ${s.lastDesync}` : 'the room agrees') + (s.bot ? ' · the bot plays until you press a key' : '');
  } else line = S.writer ? 'joining…' : 'connecting…';
  el.textContent = line;
  el.className = S.error || s.ended ? 'ended' : s.desyncs ? 'desync' : '';
  const f = stepFigures();
  $('figures').textContent = f.count ? `step ${f.median.toFixed(2)} ms (median of ${f.count})` : '';
}

// ---- drawing -----------------------------------------------------------------
function draw() {
  const n = S.module.lockstep_frame();
  if (!n) return;
  const parsed = parseFrames(output(n).buffer);
  const f = parsed.frames[0];
  if (parsed.nb !== S.nb) { // the first frame, or bodies were added
    S.world = JSON.parse(text.decode(output(S.module.lockstep_world())));
    S.nb = parsed.nb;
    S.R.setBodies(S.world.bodies);
    const own = status().ownBody;
    S.own = own ? S.world.bodies.findIndex((b) => b.handle === own.handle && b.generation === own.generation) : -1;
  }
  if (f.tick === S.drawnTick) return;
  S.drawnTick = f.tick;
  // Follow the own player from behind (+z): up walks away from the camera.
  const p = S.own >= 0 ? [f.poses[S.own * 7], f.poses[S.own * 7 + 1], f.poses[S.own * 7 + 2]] : [0, 0, 0];
  if (!S.cam) S.cam = { yaw: 0, pitch: 0.75, dist: 22, target: p };
  S.cam.target = S.cam.target.map((t, k) => t + (p[k] - t) * 0.1);
  const gl = S.R.gl, [W, H] = S.R.fit();
  gl.enable(gl.DEPTH_TEST);
  S.R.drawWorld(orbitCamera(S.cam, W / H), f, [0, 0, W, H], {
    color: (i, asleep) => (i === S.own ? [1.0, 0.88, 0.3] : kindColor(i, S.world.bodies[i], asleep)),
  });
  S.framesDrawn++;
}

function frame() {
  try {
    if (S.module) { showStatus(); draw(); }
  } catch (e) {
    fail(e);
  }
  requestAnimationFrame(frame);
}

// ---- start ---------------------------------------------------------------------
function bindKeys() {
  const set = (e, down) => {
    const bit = KEYS[e.code];
    if (bit === undefined || e.repeat) return;
    e.preventDefault();
    S.keys = down ? S.keys | bit : S.keys & ~bit;
    S.module.lockstep_keys(S.keys);
  };
  addEventListener('keydown', (e) => set(e, true));
  addEventListener('keyup', (e) => set(e, false));
  addEventListener('blur', () => { S.keys = 0; S.module.lockstep_keys(0); });
  addEventListener('pagehide', () => { S.module.lockstep_leave(); send(); });
}

async function main() {
  try {
    const server = query.get('server'), cert = query.get('cert');
    if (!server || !cert) throw new Error('the page needs ?server=https://HOST:PORT/lockstep&cert=SHA256HEX&room=R');
    const { instance } = await WebAssembly.instantiateStreaming(fetch('/client.wasm'), {});
    S.module = instance.exports;
    S.at.module = performance.now();
    S.R = createRenderer($('gl'));
    bindKeys();
    requestAnimationFrame(frame);
    const [room, name, token] = ['room', 'name', 'token'].map((k) => utf8.encode(query.get(k) || ''));
    put(new Uint8Array([...room, ...name, ...token]));
    const bot = query.has('bot') ? Number(query.get('bot')) || 0 : -1;
    if (S.module.lockstep_start(room.length, name.length, token.length, bot) !== 0) throw new Error(status().error);
    S.wt = new WebTransport(server, { serverCertificateHashes: [{ algorithm: 'sha-256', value: hexBytes(cert) }] });
    S.wt.closed.then((i) => ended(`closed (${i.closeCode}: ${i.reason || 'no reason'})`), (e) => ended(String(e.message || e)));
    await S.wt.ready;
    S.at.connected = performance.now();
    const stream = await S.wt.createBidirectionalStream();
    S.writer = stream.writable.getWriter();
    S.datagrams = S.wt.datagrams.writable.getWriter();
    readStream(stream.readable.getReader());
    readDatagrams(S.wt.datagrams.readable.getReader());
    run(); // sends the join
  } catch (e) {
    fail(e);
  }
}
main();
