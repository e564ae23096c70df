// SPDX-License-Identifier: Apache-2.0
// Run-time choice between the baseline (SSE2) copy of a temporal kernel's row
// loop, a copy compiled for AVX2 and (taa's rows, taa-improved's bands) one
// for AVX-512, as filters/repair.cpp chooses its row functions. The copies are the same
// source, always inlined into each, on 4, 8 and 16 lanes (lanes.h); the build
// has no FMA contraction (-ffp-contract=off) and no fast-math, so every copy
// performs the same IEEE operations in the same order per lane and gives the
// same bits; tests run each one the CPU has.
#pragma once

#include <atomic>

#include "core/cpu.h"

namespace crisp::temporal {

// Auto: the widest copy the CPU runs; Avx2: AVX2 at most (tests and
// benchmarks of the AVX2 copy on an AVX-512 machine); Baseline: SSE2.
enum class Isa { Auto, Baseline, Avx2 };

#if defined(__GNUC__) && defined(__x86_64__)
#define CRISP_TEMPORAL_HAS_AVX2 1
#define CRISP_TEMPORAL_AVX2 __attribute__((target("avx2")))
#endif

inline bool cpuHasAvx2() {
#ifdef CRISP_TEMPORAL_HAS_AVX2
  return crisp::cpuHasAvx2();
#else
  return false;
#endif
}
// The AVX-512 copies are units of their own, compiled with AVX-512 flags
// (filters/taa_rows.h says why), not target attributes, and built only in
// optimised builds (native/CMakeLists.txt): false where they are not.
inline bool cpuHasAvx512() {
#ifdef CRISP_HAS_AVX512_ROWS
  return crisp::cpuHasAvx512();
#else
  return false;
#endif
}

// Process-wide choice for every temporal kernel (taa, taa-improved, phlm);
// tests set Baseline to run the SSE2 copies on an AVX2 machine.
inline std::atomic<int>& fastPathIsaStorage() {
  static std::atomic<int> isa{int(Isa::Auto)};
  return isa;
}
inline void setFastPathIsa(Isa isa) { fastPathIsaStorage().store(int(isa)); }
inline bool useAvx512() { return fastPathIsaStorage().load() == int(Isa::Auto) && cpuHasAvx512(); }
inline bool useAvx2() { return fastPathIsaStorage().load() != int(Isa::Baseline) && cpuHasAvx2(); }
// The copy a kernel with an AVX-512 copy runs (taa's rows, taa-improved's
// bands); phlm runs "avx2" where this says "avx512".
inline const char* fastPathIsaName() { return useAvx512() ? "avx512" : useAvx2() ? "avx2" : "sse2"; }

}  // namespace crisp::temporal
