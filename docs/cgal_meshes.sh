#!/usr/bin/env bash
# Meshes the project has not seen, from the data CGAL ships for its demos (the Debian
# package libcgal-demo, 24 MB), for `cargo bench --bench clean -- --dir DIR`: 24 organic,
# CAD and scanned models (elephant, cow, camel, man, bull, knot, couplings, a pig in 17
# pieces...). Needs apt-get (Debian or Ubuntu) and tar; writes OFF and STL files into DIR
# (default: target/cgal-meshes).
#
#   bash docs/cgal_meshes.sh && cargo bench --bench clean -- --dir target/cgal-meshes
set -euo pipefail
dir="${1:-target/cgal-meshes}"
mkdir -p "$dir"
dir="$(cd "$dir" && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
apt-get download libcgal-demo >/dev/null 2>&1 || {
  echo "apt-get download libcgal-demo failed (a Debian or Ubuntu package source is needed)" >&2
  exit 1
}
dpkg-deb -x libcgal-demo_*.deb pkg
meshes=(elephant.off cow.off mushroom.off bear.off camel.off homer.off bull.off lion-head.off
  triceratops.off femur.off elk.off knot1.off cactus.off man.off ChineseDragon-10kv.off
  mannequin-devil.off pig.stl blobby.off anchor_dense.off couplingdown.off rotor_small.off
  head.off hand.off diplodocus.off)
tar xzf pkg/usr/share/doc/libcgal-dev/data.tar.gz "${meshes[@]/#/data/meshes/}"
cp "${meshes[@]/#/data/meshes/}" "$dir"
ls -l "$dir"
