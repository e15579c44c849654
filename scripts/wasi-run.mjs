#!/usr/bin/env node
// Runs a wasm32-wasip1 program under Node's built-in WASI (preview1).
//
//   node scripts/wasi-run.mjs [--dir HOST=GUEST]... PROGRAM.wasm [ARGS...]
//
// The repository's scenes/ directory is always preopened as /scenes, and the
// program's working directory is /, so `--scene scenes/demo.toml` names the
// same file natively (from the repository root) and under WASI. --dir
// preopens more host directories. The program gets ARGS, no environment
// variables, and this script exits with the program's exit code (1, with a
// message, if it traps, e.g. on a panic).
//
// Node 20 needs no flag for WASI but prints an ExperimentalWarning when
// node:wasi loads; that one warning is dropped so the output is only the
// program's. Others still print.
import { readFile } from 'node:fs/promises';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const repo = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
const usage = 'usage: node scripts/wasi-run.mjs [--dir HOST=GUEST]... PROGRAM.wasm [ARGS...]';

const preopens = { '/scenes': path.join(repo, 'scenes') };
const argv = process.argv.slice(2);
while (argv[0] === '--dir') {
  const spec = argv[1] ?? '';
  const eq = spec.indexOf('=');
  if (eq <= 0 || eq === spec.length - 1) {
    console.error(`wasi-run: --dir needs HOST=GUEST, got '${spec}'\n${usage}`);
    process.exit(2);
  }
  preopens[spec.slice(eq + 1)] = path.resolve(spec.slice(0, eq));
  argv.splice(0, 2);
}
if (argv.length === 0 || argv[0].startsWith('-')) {
  console.error(usage);
  process.exit(2);
}
const [program, ...args] = argv;

const emitWarning = process.emitWarning;
process.emitWarning = function (warning, ...rest) {
  const text = typeof warning === 'string' ? warning : warning?.message;
  if (typeof text === 'string' && text.startsWith('WASI is an experimental feature')) return;
  return emitWarning.call(this, warning, ...rest);
};
const { WASI } = await import('node:wasi');

const wasi = new WASI({
  version: 'preview1',
  args: [path.basename(program), ...args],
  env: {},
  preopens,
  returnOnExit: true,
});
let code;
try {
  const module = await WebAssembly.compile(await readFile(program));
  const instance = await WebAssembly.instantiate(module, wasi.getImportObject());
  code = wasi.start(instance);
} catch (e) {
  console.error(`wasi-run: ${program}: ${e instanceof Error ? e.message : e}`);
  code = 1;
}
process.exitCode = code;
