#!/usr/bin/env bash
# Regenerates the book's figures. Each block is the exact command a chapter cites; run one block
# with `book/figures.sh NAME` (measuring, bdpt, ...) or all of them with no argument. Needs only
# the crate itself (`cargo build --release` first).
set -euo pipefail
cd "$(dirname "$0")/.."
PS="${PS:-target/release/pathspace}"
mkdir -p out
want() { [ $# -eq 0 ] || [ "$1" = "$2" ]; }
sel="${1:-}"

if want "$sel" measuring; then
  $PS reference scenes/fog-box.toml --time 600 -o out/fog-ref-600.exr
  $PS converge scenes/fog-box.toml --reference out/fog-ref-600.exr --integrators path --budget 60 --runs 3 \
      -o book/src/figures/measuring
fi

if want "$sel" bsdf; then
  mkdir -p book/src/figures/bsdf
  cargo run --release --example bsdf_lobes -- book/src/figures/bsdf/ggx-lobes.svg
fi

if want "$sel" diagrams; then
  cargo run --release --example figures -- book/src/figures/diagrams
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
  $PS reference out/cloud-dt.toml --time 100 --resolution 64x64 -o out/cloud-ref.exr
  $PS converge out/cloud-dt.toml --reference out/cloud-ref.exr --integrators path \
      --propagation equidistant,stratified,random-offset,delta-tracking --budget 5 --runs 4 --checkpoints 4 \
      --resolution 64x64 --threads 2 -o out/cloud-conv
  cp out/cloud-conv/error-vs-time.png book/src/figures/cloud/converge-error-vs-time.png
  cp out/cloud-conv/convergence.csv book/src/figures/cloud/converge.csv
fi

if want "$sel" guiding; then
  # Guided local sampling on the door slit at equal time, the preprocessing counted: map size
  # (8x4, 16x8, 32x16) and region count (64, 512, 4096) swept for surface guiding, then volume
  # and both. The reference is a 1200 s BDPT render of the same scene file (scene_hash
  # a33b702e61f3b65a); `pathspace reference scenes/door-slit-strips.toml --integrator bdpt --time 1200
  # -o out/door-ref.exr` makes one.
  d=book/src/figures/guiding
  mkdir -p "$d"
  ref="${DOOR_REF:-out/door-ref.exr}"
  $PS converge scenes/door-slit-strips.toml --reference "$ref" --budget 40 --runs 2 --checkpoints 5 --threads 2 \
      --guide-particles 100000 -o out/guide-mlt --integrators \
      mlt,mlt+guide:surface:8x4:512,mlt+guide:surface:16x8:512,mlt+guide:surface:32x16:512,mlt+guide:surface:16x8:64,mlt+guide:surface:16x8:4096,mlt+guide:volume:16x8:512,mlt+guide:both:16x8:512
  $PS converge scenes/door-slit-strips.toml --reference "$ref" --budget 40 --runs 2 --checkpoints 5 --threads 2 \
      --guide-particles 100000 -o out/guide-bdpt --integrators \
      bdpt,bdpt+guide:surface:16x8:512,bdpt+guide:volume:16x8:512,bdpt+guide:both:16x8:512
  for x in mlt bdpt; do
    cp out/guide-$x/convergence.csv "$d/door-$x.csv"
    cp out/guide-$x/error-vs-time.png "$d/door-$x-error-vs-time.png"
    cp out/guide-$x/efficiency.png "$d/door-$x-efficiency.png"
  done
fi

if want "$sel" guiding-sweep; then
  # The door-slit sweep on the fixed code (chapter "guiding"): one core per run (taskset), 60 s,
  # 3 runs per line; then Metropolis particles; then 8 more runs of the key lines in two
  # halves, one per core. The reference is a 4096-spp BDPT render:
  # `pathspace reference scenes/door-slit-strips.toml --integrator bdpt --spp 4096 --seed 77 -o out/door-ref-4096.exr`.
  d=book/src/figures/guiding
  ref="${DOOR_REF:-out/door-ref-4096.exr}"
  one() { taskset -c "$1" $PS converge scenes/door-slit-strips.toml --reference "$ref" --budget 60 --checkpoints 5 \
      --threads 1 "${@:2}"; }
  one 1 --runs 3 --guide-particles 100000 -o out/sweep --integrators \
      mlt,mlt+guide:surface:8x4:512,mlt+guide:surface:16x8:512,mlt+guide:surface:32x16:512,mlt+guide:surface:16x8:64,mlt+guide:surface:16x8:4096,mlt+guide:surface:32x16:4096,mlt+guide:volume:8x4:512,mlt+guide:volume:16x8:512,mlt+guide:volume:32x16:512,mlt+guide:volume:16x8:64,mlt+guide:volume:16x8:4096,mlt+guide:volume:32x16:4096
  one 0 --runs 3 --guide-particles 400000 --guide-sampler metropolis -o out/metro --integrators \
      mlt+guide:surface:16x8:512,mlt+guide:volume:16x8:512,mlt+guide:both:16x8:512
  one 0 --runs 4 --seed 101 --guide-particles 100000 -o out/settle-a \
      --integrators mlt,mlt+guide:volume:16x8:512,mlt+guide:surface:16x8:512 &
  one 1 --runs 4 --seed 202 --guide-particles 100000 -o out/settle-b \
      --integrators mlt,mlt+guide:volume:16x8:512,mlt+guide:surface:16x8:512
  wait
  one 0 --runs 4 --seed 303 --guide-particles 100000 -o out/settle2-0 \
      --integrators mlt,mlt+guide:volume:32x16:4096,mlt+guide:volume:16x8:4096 &
  one 1 --runs 4 --seed 404 --guide-particles 100000 -o out/settle2-1 \
      --integrators mlt,mlt+guide:volume:32x16:4096,mlt+guide:volume:16x8:4096
  wait
  cp out/settle2-0/convergence.csv "$d/door-settle2-0.csv"
  cp out/settle2-1/convergence.csv "$d/door-settle2-1.csv"
  cp out/sweep/convergence.csv "$d/door-sweep.csv"
  cp out/sweep/error-vs-time.svg "$d/door-sweep-error-vs-time.svg"
  cp out/metro/convergence.csv "$d/door-metropolis.csv"
  cp out/settle-a/convergence.csv "$d/door-settle-a.csv"
  cp out/settle-b/convergence.csv "$d/door-settle-b.csv"
fi

if want "$sel" guiding-fog; then
  # The fog box at 64x64: guided BDPT and MLT (surface, volume, both) against unguided, equal time.
  d=book/src/figures/guiding
  mkdir -p "$d"
  sed 's/resolution = \[256, 256\]/resolution = [64, 64]/' scenes/fog-box.toml > out/fog-64.toml
  [ -f out/fog-64-ref.exr ] || $PS reference out/fog-64.toml --integrator bdpt --time 240 --threads 1 -o out/fog-64-ref.exr
  $PS converge out/fog-64.toml --reference out/fog-64-ref.exr --budget 20 --runs 2 --checkpoints 5 --threads 2 \
      --guide-particles 50000 -o out/guide-fog --integrators \
      bdpt,bdpt+guide:surface:16x8:512,bdpt+guide:volume:16x8:512,bdpt+guide:both:16x8:512,mlt,mlt+guide:both:16x8:512
  cp out/guide-fog/convergence.csv "$d/fog.csv"
  cp out/guide-fog/error-vs-time.png "$d/fog-error-vs-time.png"
fi

if want "$sel" guiding-indirect; then
  # The same with maps from indirect particles only (--guide-min-depth 2): the direct light and
  # the camera's direct view are left to BDPT's connections.
  d=book/src/figures/guiding
  $PS converge out/fog-64.toml --reference out/fog-64-ref.exr --budget 20 --runs 2 --checkpoints 5 --threads 2 \
      --guide-particles 50000 --guide-min-depth 2 -o out/guide-fog-indirect --integrators \
      bdpt+guide:surface:16x8:512,bdpt+guide:volume:16x8:512,bdpt+guide:both:16x8:512,mlt+guide:both:16x8:512
  cp out/guide-fog-indirect/convergence.csv "$d/fog-indirect.csv"
  $PS converge scenes/door-slit-strips.toml --reference "${DOOR_REF:-out/door-ref.exr}" --budget 40 --runs 2 --checkpoints 5 --threads 2 \
      --guide-particles 100000 --guide-min-depth 2 -o out/guide-door-indirect --integrators \
      bdpt+guide:both:16x8:512,mlt+guide:both:16x8:512
  cp out/guide-door-indirect/convergence.csv "$d/door-indirect.csv"
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
  # the adjoint image from the Metropolis particle chains (the thesis's estimator)
  $PS converge scenes/maze.toml --reference out/maze-ref.exr --adjoint-estimator metropolis \
      --integrators bdpt+adjoint,mlt+adjoint --budget 40 --runs 2 --threads 2 -o out/maze-metro-conv
  cp out/maze-metro-conv/convergence.csv "$d/maze-convergence-metropolis-adjoint.csv"
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

if want "$sel" guiding-bidir; then
  # Guide maps from the bidirectional particle sampler (indirect particles only).
  d=book/src/figures/guiding
  $PS converge scenes/door-slit-strips.toml --reference "${DOOR_REF:-out/door-ref.exr}" --budget 40 --runs 2 --checkpoints 5 --threads 2 \
      --guide-particles 2000000 --guide-sampler bidirectional --guide-min-depth 2 -o out/guide-door-bidir --integrators \
      mlt+guide:both:16x8:512
  cp out/guide-door-bidir/convergence.csv "$d/door-bidir.csv"
fi
