// SPDX-License-Identifier: Apache-2.0
// What the CPU we run on can do, asked once: the filters compile a copy of
// their row loops for AVX2 (target attribute, same source, no FMA
// contraction, so the same bits), and taa's rows one for AVX-512 (a unit of
// its own built with -mavx512* flags, filters/taa_rows.h), and pick it at run
// time when this says yes.
#pragma once

namespace crisp {

inline bool cpuHasAvx2() {
#if defined(__GNUC__) && defined(__x86_64__)
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
#else
  return false;
#endif
}

// AVX-512 Foundation with the byte/word, doubleword/quadword and 128/256-bit
// vector-length extensions (every AVX-512 CPU since Skylake-SP has all four):
// the set the AVX-512 copies are compiled for.
inline bool cpuHasAvx512() {
#if defined(__GNUC__) && defined(__x86_64__)
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
           __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512vl");
  }();
  return has;
#else
  return false;
#endif
}

}  // namespace crisp
