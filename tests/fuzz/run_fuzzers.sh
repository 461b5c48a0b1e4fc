#!/usr/bin/env bash
# Runs the libFuzzer targets of a fuzz build one after the other (`make fuzz`, docs/fuzzing.md).
#
#   tests/fuzz/run_fuzzers.sh BUILD_DIR SECONDS [TARGET...]
#
# Each target fuzzes a copy of its seed corpus (BUILD_DIR/corpus/TARGET: the repository is not
# modified, and what the fuzzer adds stays there for the next run) for SECONDS, in libFuzzer's
# fork mode so that a crash, a timeout (10 s for one input) or running out of memory is kept
# and the fuzzing goes on. What failed is in BUILD_DIR/artifacts/TARGET, the log in
# BUILD_DIR/logs/TARGET.log. Prints one line per target (executions, executions per second,
# coverage edges and corpus entries as libFuzzer last reported them, new files in the
# artifacts); exits 1 when any target found something.
set -uo pipefail

if [ $# -lt 2 ]; then
  echo "usage: $0 BUILD_DIR SECONDS [TARGET...]" >&2
  exit 2
fi
build=$(cd "$1" && pwd)
seconds=$2
shift 2
here=$(cd "$(dirname "$0")" && pwd)

if [ $# -gt 0 ]; then
  targets=("$@")
else
  mapfile -t targets <"$build/fuzz-targets.txt"
fi

# The parsers refuse by throwing, and ASan's detection of stack use after return makes every
# throw scan its fake stacks: 6 times fewer executions with it (the probe codec, 2026-11-24).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_stack_use_after_return=0}
# Stack traces with function names and lines need llvm-symbolizer (Debian's llvm-16 or llvm).
if [ -z "${ASAN_SYMBOLIZER_PATH:-}" ]; then
  for s in llvm-symbolizer-16 llvm-symbolizer; do
    if command -v "$s" >/dev/null; then
      export ASAN_SYMBOLIZER_PATH=$(command -v "$s")
      break
    fi
  done
fi

failed=0
printf '%-22s %12s %8s %6s %7s %9s\n' target executions exec/s cov corpus findings
for t in "${targets[@]}"; do
  fuzzer="$build/tests/fuzz/${t}_fuzz"
  if [ ! -x "$fuzzer" ]; then
    echo "$t: no fuzzer $fuzzer (is it in tests/fuzz/targets.cmake?)" >&2
    failed=1
    continue
  fi
  corpus="$build/corpus/$t"
  artifacts="$build/artifacts/$t"
  log="$build/logs/$t.log"
  mkdir -p "$corpus" "$artifacts" "$build/logs"
  cp -r "$here/corpus/$t/." "$corpus/"
  before=$(find "$artifacts" -type f | wc -l)
  start=$(date +%s)
  "$fuzzer" "$corpus" -fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1 -timeout=10 -rss_limit_mb=2048 \
    -max_total_time="$seconds" -artifact_prefix="$artifacts/" </dev/null >"$log" 2>&1
  rc=$?
  elapsed=$(($(date +%s) - start))
  # Fork mode's progress lines: "#EXECS: cov: C ft: F corp: N exec/s: R oom/timeout/crash: ..."
  last=$(grep -E '^#[0-9]+: cov:' "$log" | tail -n 1)
  execs=$(sed -nE 's/^#([0-9]+):.*/\1/p' <<<"$last")
  cov=$(sed -nE 's/.* cov: ([0-9]+) .*/\1/p' <<<"$last")
  corp=$(sed -nE 's/.* corp: ([0-9]+) .*/\1/p' <<<"$last")
  execs=${execs:-0}
  rate=$((execs / (elapsed > 0 ? elapsed : 1)))
  found=$(($(find "$artifacts" -type f | wc -l) - before))
  printf '%-22s %12s %8s %6s %7s %9s\n' "$t" "$execs" "$rate" "${cov:-?}" "${corp:-?}" "$found"
  # A process that crashed leaves its scratch file (fuzz_support.h): remove those of dead ones.
  for f in /dev/shm/mtcal-fuzz-* "${TMPDIR:-/tmp}"/mtcal-fuzz-*; do
    pid=$(sed -nE 's/.*mtcal-fuzz-([0-9]+)-.*/\1/p' <<<"$f")
    if [ -n "$pid" ] && ! kill -0 "$pid" 2>/dev/null; then rm -f "$f"; fi
  done
  if [ "$found" -gt 0 ] || [ "$rc" -ne 0 ]; then
    failed=1
  fi
done
if [ "$failed" -ne 0 ]; then
  echo "findings: see $build/artifacts/<target> and $build/logs/<target>.log; replay one with" \
    "$build/tests/fuzz/<target>_fuzz FILE, keep it in tests/fuzz/regressions/<target>/ (docs/fuzzing.md)" >&2
  exit 1
fi
