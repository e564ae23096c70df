#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The whole test suite, from a fresh Debian 12 machine: installs what is
# missing, builds, then runs
#   1. the unit and API tests under AddressSanitizer + UBSan,
#   2. the fast paths' equality tests in a Debug (-O0) build,
#   3. the libFuzzer targets (EXR reader, C API, filters, sidecars) for a
#      short fixed time, fuzz_c_api's and fuzz_filters' from seeds that
#      reach each filter's output in place,
#   4. every CTest test of the release build (unit, API, Python/ctypes,
#      headless Blender, benchmark smoke run).
# Set CRISP_FUZZ_SECONDS (default 30 per target) to change step 3.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
# Leaks inside third-party code that we cannot fix, each explained in the file.
export LSAN_OPTIONS="suppressions=$PWD/tests/fuzz/lsan.supp"

echo "== sanitizer build (ASan + UBSan)"
scripts/build.sh sanitize --target crisp_unit crisp_api_test
# The stability suite's long runs at 2000 frames here (the same code paths;
# the release stage below runs the full 20 000).
ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1 CRISP_STABILITY_FRAMES=2000 \
  ctest --test-dir build-sanitize -L 'unit|api' -j 2 --output-on-failure

echo "== debug build (-O0): fast paths equal the reference paths"
# At -O0 GCC inlines only always_inline functions: a vector helper left plain
# inline is emitted for the default target and called from an AVX2/AVX-512 row
# copy with another ABI for 32-byte vectors, which crashes or reads garbage
# lanes. Optimised builds inline it and hide the mistake (62ff056).
scripts/build.sh debug --target crisp_unit
# The tests that compare a fast path with the reference one, or run on each of kFastPathIsas. A filter
# that matches nothing passes: each pattern must match, and 23 tests in all, or renamed tests would
# empty the stage silently.
patterns=('*FastPath*' '*FastEquals*' '*FastIsBitIdentical*' '*FastEncoding*' '*ShortcutEqualsReference*'
  '*EqualsTwo*' '*RowEqualsPerPixel*' '*LuminanceOfRgbaEqualsRgb*' 'Taa.StridedTwoChannelMotionIsReadAsTwoChannels'
  'Taa.KernelsPassTheInputAlphaThrough' 'TemporalAlpha.KernelsNoteAnAlphaBelowOneOnEveryPath')
fast=$(IFS=:; echo "${patterns[*]}")
for pattern in "${patterns[@]}" "$fast"; do
  listed=$(build-debug/bin/crisp_unit --gtest_list_tests --gtest_filter="$pattern" | grep -c '^  ' || true)
  if [ "$listed" -lt 1 ] || { [ "$pattern" = "$fast" ] && [ "$listed" -lt 23 ]; }; then
    echo "crisp: the debug stage's filter '$pattern' matches $listed tests (renamed tests?)" >&2
    exit 1
  fi
done
build-debug/bin/crisp_unit --gtest_brief=1 --gtest_filter="$fast"

echo "== fuzzing (${CRISP_FUZZ_SECONDS:-30} s per target)"
scripts/build.sh fuzz --target fuzz_frame_reader fuzz_c_api fuzz_filters fuzz_sidecar crisp_cli
corpus=$(mktemp -d)
trap 'rm -rf "$corpus"' EXIT
mkdir -p "$corpus/frames" "$corpus/api" "$corpus/filters" "$corpus/sidecars"
build-fuzz/bin/crisp synth -o "$corpus/gen" --size 8x6 >/dev/null
# Seed files: a real EXR and PNG, prefixed with the byte that picks the extension.
{ printf '\x00'; cat "$corpus/gen/chart_1spp.exr"; } >"$corpus/frames/exr"
{ printf '\x01'; cat "$corpus/gen/chart_1spp.png"; } >"$corpus/frames/png"
# Inputs that crashed a reader once (tests/fuzz/regressions: the target's own input format), run first
# as seeds, so that one crashing again fails here at once rather than by chance.
cp tests/fuzz/regressions/frame_reader_* "$corpus/frames/"
# Sidecar texts of real renders (NUL between this frame's, the previous one's and the next one's;
# resolutions cut to 16x9 and 12x7 so that motion is rebuilt over the whole image on every run).
cp tests/fuzz/seeds/sidecar_* "$corpus/sidecars/"
# Seeds that reach each filter's output in place at once (a valid colour, the output on its buffer,
# executes), written by the targets' own code (fuzz_common.h, writeSeedsIfAsked): from an empty corpus
# fuzz_c_api took 58-75 s to trap a filter made unsafe in place; from these it traps fxaa without its
# staged copy, or repair's in-place path reading what it wrote, on a seed. Each seed is checked to still
# reach its state; one that does not fails here. (-runs=0: a target that ignored the variable would run
# no input and stop, rather than fuzz without end, and write no seed, which fails here too.)
for target in fuzz_c_api:api fuzz_filters:filters; do
  if ! CRISP_FUZZ_WRITE_SEEDS="$corpus/${target##*:}" ASAN_OPTIONS=detect_leaks=1:fast_unwind_on_malloc=0 \
      "build-fuzz/bin/${target%%:*}" -runs=0 2>"$corpus/seeds.log" ||
      [ -z "$(ls -A "$corpus/${target##*:}")" ]; then
    cat "$corpus/seeds.log"
    echo "crisp: ${target%%:*} did not write its seeds" >&2
    exit 1
  fi
  echo "${target%%:*}: $(ls "$corpus/${target##*:}" | wc -l) seeds"
done
for target in fuzz_frame_reader:frames fuzz_c_api:api fuzz_filters:filters fuzz_sidecar:sidecars; do
  bin=${target%%:*}
  dir=$corpus/${target##*:}
  log=$corpus/$bin.log
  # fuzz_filters' sequences need a few hundred bytes (images, parameters, frames): at libFuzzer's
  # slowly growing default length its 30 s reached 3 257 coverage points, at full length 5 072.
  extra=()
  if [ "$bin" = fuzz_filters ]; then extra=(-max_len=1024 -len_control=0); fi
  if [ "$bin" = fuzz_sidecar ]; then extra=(-max_len=8192); fi  # three sidecars of 1-1.5 KB
  # Full unwinding so leak stacks reach past libstdc++ (the suppressions match on them).
  if ! ASAN_OPTIONS=detect_leaks=1:fast_unwind_on_malloc=0 "build-fuzz/bin/$bin" \
      -max_total_time="${CRISP_FUZZ_SECONDS:-30}" -timeout=10 -rss_limit_mb=4096 -print_final_stats=1 \
      -artifact_prefix="$corpus/" "${extra[@]}" "$dir" >"$log" 2>&1; then
    grep -v '^libpng' "$log" | tail -n 60
    echo "crisp: fuzz target $bin failed (the input is printed above as base64 by libFuzzer)" >&2
    exit 1
  fi
  grep -E '^(Done|stat::number_of_executed_units)' "$log" | sed "s/^/$bin: /"
done

echo "== release build and full test suite"
scripts/build.sh release
ctest --test-dir build -j 2 --output-on-failure
