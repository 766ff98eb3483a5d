#!/usr/bin/env bash
# Meshes the project has not seen, from assimp's test models (the Debian package
# assimp-testmodels), for `cargo bench --bench clean -- --dir DIR`: cubes as five formats
# write them, a low-poly toy (Wuson), a spider in many pieces, exports from 3ds Max and
# other tools, a sphere with a hole. Needs apt-get (Debian or Ubuntu); writes the files
# into DIR (default: target/assimp-meshes).
#
#   bash docs/assimp_meshes.sh && cargo bench --bench clean -- --dir target/assimp-meshes
set -euo pipefail
dir="${1:-target/assimp-meshes}"
mkdir -p "$dir"
dir="$(cd "$dir" && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
apt-get download assimp-testmodels >/dev/null 2>&1 || {
  echo "apt-get download assimp-testmodels failed (a Debian or Ubuntu package source is needed)" >&2
  exit 1
}
dpkg-deb -x assimp-testmodels_*.deb pkg
models=pkg/usr/share/assimp/models
cp "$models/OFF/Cube.off" "$dir/cube.off"
cp "$models/OBJ/box.obj" "$dir/box.obj"
cp "$models/PLY/cube.ply" "$dir/cube.ply"
cp "$models/glTF2/BoxTextured-glTF-Binary/BoxTextured.glb" "$dir/box_textured.glb"
cp "$models/OFF/Wuson.off" "$dir/wuson.off"
cp "$models/OBJ/spider.obj" "$dir/spider.obj"
cp "$models/STL/Spider_binary.stl" "$dir/spider_binary.stl"
cp "$models/STL/3DSMaxExport.STL" "$dir/3ds_max_export.stl"
cp "$models/OBJ/concave_polygon.obj" "$dir/concave_polygon.obj"
cp "$models/STL/sphereWithHole.stl" "$dir/sphere_with_hole.stl"
cp "$models/OBJ/regr01.obj" "$dir/regr01.obj"
cp "$models/OBJ/empty_mat.obj" "$dir/empty_mat.obj"
ls -l "$dir"
