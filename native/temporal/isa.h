// SPDX-License-Identifier: Apache-2.0
// Run-time choice between the baseline (SSE2) copy of a temporal kernel's row
// loop and a copy compiled for AVX2, as filters/repair.cpp chooses its row
// functions. Both copies are the same source, always inlined into each; the
// build has no FMA contraction (-ffp-contract=off) and no fast-math, so the
// AVX2 copy performs the same IEEE operations in the same order (VEX-encoded,
// fewer register moves) and gives the same bits; tests run both.
#pragma once

#include <atomic>

#include "core/cpu.h"

namespace crisp::temporal {

enum class Isa { Auto, Baseline };  // Auto: AVX2 when the CPU has it

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

// Process-wide choice for every temporal kernel (taa, taa-improved, phlm);
// tests set Baseline to run the SSE2 copies on an AVX2 machine.
inline std::atomic<int>& fastPathIsaStorage() {
  static std::atomic<int> isa{int(Isa::Auto)};
  return isa;
}
inline void setFastPathIsa(Isa isa) { fastPathIsaStorage().store(int(isa)); }
inline bool useAvx2() { return fastPathIsaStorage().load() == int(Isa::Auto) && cpuHasAvx2(); }
inline const char* fastPathIsaName() { return useAvx2() ? "avx2" : "sse2"; }

}  // namespace crisp::temporal
