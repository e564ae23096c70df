// SPDX-License-Identifier: Apache-2.0
// What the CPU we run on can do, asked once: the filters compile a copy of
// their row loops for AVX2 (target attribute, same source, no FMA contraction,
// so the same bits) and pick it at run time when this says yes.
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

}  // namespace crisp
