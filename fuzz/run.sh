#!/usr/bin/env bash
# Fuzz every parser of untrusted input for a bounded time each (not part of CI).
#
#   fuzz/run.sh [SECONDS_PER_TARGET] [TARGET…]     (default: 600 s, every target)
#
# Needs the nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`). The first build
# compiles aepipe and its dependencies with coverage instrumentation (~30 min on 2 cores).
# Seeds come from the bad-input corpus (tests/it/corpus.rs writes each case as a seed of the
# target that reads its kind); what a target finds is kept in fuzz/corpus/<target>/, and a
# crash in fuzz/artifacts/<target>/ (replay: cargo +nightly fuzz run -s none <target> FILE).
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-600}
shift || true
seeds=$PWD/fuzz/seeds
rm -rf "$seeds"
AEPIPE_CORPUS_OUT=$seeds cargo test -q --test it corpus:: >/dev/null
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  mapfile -t targets < <(cargo +nightly fuzz list)
fi
for t in "${targets[@]}"; do
  mkdir -p "fuzz/corpus/$t" "$seeds/$t"
  echo "== $t: $secs s (seeds: $(ls "$seeds/$t" | wc -l))"
  # -s none: no sanitizer (safe Rust; a panic or an abort is the crash). rss_limit: a
  # header that makes a parser allocate gigabytes is a finding too.
  mkdir -p fuzz/logs
  if cargo +nightly fuzz run -s none -O "$t" "fuzz/corpus/$t" "$seeds/$t" -- \
    -max_total_time="$secs" -rss_limit_mb=2048 -timeout=20 -print_final_stats=1 \
    >"fuzz/logs/$t.log" 2>&1; then
    echo "   ok: $(grep -E '^stat::number_of_executed_units' "fuzz/logs/$t.log" | awk '{print $2}') runs, corpus $(ls "fuzz/corpus/$t" | wc -l) inputs"
  else
    echo "   CRASH: see fuzz/logs/$t.log and fuzz/artifacts/$t/"
    failed=1
  fi
done
exit ${failed:-0}
