#include "simd_width.hpp"

#include "protocol/cpp/cpu.hpp"

namespace marzipan::simd_width {

bool avx2Available() {
#if defined(MARZIPAN_AVX2)
  static const bool has = cpu::hasAvx2();
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
