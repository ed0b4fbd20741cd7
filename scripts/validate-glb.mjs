#!/usr/bin/env node
// Validates GLB files with the Khronos glTF Validator (npm gltf-validator).
// Usage: node scripts/validate-glb.mjs FILE.glb...
// Prints one JSON line per file: {"file", "errors", "warnings", "infos", "hints", "messages"}.
// Exits 1 when any file has errors or warnings, 2 when the validator is not installed.
import { readFile } from 'node:fs/promises';

let validator;
try {
  validator = await import('gltf-validator');
} catch {
  console.error('gltf-validator is not installed: run `npm ci` (scripts/test does it for you)');
  process.exit(2);
}

let failed = false;
for (const file of process.argv.slice(2)) {
  const bytes = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(bytes, { maxIssues: 200 });
  const { numErrors, numWarnings, numInfos, numHints, messages } = report.issues;
  console.log(JSON.stringify({
    file, errors: numErrors, warnings: numWarnings, infos: numInfos, hints: numHints,
    messages: messages.map((m) => `${m.code} ${m.pointer ?? ''}: ${m.message}`),
  }));
  if (numErrors > 0 || numWarnings > 0) failed = true;
}
process.exit(failed ? 1 : 0);
