#!/bin/sh
# pathspace's BVH against Embree 3 on the same rays (book: "Measuring a renderer: the tools").
#
#     benches/embree/run.sh [ALTERNATIONS]     # default 5
#     EMBREE_FLAGS=--robust benches/embree/run.sh   # Embree with RTC_SCENE_FLAG_ROBUST
#
# Builds benches/embree/embree_trace.c with the system compiler if Embree 3's headers are
# installed (Debian: apt-get install -y libembree-dev) and exits 0 saying so if not; writes the
# ray sets (cargo run --release --example ray_sets -- write target/ray_sets); then runs both
# sides one after the other, alternating which goes first, and prints benches/embree/table.py's
# table. Embree is used by this benchmark only, never by the renderer or its tests.
set -eu
cd "$(dirname "$0")/../.."
runs=${1:-5}
if [ ! -f /usr/include/embree3/rtcore.h ] && [ ! -f /usr/local/include/embree3/rtcore.h ]; then
    echo "Embree 3 is not installed (apt-get install -y libembree-dev): nothing measured."
    exit 0
fi
dir=target/ray_sets
mkdir -p "$dir"
${CC:-cc} -O2 -o target/embree_trace benches/embree/embree_trace.c -lembree3 -lm
cargo build --release --example ray_sets
target/release/examples/ray_sets write "$dir"
log="$dir/results.txt"
: >"$log"
ours() { target/release/examples/ray_sets trace "$dir" | sed "s/^/$1 /" >>"$log"; }
embree() { target/embree_trace "$dir" ${EMBREE_FLAGS:-} fog-box rooms100 sphere1m | sed "s/^/$1 /" >>"$log"; }
for i in $(seq "$runs"); do
    if [ $((i % 2)) -eq 1 ]; then ours "$i"; embree "$i"; else embree "$i"; ours "$i"; fi
done
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) cores; $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"
python3 benches/embree/table.py "$log"
