#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) with clang, ASan and UBSan into
# build/fuzz and runs each for N seconds over its corpus: the committed seeds
# (fuzz/corpus/<target>, never written to) plus a working corpus that grows
# between runs (build/fuzz/corpus/<target>). Prints the executions per target;
# exits non-zero if any target crashed, leaked, hung or ran out of memory (the
# input is saved as build/fuzz/artifacts/<target>-crash-... etc.).
#
#   bash scripts/fuzz.sh              # 20 s per target (CI)
#   bash scripts/fuzz.sh 600          # a long run
#   bash scripts/fuzz.sh 60 fuzz_core # one target
# Reproduce a saved input: build/fuzz/<target> build/fuzz/artifacts/<file>
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-20}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_exr_loader fuzz_config fuzz_core fuzz_reconfigure fuzz_gige_registers)

# camsim's own packages and libFuzzer's runtime (clang's compiler-rt); nothing
# to do when scripts/test.sh installed them.
bash scripts/install-deps.sh --native --fuzz

build=build/fuzz
CXX=clang++ cmake -S fuzz -B "$build" >/dev/null
cmake --build "$build" -j"$(nproc)" --target "${targets[@]}"

mkdir -p "$build/artifacts"
failed=()
summary=()
for t in "${targets[@]}"; do
  mkdir -p "$build/corpus/$t"
  log="$build/$t.log"
  echo "=== $t: ${seconds} s"
  status=0
  "$build/$t" -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 \
    -artifact_prefix="$build/artifacts/$t-" "$build/corpus/$t" "fuzz/corpus/$t" >"$log" 2>&1 || status=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
  cov=$(grep -E '^#[0-9]+' "$log" | tail -n 1 | grep -oE 'cov: [0-9]+' || true)
  line="$t: ${execs:-?} executions in ${seconds} s${cov:+ ($cov)}"
  if [ "$status" -ne 0 ]; then
    line="$line: FAILED (exit $status, log $log)"
    failed+=("$t")
    # (|| true: a log of nothing but progress lines leaves grep nothing to print,
    # its exit status 1, and set -e with pipefail would end the script here.)
    { grep -vE '^(#[0-9]+|INFO:|\s+NEW_FUNC)' "$log" || true; } | tail -n 60
  fi
  echo "$line"
  summary+=("$line")
done

echo "=== fuzz summary"
printf '%s\n' "${summary[@]}"
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: ${#failed[@]} target(s) failed: ${failed[*]}; inputs in $build/artifacts/"
  exit 1
fi
