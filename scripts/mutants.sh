#!/usr/bin/env bash
# The sampled mutation-testing campaign of tests/MUTANTS.md (not run by CI).
#
# For each group of physics modules: the mutants cargo-mutants lists for the group's files,
# sampled by a deterministic round-robin shard (`--sharding round-robin --shard K/N`: mutant i of
# the group's list is in the sample when i % N == K), each built with `--profile mutants`
# (release speed, incremental) and judged by the group's guarding test binaries only
# (`--cargo-arg=--test=NAME`, given to both the build and the test phase so that only those
# binaries are built). A timeout counts as caught.
#
# Usage:
#   scripts/mutants.sh                 every group
#   scripts/mutants.sh phase bsdf      some groups
#   SHARD_K=1 scripts/mutants.sh       another sample (K < N of each group)
#   IN_PLACE=1 scripts/mutants.sh      mutate this tree in place (run it from a scratch copy:
#                                      it rewrites src/ while it runs), reusing ./target
#   MUTANTS_RE='regex' scripts/mutants.sh path   only the listed mutants matching the regex
#                                                (re-running survivors, no sharding)
#
# Results: mutants.out/<group>/mutants.out/{caught,missed,timeout,unviable}.txt
set -euo pipefail
cd "$(dirname "$0")/.."

JOBS=${JOBS:-1}
SHARD_K=${SHARD_K:-0}
OUT=${OUT:-mutants.out}

# name | files (space separated globs) | guarding test modules (CRATE::MODULE) | N (shard count) | timeout (s)
GROUPS_TABLE=(
  "phase|src/medium/phase.rs|spec::medium::phase oracles::transport|14|120"
  "path|src/path/*.rs|spec::path oracles::transport|18|120"
  "bsdf|src/bsdf/mod.rs src/bsdf/lambert.rs src/bsdf/mirror.rs src/bsdf/dielectric.rs src/bsdf/thin_dielectric.rs src/bsdf/null.rs|spec::bsdf spec::bsdf::contract spec::path|10|120"
  "path_tracer|src/integrator/path.rs|oracles::transport spec::path|8|120"
  "medium|src/medium/homogeneous.rs src/medium/heterogeneous.rs src/medium/grid.rs src/medium/procedural.rs|spec::medium::homogeneous spec::medium::heterogeneous|50|120"
  "bdpt|src/bidir/*.rs|spec::path spec::integrator::reach|30|120"
  "smc|src/integrator/smc/march.rs src/integrator/smc/cache.rs|spec::integrator::smc::cache spec::integrator::smc::march invariants::smc_unbiased|17|120"
  "mlt|src/integrator/mlt/contribution.rs src/integrator/mlt/acceptance.rs src/integrator/mlt/mutation/*.rs|spec::integrator::mlt spec::integrator::mlt::mutation|70|300"
)

want=("$@")
for row in "${GROUPS_TABLE[@]}"; do
  IFS='|' read -r name files tests shards timeout <<<"$row"
  if [ ${#want[@]} -gt 0 ] && [[ ! " ${want[*]} " =~ " ${name} " ]]; then
    continue
  fi
  args=(--profile mutants --timeout "$timeout" --build-timeout 600
        --baseline skip --output "$OUT/$name")
  for f in $files; do args+=(--file "$f"); done
  # each guard is a test crate's module: its crate is built and run, filtered to the module
  filters=()
  for t in $tests; do
    crate=${t%%::*}
    [[ " ${args[*]} " == *" --cargo-arg=--test=$crate "* ]] || args+=("--cargo-arg=--test=$crate")
    [ "$crate" = "$t" ] || filters+=("${t#*::}::")
  done
  if [ -n "${MUTANTS_RE:-}" ]; then
    args+=(--re "$MUTANTS_RE")
  else
    args+=(--sharding round-robin --shard "$SHARD_K/$shards")
  fi
  if [ -n "${IN_PLACE:-}" ]; then
    args+=(--in-place)          # one build directory: one job
  else
    args+=(-j "$JOBS")
  fi
  mkdir -p "$OUT/$name"
  echo "== $name: cargo mutants ${args[*]}"
  [ ${#filters[@]} -eq 0 ] || args+=(-- -- "${filters[@]}")
  cargo mutants "${args[@]}" || true   # exit 2 = some missed, 3 = some timed out
done
