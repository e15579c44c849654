// lockstep's browser client, the page: starts the worker (worker.js: the
// game's module and the WebTransport connection), sends it the keys held,
// and draws the world it reports with the viewer's renderer (render.js).
// The query string says where to join:
//   ?server=https://HOST:PORT/lockstep&room=R&name=N[&cert=SHA256HEX][&token=T][&bot=SEED]
// (cert: the development certificate's hash; bot: the game's bot plays
// until a key is pressed).
'use strict';

const $ = (id) => document.getElementById(id);
const query = new URLSearchParams(location.search);

// Each game key (lockstep_web::Keys) and the keyboard keys bound to it.
const KEYS = {
  ArrowUp: 1, KeyW: 1, ArrowDown: 2, KeyS: 2, ArrowLeft: 4, KeyA: 4, ArrowRight: 8, KeyD: 8,
  Space: 16, Enter: 32, KeyE: 32, ShiftLeft: 64, ShiftRight: 64,
};

const P = {
  worker: null, state: { phase: 'loading' }, error: null, keys: 0, asked: false, needWorld: false,
  R: null, world: null, nb: 0, own: -1, cam: null, drawnTick: -1, framesDrawn: 0,
};

// ---- for tests and tools ---------------------------------------------------
window.lockstep = {
  // The worker's last report (docs/browser.md) and the page's own.
  state() {
    return Object.assign({}, P.state, {
      pageError: P.error, framesDrawn: P.framesDrawn, isolated: self.crossOriginIsolated === true,
      statusText: $('status').textContent,
    });
  },
};

function fail(e) {
  if (P.error === null) P.error = String((e && e.message) || e);
  showStatus();
}

// ---- status ------------------------------------------------------------------
function showStatus() {
  const s = P.state, el = $('status'), error = P.error || s.workerError;
  let line;
  if (error) line = `error: ${error}`;
  else if (s.ended) {
    const what = { refused: 'refused', closed: 'match over', failed: 'failed', left: 'left' }[s.ended.kind];
    line = `${what}: ${s.ended.reason}${s.ended.detail ? ` (${s.ended.detail})` : ''}` +
      (s.ticksApplied ? ` after ${s.ticksApplied} ticks, ${s.reportsSent} hashes reported, ${s.desyncs} desyncs` : '');
  } else if (s.phase === 'playing') {
    line = `slot ${s.slot} · tick ${s.lastTick ?? '-'} · ${s.reportsSent} hashes reported · ` +
      (s.desyncs ? `DESYNC: ${s.lastDesync}` : 'the room agrees') + (s.bot ? ' · the bot plays until you press a key' : '');
  } else line = s.phase === 'loading' ? 'loading the module…' : s.connected ? 'joining…' : 'connecting…';
  el.textContent = line;
  el.className = error || s.ended ? 'ended' : s.desyncs ? 'desync' : '';
  const f = s.step;
  $('figures').textContent = f && f.count ? `step ${f.median.toFixed(2)} ms (median of ${f.count})` : '';
}

// ---- drawing -----------------------------------------------------------------
function draw(frame, world) {
  const parsed = parseFrames(frame);
  const f = parsed.frames[0];
  if (world) {
    P.world = JSON.parse(world);
    P.nb = parsed.nb;
    P.needWorld = false;
    P.R.setBodies(P.world.bodies);
    const own = P.state.ownBody;
    P.own = own ? P.world.bodies.findIndex((b) => b.handle === own.handle && b.generation === own.generation) : -1;
  }
  if (!P.world || f.tick === P.drawnTick) return;
  P.drawnTick = f.tick;
  // Follow the own player from behind (+z): up walks away from the camera.
  const p = P.own >= 0 ? [f.poses[P.own * 7], f.poses[P.own * 7 + 1], f.poses[P.own * 7 + 2]] : [0, 0, 0];
  if (!P.cam) P.cam = { yaw: 0, pitch: 1.2, dist: 24, target: p };
  P.cam.target = P.cam.target.map((t, k) => t + (p[k] - t) * 0.1);
  const gl = P.R.gl, [w, h] = P.R.fit();
  gl.enable(gl.DEPTH_TEST);
  P.R.drawWorld(orbitCamera(P.cam, w / h), f, [0, 0, w, h], {
    color: (i, asleep) => (i === P.own ? [1.0, 0.88, 0.3] : kindColor(i, P.world.bodies[i], asleep)),
  });
  P.framesDrawn++;
}

// The worker answers each request with its state, and a frame request
// with the world now (and the bodies, when asked).
function onReport({ data: m }) {
  P.state = m.state;
  if (m.kind === 'frame') {
    P.asked = false;
    try {
      // A frame with more bodies than drawn so far: ask for them.
      if (m.frame && !m.world && new DataView(m.frame).getUint32(12, true) !== P.nb) P.needWorld = true;
      else if (m.frame) draw(m.frame, m.world);
    } catch (e) {
      fail(e);
    }
  }
  showStatus();
}

function frame() {
  if (!P.asked && P.worker) {
    P.asked = true;
    P.worker.postMessage({ type: 'frame', world: !P.world || P.needWorld, origin: performance.timeOrigin });
  }
  requestAnimationFrame(frame);
}

// ---- start ---------------------------------------------------------------------
function bindKeys() {
  const set = (e, down) => {
    const bit = KEYS[e.code];
    if (bit === undefined || e.repeat) return;
    e.preventDefault();
    P.keys = down ? P.keys | bit : P.keys & ~bit;
    P.worker.postMessage({ type: 'keys', bits: P.keys });
  };
  addEventListener('keydown', (e) => set(e, true));
  addEventListener('keyup', (e) => set(e, false));
  addEventListener('blur', () => { P.keys = 0; P.worker.postMessage({ type: 'keys', bits: 0 }); });
  addEventListener('pagehide', () => P.worker.postMessage({ type: 'leave' }));
}

function main() {
  try {
    const server = query.get('server'), cert = query.get('cert');
    if (!server) throw new Error('the page needs ?server=https://HOST:PORT/lockstep&room=R (and &cert=SHA256HEX for a development certificate)');
    P.R = createRenderer($('gl'));
    P.worker = new Worker('/worker.js');
    P.worker.onmessage = onReport;
    P.worker.onerror = (e) => fail(e.message ? `${e.message} (worker.js:${e.lineno})` : 'the worker did not start');
    const bot = query.has('bot') ? Number(query.get('bot')) || 0 : -1;
    const params = { server, cert, room: query.get('room'), name: query.get('name'), token: query.get('token'), bot };
    P.worker.postMessage({ type: 'start', params });
    bindKeys();
    // The state also while nothing is drawn (a hidden page draws nothing).
    setInterval(() => P.worker.postMessage({ type: 'state', origin: performance.timeOrigin }), 250);
    requestAnimationFrame(frame);
  } catch (e) {
    fail(e);
  }
}
main();
