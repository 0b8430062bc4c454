#!/usr/bin/env bash
# Submit a sharded aepipe run to Slurm: an N-task job array and a merge job that waits for
# it (afterok). Prints the two job ids.
#
#   pipelines/slurm/submit.sh PIPELINE.toml --out DIR --shards N [--partition P]
#                             [--cpus C] [--truth T] INPUT…
#
# AEPIPE names the binary (default: aepipe on PATH); it and DIR must be visible to every
# node (a shared file system). The merged run is in DIR/merged/.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
pipeline=$1
shift
out="" shards="" partition=() cpus=1 truth=()
inputs=()
while [ $# -gt 0 ]; do
  case $1 in
    --out) out=$2; shift 2 ;;
    --shards) shards=$2; shift 2 ;;
    --partition) partition=(--partition "$2"); shift 2 ;;
    --cpus) cpus=$2; shift 2 ;;
    --truth) truth=(--truth "$2"); shift 2 ;;
    *) inputs+=("$1"); shift ;;
  esac
done
if [ -z "$out" ] || [ -z "$shards" ] || [ ${#inputs[@]} -eq 0 ]; then
  echo "usage: submit.sh PIPELINE.toml --out DIR --shards N [--partition P] [--cpus C] [--truth T] INPUT…" >&2
  exit 1
fi
# Absolute paths: every job runs in DIR.
mkdir -p "$out"
out=$(realpath "$out")
pipeline=$(realpath "$pipeline")
for i in "${!inputs[@]}"; do inputs[$i]=$(realpath "${inputs[$i]}"); done
if [ ${#truth[@]} -gt 0 ]; then truth[1]=$(realpath "${truth[1]}"); fi
array=$(sbatch --parsable "${partition[@]}" --cpus-per-task="$cpus" --array=0-$((shards - 1)) \
  --export=ALL,AEPIPE_SHARDS="$shards" \
  --chdir="$out" "$here/shard.sbatch" "$pipeline" "$out" "${inputs[@]}")
array=${array%%;*}
merge=$(sbatch --parsable "${partition[@]}" --cpus-per-task="$cpus" \
  --dependency=afterok:"$array" --kill-on-invalid-dep=yes \
  --chdir="$out" "$here/merge.sbatch" "$out" "${truth[@]}")
merge=${merge%%;*}
echo "array job $array ($shards tasks), merge job $merge"
