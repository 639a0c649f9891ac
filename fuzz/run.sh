#!/usr/bin/env bash
# Runs every libFuzzer target for SECONDS each (make fuzz), one after the other, and appends
# the time spent to fuzz/hours.md so the fuzzing hours add up honestly across sessions.
#
#   fuzz/run.sh BUILD_DIR SECONDS [TARGET...]
#
# Each target fuzzes a working corpus in BUILD_DIR/corpus/TARGET, seeded from the checked-in
# corpus (fuzz/corpus/TARGET) and the regression files (fuzz/regressions/TARGET). A crash is
# copied into fuzz/regressions/TARGET/ (the normal test suite replays that directory) and the
# script exits 1 after the remaining targets have run. `make fuzz-merge` minimises the working
# corpus back into fuzz/corpus.
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:?build dir}
seconds=${2:?seconds per target}
shift 2
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_csv_pairs fuzz_csv_trajectories fuzz_model_file fuzz_cli_args fuzz_suite_file)
nice_level=${FUZZ_NICE:-19}
log=fuzz/hours.md
if [ ! -f "$log" ]; then
  cat >"$log" <<'HEAD'
# Fuzzing log

One row per `make fuzz` target run, appended by `fuzz/run.sh`. CPU seconds are user + system
time of the fuzzer process (`/usr/bin/time`), so runs at low priority on a busy machine count
only the time they actually got. Total: `make fuzz-hours`.

| date (UTC) | target | wall s | CPU s | executions | crashes |
|---|---|---|---|---|---|
HEAD
fi

status=0
for t in "${targets[@]}"; do
  bin="$build/bin/$t"
  [ -x "$bin" ] || { echo "fuzz: $bin not built (make fuzz-build)" >&2; exit 2; }
  work="$build/corpus/$t"
  art="$build/artifacts/$t"
  mkdir -p "$work" "$art" "fuzz/regressions/$t"
  cp -n fuzz/corpus/"$t"/* fuzz/regressions/"$t"/* "$work"/ 2>/dev/null || true
  out="$build/fuzz-$t.log"
  maxlen=8192
  [ "$t" = fuzz_model_file ] && maxlen=32768  # the seed models are up to 30 kB
  [ "$t" = fuzz_cli_args ] && maxlen=1024
  start=$(date -u +%s)
  stamp=$(date -u '+%Y-%m-%d %H:%M')
  dict=()
  [ -f "fuzz/$t.dict" ] && dict=(-dict="fuzz/$t.dict")
  /usr/bin/time -f '%U %S' -o "$build/time-$t.txt" \
    nice -n "$nice_level" "$bin" "${dict[@]}" -max_total_time="$seconds" -timeout="${FUZZ_TIMEOUT:-30}" -rss_limit_mb="${FUZZ_RSS_MB:-2048}" \
    -max_len="$maxlen" -print_final_stats=1 -artifact_prefix="$art/" "$work" >"$out" 2>&1
  rc=$?
  wall=$(( $(date -u +%s) - start ))
  cpu=$(awk 'NR==1 && NF==2 {printf "%.0f", $1 + $2}' "$build/time-$t.txt")
  [ -n "$cpu" ] || cpu=$(tail -1 "$build/time-$t.txt" | awk '{printf "%.0f", $1 + $2}')
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$out" | tail -1)
  crashes=0
  for f in "$art"/crash-* "$art"/leak-* "$art"/timeout-* "$art"/oom-*; do
    [ -e "$f" ] || continue
    name=$(basename "$f")
    if [ ! -e "fuzz/regressions/$t/$name" ]; then
      cp "$f" "fuzz/regressions/$t/$name"
      crashes=$((crashes + 1))
      echo "fuzz: $t: new finding kept as fuzz/regressions/$t/$name" >&2
    fi
  done
  echo "| $stamp | $t | $wall | $cpu | ${execs:-?} | $crashes |" >>"$log"
  echo "fuzz: $t: ${wall} s wall, ${cpu} CPU s, ${execs:-?} executions, exit $rc, $crashes new findings (log $out)"
  if [ $rc -ne 0 ] || [ $crashes -gt 0 ]; then status=1; tail -30 "$out" >&2; fi
done
exit $status
