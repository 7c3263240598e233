#!/usr/bin/env bash
# Bit-identity of a refactoring: record every shipped scene under every integrator and variant,
# the golden tests and the agreement matrix, then compare two records.
#
#   scripts/bit-identity.sh record DIR     # renders into DIR (about 5 minutes on 2 cores)
#   scripts/bit-identity.sh compare A B    # exit 1 on the first difference, listing all
#
# Images are compared pixel by pixel (`pathspace diff`, max_abs must be 0), meters and image
# means by their JSON (timings removed), refusals by their messages, and the Monte Carlo tests
# by the exact p-value of every comparison (`PATHSPACE_STATS_DUMP`), which is a function of the
# runs' means and variances.
set -uo pipefail
abs() { mkdir -p "$1" && (cd "$1" && pwd); }
cd "$(dirname "$0")/.."
BIN=target/release/pathspace

configs() {
  # name | scene | options
  for s in scenes/*.toml; do
    n=$(basename "$s" .toml)
    for i in path light bdpt mlt smc; do
      echo "$n-$i|$s|--integrator $i"
    done
  done
  echo "fog-bdpt-guide|scenes/fog-box.toml|--integrator bdpt --guide both --guide-particles 2000 --guide-regions 16"
  echo "fog-light-guide|scenes/fog-box.toml|--integrator light --guide volume --guide-particles 2000 --guide-regions 16 --guide-roulette 1"
  echo "fog-path-guide|scenes/fog-box.toml|--integrator path --guide both --guide-particles 2000 --guide-regions 16 --guide-roulette 1"
  echo "fog-mlt-guide|scenes/fog-box.toml|--integrator mlt --guide both --guide-particles 2000 --guide-regions 16 --guide-sampler metropolis"
  echo "fog-bdpt-adjoint|scenes/fog-box.toml|--integrator bdpt --adjoint-image --adjoint-resolution 8x8"
  echo "fog-light-adjoint|scenes/fog-box.toml|--integrator light --adjoint-image --adjoint-resolution 8x8 --adjoint-estimator metropolis"
  echo "fog-mlt-adjoint|scenes/fog-box.toml|--integrator mlt --adjoint-image --adjoint-resolution 8x8 --chains 8 --bootstrap 2000"
  echo "fog-mlt-weights|scenes/fog-box.toml|--integrator mlt --mutation-weights bidirectional=1,sensor=3,light=2,propagation=5"
  for v in is0_cv0 is0_cv1 is0_cv2 is1_cv0 is1_cv1 is1_cv2; do
    echo "cloud-smc-$v|scenes/cloud.toml|--integrator smc --smc-variant $v --smc-threshold 8"
    echo "fog-smc-distance-$v|scenes/fog-box.toml|--integrator smc --smc-variant $v --smc-estimator distance"
  done
  echo "fog-maxdepth|scenes/fog-box.toml|--integrator bdpt --max-depth 3"
}

record() {
  local dir
  dir=$(abs "$1")
  cargo build --release --quiet || exit 1
  configs | while IFS='|' read -r name scene opts; do
    local res="--resolution 12x12"
    grep -q '^\[camera\]' "$scene" || res=""
    # shellcheck disable=SC2086
    if $BIN render "$scene" $opts $res --spp 4 --seed 7 --threads 2 --json \
        -o "$dir/$name.exr" >"$dir/$name.json.raw" 2>"$dir/$name.err"; then
      jq -S 'del(.seconds, .paths_per_second, .outputs, .memory.peak_resident)' "$dir/$name.json.raw" >"$dir/$name.json"
    else
      # a refusal: its message is part of the behaviour
      echo "refused: $(tail -1 "$dir/$name.err")" >"$dir/$name.json"
    fi
    rm -f "$dir/$name.json.raw" "$dir/$name.png" "$dir/$name.err"
  done
  rm -f "$dir/stats.raw"
  PATHSPACE_STATS_DUMP="$dir/stats.raw" cargo test --release --quiet \
    --test oracles -- agreement:: golden:: slab:: >"$dir/tests.log" 2>&1 \
    || echo "warning: the tests failed, see $dir/tests.log"
  sort "$dir/stats.raw" >"$dir/stats.tsv" && rm -f "$dir/stats.raw"
  echo "recorded $(ls "$dir"/*.json | wc -l) renders and $(wc -l <"$dir/stats.tsv") comparisons in $dir"
}

# A record's JSON without its timings (every key starting with `seconds`, at any depth) and
# without `options`, the record of the options given (a function of the command line, added
# after the first records were made).
untimed() {
  jq -S 'del(.options) | walk(if type == "object" then with_entries(select(.key | startswith("seconds") | not)) else . end)' \
    "$1" 2>/dev/null || cat "$1"
}

compare() {
  local a=$1 b=$2 bad=0 n=0
  for j in "$a"/*.json; do
    local name
    name=$(basename "$j" .json)
    n=$((n + 1))
    if ! cmp -s <(untimed "$j") <(untimed "$b/$name.json"); then
      echo "DIFFERENT: $name (json)"; diff <(untimed "$j") <(untimed "$b/$name.json") | head -5; bad=1
    fi
    if [ -f "$a/$name.exr" ]; then
      local m
      m=$($BIN diff --json "$a/$name.exr" "$b/$name.exr" 2>&1 | jq -r .max_abs 2>/dev/null)
      if [ "$m" != "0" ] && [ "$m" != "0.0" ]; then
        echo "DIFFERENT: $name (image, max_abs $m)"; bad=1
      fi
    fi
  done
  if ! cmp -s "$a/stats.tsv" "$b/stats.tsv"; then
    echo "DIFFERENT: test statistics"; diff "$a/stats.tsv" "$b/stats.tsv" | head -10; bad=1
  fi
  echo "compared $n renders and $(wc -l <"$a/stats.tsv") test comparisons: $([ $bad = 0 ] && echo bit-identical || echo DIFFERENT)"
  return $bad
}

case "${1:-}" in
  record) record "$2" ;;
  compare) compare "$(abs "$2")" "$(abs "$3")" ;;
  *) echo "usage: $0 record DIR | compare A B" >&2; exit 2 ;;
esac
