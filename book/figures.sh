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

if want "$sel" enlightened; then
  # book chapter "Enlightened local path sampling": the maze with and without the adjoint image
  d=book/src/figures/enlightened
  mkdir -p "$d"
  $PS reference scenes/maze.toml --time 300 --threads 2 -o out/maze-ref.exr
  $PS converge scenes/maze.toml --reference out/maze-ref.exr --integrators bdpt,bdpt+adjoint,mlt,mlt+adjoint \
      --budget 40 --runs 2 --threads 2 -o out/maze-conv
  cp out/maze-conv/error-vs-time.svg "$d/maze-error-vs-time.svg"
  cp out/maze-conv/convergence.csv "$d/maze-convergence.csv"
  $PS render scenes/maze.toml --integrator bdpt --spp 32 --threads 2 -o out/maze-bdpt.exr --png "$d/maze-bdpt-32spp.png"
  $PS render scenes/maze.toml --integrator bdpt --adjoint-image --spp 32 --threads 2 -o out/maze-bdpt-adj.exr \
      --png "$d/maze-bdpt-adjoint-32spp.png" --adjoint-output out/maze-adjoint.exr
  cp out/maze-adjoint.png "$d/maze-adjoint-image.png"
  $PS reference scenes/maze-fog.toml --time 240 --threads 2 -o out/maze-fog-ref.exr
  $PS converge scenes/maze-fog.toml --reference out/maze-fog-ref.exr --integrators bdpt,bdpt+adjoint,mlt,mlt+adjoint \
      --budget 40 --runs 2 --threads 2 -o out/maze-fog-conv
  cp out/maze-fog-conv/error-vs-time.svg "$d/maze-fog-error-vs-time.svg"
  cp out/maze-fog-conv/convergence.csv "$d/maze-fog-convergence.csv"
fi
