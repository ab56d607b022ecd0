#include "simd_width.hpp"

namespace marzipan::simd_width {

bool avx2Available() {
#if defined(MARZIPAN_AVX2)
  static const bool has = [] {
    __builtin_cpu_init();  // may run before the constructors that would otherwise set it up
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
#else
  return false;
#endif
}

namespace detail {
std::atomic<bool> useAvx2{avx2Available()};
}

void limitWidth(Width w) { detail::useAvx2.store(w == Width::Widest && avx2Available(), std::memory_order_relaxed); }

}  // namespace marzipan::simd_width
