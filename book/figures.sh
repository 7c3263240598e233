#!/usr/bin/env bash
# Regenerates the book's figures. Each block is the exact command a chapter cites; run one block
# with `book/figures.sh NAME` (measuring, bdpt, ...) or all of them with no argument. Needs only
# the crate itself (`cargo build --release` first).
set -euo pipefail
cd "$(dirname "$0")/.."
PS=target/release/pathspace
mkdir -p out
want() { [ $# -eq 0 ] || [ "$1" = "$2" ]; }
sel="${1:-}"

if want "$sel" measuring; then
  $PS reference scenes/fog-box.toml --time 600 -o out/fog-ref-600.exr
  $PS converge scenes/fog-box.toml --reference out/fog-ref-600.exr --integrators path --budget 60 --runs 3 \
      -o book/src/figures/measuring
fi

if want "$sel" bdpt; then
  d=book/src/figures/bdpt
  mkdir -p "$d"
  $PS render scenes/volume-caustic.toml --integrator path --spp 64 --resolution 160x160 -o out/vc-path.exr --png "$d/volume-caustic-path.png"
  $PS render scenes/volume-caustic.toml --integrator bdpt --spp 64 --resolution 160x160 -o out/vc-bdpt.exr --png "$d/volume-caustic-bdpt.png" \
      --strategy-images out/vc-strategies --strategy-depth 3
  for st in s1-t2 s2-t1 s1-t4 s4-t1 s3-t2 s2-t3; do
    [ -f "out/vc-strategies/$st.png" ] && cp "out/vc-strategies/$st.png" "$d/strategy-$st.png" || true
  done
fi

if want "$sel" cloud; then
  sed 's/propagation = "random-offset"/propagation = "delta-tracking"/' scenes/cloud.toml > out/cloud-dt.toml
  $PS reference out/cloud-dt.toml --time 360 -o out/cloud-ref.exr
  $PS converge out/cloud-dt.toml --reference out/cloud-ref.exr --integrators path \
      --propagation equidistant,stratified,random-offset,delta-tracking --budget 30 --checkpoints 6 -o out/cloud-conv
  cp out/cloud-conv/error-vs-time.png book/src/figures/cloud/converge-error-vs-time.png
  cp out/cloud-conv/convergence.csv book/src/figures/cloud/converge.csv
fi
