// lockstep's browser client, its worker: the game's module (/client.wasm,
// lockstep-web's export_client!) and the WebTransport connection, off the
// page's thread so that drawing never delays an input or a tick. It moves
// bytes between the connection and the module and runs the module whenever
// something arrives or its timer is due; the module does the rest (the
// protocol, the rules, the simulation, the hashes: docs/browser.md). The
// page (client.js) sends the keys and asks for frames to draw.
'use strict';

const utf8 = new TextEncoder();
const text = new TextDecoder();
const W = { module: null, wt: null, writer: null, datagrams: null, timer: 0, error: null, closed: false, at: {}, steps: [] };

// ---- the module's memory -------------------------------------------------
function put(bytes) {
  const at = W.module.lockstep_buffer(bytes.length); // may grow the memory
  new Uint8Array(W.module.memory.buffer, at, bytes.length).set(bytes);
}
function output(len) {
  return new Uint8Array(W.module.memory.buffer, W.module.lockstep_output(), len).slice();
}
function status() {
  return W.module ? JSON.parse(text.decode(output(W.module.lockstep_status()))) : { phase: 'loading' };
}
// A time on the page's clock: ms since the page's time origin.
const pageTime = (t, origin) => performance.timeOrigin + t - origin;

// ---- the loop ----------------------------------------------------------------
// Runs whatever is due: inputs and timers (pump), every bundle that is
// ready (step, timed alone, then report), then sends what the module
// queued and sets the timer for its next wake-up.
function run() {
  if (!W.module) return;
  try {
    const wake = W.module.lockstep_pump(performance.now());
    for (;;) {
      const t0 = performance.now();
      const tick = W.module.lockstep_step();
      const t1 = performance.now();
      if (tick < 0) break;
      W.steps.push(t1 - t0);
      W.module.lockstep_report();
      if (W.at.firstTick === undefined) W.at.firstTick = t1;
    }
    send();
    clearTimeout(W.timer);
    if (wake >= 0) W.timer = setTimeout(run, Math.max(0, wake - performance.now()));
  } catch (e) {
    fail(e);
  }
}

function send() {
  if (!W.writer) return;
  const n = W.module.lockstep_take_stream();
  if (n > 0) W.writer.write(output(n)).catch(fail);
  for (let d = W.module.lockstep_take_datagram(); d >= 0; d = W.module.lockstep_take_datagram()) {
    W.datagrams.write(output(d)).catch(() => {}); // a lost datagram is the protocol's business
  }
  if (status().phase === 'ended' && !W.closed) {
    W.closed = true;
    W.writer.close().catch(() => {});
    setTimeout(() => W.wt.close(), 500);
  }
}

function fail(e) {
  if (W.error === null) W.error = String((e && e.message) || e);
}

async function readStream(reader) {
  let why = 'the server ended the stream';
  try {
    for (;;) {
      const { value, done } = await reader.read();
      if (done) break;
      put(value);
      W.module.lockstep_stream(value.length, performance.now());
      if (W.at.welcome === undefined && status().joined) W.at.welcome = performance.now();
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
      W.module.lockstep_datagram(value.length, performance.now());
      run();
    }
  } catch (e) {
    // The stream's end says why.
  }
}

function ended(why) {
  const bytes = utf8.encode(why);
  put(bytes);
  W.module.lockstep_stream_ended(bytes.length);
  clearTimeout(W.timer);
}

function hexBytes(hex) {
  const b = new Uint8Array(hex.length / 2);
  for (let i = 0; i < b.length; i++) b[i] = parseInt(hex.substr(2 * i, 2), 16);
  return b;
}

async function start(p) {
  try {
    const { instance } = await WebAssembly.instantiateStreaming(fetch('/client.wasm'), {});
    W.module = instance.exports;
    W.at.module = performance.now();
    const [room, name, token] = [p.room, p.name, p.token].map((s) => utf8.encode(s || ''));
    put(new Uint8Array([...room, ...name, ...token]));
    if (W.module.lockstep_start(room.length, name.length, token.length, p.bot) !== 0) throw new Error(status().error);
    // A development certificate is trusted by its hash; without one the
    // browser checks the server's certificate as for any HTTPS site.
    const options = p.cert ? { serverCertificateHashes: [{ algorithm: 'sha-256', value: hexBytes(p.cert) }] } : {};
    W.wt = new WebTransport(p.server, options);
    W.wt.closed.then((i) => ended(`closed (${i.closeCode}: ${i.reason || 'no reason'})`), (e) => ended(String(e.message || e)));
    await W.wt.ready;
    W.at.connected = performance.now();
    const stream = await W.wt.createBidirectionalStream();
    W.writer = stream.writable.getWriter();
    W.datagrams = W.wt.datagrams.writable.getWriter();
    readStream(stream.readable.getReader());
    readDatagrams(W.wt.datagrams.readable.getReader());
    run(); // sends the join
  } catch (e) {
    fail(e);
  }
}

// The step's cost so far: median, 90th percentile, maximum (ms).
function stepFigures() {
  const v = Float64Array.from(W.steps).sort();
  const at = (p) => (v.length ? v[Math.min(v.length - 1, Math.floor(p * v.length))] : null);
  return { count: v.length, median: at(0.5), p90: at(0.9), max: v.length ? v[v.length - 1] : null };
}

// What the page sees: the module's status, the worker's own (milestones on
// the page's clock, the step's cost), and for a frame request the world
// now (and the bodies, when asked).
function report(m) {
  const at = {};
  for (const k in W.at) at[k] = pageTime(W.at[k], m.origin);
  const out = Object.assign(status(), { workerError: W.error, connected: !!W.writer, at, step: stepFigures() });
  const msg = { kind: m.type, state: out };
  if (m.type === 'frame' && W.module) {
    const n = W.module.lockstep_frame();
    if (n) msg.frame = output(n).buffer;
    if (n && m.world) msg.world = text.decode(output(W.module.lockstep_world()));
  }
  postMessage(msg, msg.frame ? [msg.frame] : []);
}

onmessage = ({ data: m }) => {
  if (m.type === 'start') start(m.params);
  else if (m.type === 'keys' && W.module) W.module.lockstep_keys(m.bits);
  else if (m.type === 'leave' && W.module) { W.module.lockstep_leave(); send(); }
  else if (m.type === 'frame' || m.type === 'state') report(m);
};
