#!/usr/bin/env bash
# End-to-end test of the Slurm scale-out on a one-node Slurm cluster on this machine.
#
#   sudo pipelines/slurm/local-cluster-test.sh [AEPIPE_BINARY] [SHARDS…]
#
# Installs Debian's slurm-wlm and munge (if absent), writes a one-node configuration in a
# temporary folder (SLURM_CONF; /etc is not touched), starts munged, slurmctld and slurmd,
# builds a 10-experiment synthetic batch, runs it once unsharded, then for each shard count
# (default: 4) submits the array + merge through the real sbatch (pipelines/slurm/submit.sh),
# waits for the merge job, and compares the merged tables, trend and SOM with the unsharded
# run byte for byte. Prints wall time, CPU time and the merge's share per shard count.
# Stops the daemons it started. Exit 0 only if every comparison holds. Needs root.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
aepipe=$(realpath "${1:-$repo/target/release/aepipe}")
shift || true
shard_counts=("$@")
[ ${#shard_counts[@]} -eq 0 ] && shard_counts=(4)
[ -x "$aepipe" ] || { echo "no aepipe binary at $aepipe (cargo build --release)" >&2; exit 1; }

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge >/dev/null
fi

work=$(mktemp -d /tmp/aepipe-slurm.XXXXXX)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  sleep 1
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done
}
trap cleanup EXIT

# munge: a key if absent, then the daemon.
if [ ! -s /etc/munge/munge.key ]; then
  mkdir -p /etc/munge
  dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
  chown munge:munge /etc/munge/munge.key 2>/dev/null || true
  chmod 400 /etc/munge/munge.key
fi
mkdir -p /run/munge /var/log/munge /var/lib/munge
chown munge:munge /run/munge /var/log/munge /var/lib/munge 2>/dev/null || true
if ! pgrep -x munged >/dev/null; then
  munged --force
  sleep 1
fi

cpus=$(nproc)
mem=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 * 8 / 10 ))
mkdir -p "$work/state" "$work/spool" "$work/log"
export SLURM_CONF=$work/slurm.conf
cat > "$SLURM_CONF" <<CONF
ClusterName=aepipe-local
SlurmctldHost=localhost
SlurmUser=root
AuthType=auth/munge
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
NodeName=localhost CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
slurmctld -D -f "$SLURM_CONF" >/dev/null 2>&1 &
pids+=($!)
sleep 2
slurmd -D -N localhost -f "$SLURM_CONF" >/dev/null 2>&1 &
pids+=($!)
for _ in $(seq 60); do
  sinfo -h -o %t 2>/dev/null | grep -qE "idle|mix" && break
  sleep 1
done
sinfo

# A 10-experiment synthetic batch (HITS per experiment, default 200) from one library.
hits=${HITS:-200}
export AEPIPE="$aepipe"
"$aepipe" reference --config "$repo/pipelines/reference-library.toml" --out "$work/lib" >/dev/null
for i in $(seq 0 9); do
  "$aepipe" synth-experiment --library "$work/lib/waveforms.parquet" --out "$work/data/exp$i" \
    --id "exp$i" --seed $((100 + i)) --hits "$hits" >/dev/null
  mv "$work/data/exp$i/truth.parquet" "$work/truth-exp$i.parquet"
done
cat > "$work/pipeline.toml" <<'TOML'
[som]
reference_library = "LIB"
[report]
gallery_per_class = 2
TOML
sed -i "s|LIB|$work/lib/waveforms.parquet|" "$work/pipeline.toml"

TIMEFORMAT="%R %U %S"
one=$( { time "$aepipe" run --config "$work/pipeline.toml" "$work/data" --out "$work/whole" --threads 1 >/dev/null ; } 2>&1 )
echo "unsharded, one process, 1 thread: wall/user/sys s = $one"

status=0
for n in "${shard_counts[@]}"; do
  out=$work/s$n
  t0=$(date +%s.%N)
  ids=$("$here/submit.sh" "$work/pipeline.toml" --out "$out" --shards "$n" "$work/data")
  echo "$n shards: $ids"
  merge=$(echo "$ids" | awk '{print $NF}')
  while squeue -h -j "$merge" 2>/dev/null | grep -q .; do sleep 0.5; done
  t1=$(date +%s.%N)
  if [ ! -f "$out/merged/report.html" ]; then
    echo "  the merge job did not finish: see $out/aepipe-*.out" >&2
    cat "$out"/aepipe-*.out >&2 || true
    status=1
    continue
  fi
  for f in features/features.parquet features/hits.parquet features/rejects.parquet \
           trend/trend.parquet som/model/model.json som/classification.parquet; do
    if ! cmp -s "$work/whole/$f" "$out/merged/$f"; then
      echo "  $f differs from the unsharded run" >&2
      status=1
    fi
  done
  cpu=$(cat "$out"/slurm-times/shard-*.time | awk 'NF==3 {u+=$2; s+=$3} END {printf "%.1f", u+s}')
  mwall=$(awk 'NF==3 {print $1}' "$out/slurm-times/merge.time")
  mcpu=$(awk 'NF==3 {printf "%.1f", $2+$3}' "$out/slurm-times/merge.time")
  printf "  %d shards: submit→merged %.1f s wall; shards %s s CPU; merge %s s wall, %s s CPU; identical: %s\n" \
    "$n" "$(awk -v a="$t0" -v b="$t1" 'BEGIN {print b - a}')" "$cpu" "$mwall" "$mcpu" "$([ $status -eq 0 ] && echo yes || echo NO)"
done

# A lost shard: the merge refuses and names it; the one task resubmitted alone, and the
# merge again, give the same result.
n=${shard_counts[-1]}
out=$work/s$n
if [ "$n" -gt 1 ]; then
  rm "$out/shards/shard-1-of-$n.json"
  if "$aepipe" merge "$out" --out "$work/refused" 2> "$work/refused.err"; then
    echo "  the merge ran with shard 1 missing" >&2
    status=1
  else
    echo "  merge with shard 1 missing refused: $(cat "$work/refused.err")"
  fi
  task=$(cd "$out" && AEPIPE_SHARDS=$n sbatch --parsable --array=1 "$here/shard.sbatch" \
    "$work/pipeline.toml" "$out" "$work/data")
  merge=$(cd "$out" && sbatch --parsable --dependency=afterok:"${task%%;*}" "$here/merge.sbatch" "$out")
  while squeue -h -j "${merge%%;*}" 2>/dev/null | grep -q .; do sleep 0.5; done
  if cmp -s "$work/whole/som/classification.parquet" "$out/merged/som/classification.parquet" &&
     [ -f "$out/shards/shard-1-of-$n.json" ]; then
    echo "  task 1 resubmitted alone (job ${task%%;*}) and merged again (job ${merge%%;*}): identical"
  else
    echo "  the resubmitted task or merge failed" >&2
    status=1
  fi
fi
echo "local Slurm test: $([ $status -eq 0 ] && echo PASSED || echo FAILED)"
exit $status
