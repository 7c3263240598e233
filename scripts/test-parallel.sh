#!/usr/bin/env bash
# Shards without a scheduler: GNU parallel renders 4 shards of a small fog box on this machine
# (the same command runs them on other hosts with -S), `merge` joins them, and the merge must
# equal the single run to one f32 step (`diff`'s max f32 steps; see tests/spec/render/shard.rs for why one).
#
#   scripts/test-parallel.sh          # about 5 s after the release build
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${PATHSPACE:-$PWD/target/release/pathspace}
[ -x "$BIN" ] || cargo build --release
command -v parallel >/dev/null || apt-get install -y parallel >/dev/null || (apt-get update >/dev/null && apt-get install -y parallel >/dev/null)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
args=(render scenes/fog-box.toml --resolution 32x24 --spp 64 --seed 7 --reproducible)

"$BIN" "${args[@]}" --threads 2 -o "$tmp/single.exr" >/dev/null 2>&1
parallel --will-cite -j 2 "$BIN" "${args[@]}" --threads 1 --shard {}/4 -o "$tmp/shard{}.exr" \
    '>/dev/null' '2>&1' ::: 1 2 3 4
"$BIN" merge "$tmp"/shard{1..4}.exr -o "$tmp/merged.exr"
steps=$("$BIN" diff "$tmp/merged.exr" "$tmp/single.exr" --json |
    python3 -c 'import json, sys; print(json.load(sys.stdin)["max_f32_steps"])')
if [ "$steps" -gt 1 ]; then
    echo "test-parallel: FAILED: the merge of 4 shards is $steps f32 steps from the single run" >&2
    exit 1
fi
echo "test-parallel: ok (4 shards by GNU parallel, merged: at most $steps f32 step from the single run)"
