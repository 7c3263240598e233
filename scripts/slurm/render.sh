#!/usr/bin/env bash
# One command for a sharded render on a Slurm cluster: an array of N shard tasks and a merge job
# that runs after all of them succeeded.
#
#   scripts/slurm/render.sh SCENE --shards N [--out DIR] [--sbatch "OPTIONS"] [RENDER-ARGS...]
#   scripts/slurm/render.sh scenes/fog-box.toml --shards 16 --out fog --spp 4096 --seed 7
#
# prints the two job ids (array, merge); the image is DIR/merged.exr (default DIR: the scene's
# name). Extra sbatch options (partition, time limit, account) go in --sbatch "...".
# PATHSPACE names the binary the nodes run (default: pathspace on their PATH).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
usage() { sed -n '4,5p' "$0" >&2; exit 2; }
[ $# -ge 1 ] || usage
scene=$1
shift
n="" out="" extra=""
rest=()
while [ $# -gt 0 ]; do
    case $1 in
        --shards) n=$2; shift 2 ;;
        --out) out=$2; shift 2 ;;
        --sbatch) extra=$2; shift 2 ;;
        *) rest+=("$1"); shift ;;
    esac
done
[[ $n =~ ^[1-9][0-9]*$ ]] || { echo "render.sh: --shards N (a positive count) is required" >&2; exit 2; }
out=${out:-$(basename "$scene" .toml)}
mkdir -p "$out"
out=$(cd "$out" && pwd)
# shellcheck disable=SC2086 # $extra is a list of sbatch options
array=$(sbatch --parsable $extra --array="1-$n" --output="$out/shard-%a.log" \
    "$here/shard.sbatch" "$out" "$n" "$scene" "${rest[@]}")
array=${array%%;*}
# shellcheck disable=SC2086
merge=$(sbatch --parsable $extra --dependency="afterok:$array" --kill-on-invalid-dep=yes \
    --output="$out/merge.log" "$here/merge.sbatch" "$out" "$n")
echo "$array ${merge%%;*}"
