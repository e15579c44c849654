#!/usr/bin/env node
// Drives core's `plain_exports` example, built for wasm32-unknown-unknown,
// from JS the way a browser page would: no WASI, no imports at all (this
// script fails if the module asks for any), the scene text passed in
// through linear memory. Prints the same lines as the `scene_hashes`
// example, one `tick <n> <16 hex digits>` per tick.
//
//   node scripts/plain-exports-run.mjs PLAIN_EXPORTS.wasm (--scene FILE | --random SEED) --ticks N
//
// Exits 0, or 2 with a message on stderr (bad arguments, a scene that does
// not load, an arithmetic fault, or a module that imports something).
import { readFileSync, writeSync } from 'node:fs';

const usage =
  'usage: node scripts/plain-exports-run.mjs PLAIN_EXPORTS.wasm (--scene FILE | --random SEED) --ticks N';
function fail(message) {
  console.error(`plain-exports-run: ${message}`);
  process.exit(2);
}

const [program, ...rest] = process.argv.slice(2);
if (!program || program.startsWith('-')) fail(usage);
let scene, seed, ticks;
for (let i = 0; i < rest.length; i += 2) {
  const [flag, value] = [rest[i], rest[i + 1]];
  if (value === undefined) fail(`${flag} needs a value\n${usage}`);
  if (flag === '--scene') scene = value;
  else if (flag === '--random' && /^\d+$/.test(value)) seed = BigInt(value);
  else if (flag === '--ticks' && /^\d+$/.test(value)) ticks = Number(value);
  else fail(`bad argument ${flag} ${value}\n${usage}`);
}
if ((scene === undefined) === (seed === undefined) || ticks === undefined) fail(usage);

let module;
try {
  module = new WebAssembly.Module(readFileSync(program));
} catch (e) {
  fail(`${program}: ${e.message}`);
}
const imports = WebAssembly.Module.imports(module);
if (imports.length > 0) {
  fail(`${program} imports ${imports.map((i) => `${i.module}.${i.name}`).join(', ')}; expected nothing`);
}
const core = new WebAssembly.Instance(module, {}).exports;

function errorMessage() {
  const bytes = new Uint8Array(core.memory.buffer, core.lockstep_error_ptr(), core.lockstep_error_len());
  return new TextDecoder().decode(bytes);
}

let status;
if (scene !== undefined) {
  let text;
  try {
    text = readFileSync(scene);
  } catch (e) {
    fail(`${scene}: ${e.message}`);
  }
  // Memory may grow inside lockstep_input: take the view after the call.
  const at = core.lockstep_input(text.length);
  new Uint8Array(core.memory.buffer, at, text.length).set(text);
  status = core.lockstep_load_scene(text.length);
} else {
  status = core.lockstep_load_random(seed);
}
if (status !== 0) fail(`${scene ?? `random scene ${seed}`}: ${errorMessage()}`);

let out = '';
for (let i = 0; i < ticks; i++) {
  const hash = core.lockstep_step(); // a u64 export is a BigInt in JS
  if (core.lockstep_faults() !== 0) {
    writeSync(1, out);
    fail(`arithmetic fault at tick ${core.lockstep_tick()} (faults ${core.lockstep_faults()})`);
  }
  out += `tick ${core.lockstep_tick()} ${BigInt.asUintN(64, hash).toString(16).padStart(16, '0')}\n`;
}
writeSync(1, out);
