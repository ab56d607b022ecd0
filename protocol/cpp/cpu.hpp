// Whether the CPU (and its OS) runs AVX2: the run-time check of the vector forms compiled for
// AVX2 function by function, the engine's (server/engine/simd_width.hpp) and the splat codec's
// (splat_width.hpp). Header-only, so that both share it without linking each other.
#pragma once

namespace marzipan::cpu {

#if defined(__x86_64__) && defined(__GNUC__)
inline bool hasAvx2() {
  __builtin_cpu_init();  // may run before the constructors that would otherwise set it up
  return __builtin_cpu_supports("avx2") != 0;
}
#endif

}  // namespace marzipan::cpu
