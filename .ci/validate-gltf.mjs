// Runs the Khronos glTF Validator on each .gltf or .glb file named on the command line.
//
//   node .ci/validate-gltf.mjs FILE...
//
// Prints, per file, the counts of errors, warnings, infos and hints and every message, and
// exits non-zero if any file has an error or a warning, or cannot be read or validated.
// External resources of a .gltf (its .bin) are read from disk relative to the file.
// Install the validator first with `npm ci --prefix .ci`.

import { readFile } from 'node:fs/promises';
import path from 'node:path';
import * as validator from 'gltf-validator';

const SEVERITY = ['error', 'warning', 'info', 'hint'];

async function validateFile(file) {
  const bytes = new Uint8Array(await readFile(file));
  const dir = path.dirname(path.resolve(file));
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 0,
    writeTimestamp: false,
    externalResourceFunction: async (uri) => {
      const resolved = path.resolve(dir, decodeURIComponent(uri));
      const relative = path.relative(dir, resolved);
      if (relative.startsWith('..') || path.isAbsolute(relative)) {
        throw new Error(`external resource ${uri} lies outside ${dir}`);
      }
      return new Uint8Array(await readFile(resolved));
    },
  });
  const issues = report.issues;
  console.log(
    `${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
      `${issues.numInfos} infos, ${issues.numHints} hints`,
  );
  for (const m of issues.messages) {
    const severity = SEVERITY[m.severity] ?? `severity ${m.severity}`;
    console.log(`  ${severity} ${m.code} at ${m.pointer ?? m.offset ?? '?'}: ${m.message}`);
  }
  return issues.numErrors === 0 && issues.numWarnings === 0;
}

async function main() {
  const files = process.argv.slice(2);
  if (files.length === 0) {
    console.error('usage: node .ci/validate-gltf.mjs FILE...');
    process.exit(2);
  }
  console.log(`gltf-validator ${validator.version()}`);
  let ok = true;
  for (const file of files) {
    try {
      ok = (await validateFile(file)) && ok;
    } catch (error) {
      console.log(`${file}: could not be validated: ${error}`);
      ok = false;
    }
  }
  process.exit(ok ? 0 : 1);
}

await main();
