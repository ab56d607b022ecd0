// Which vector width the engine's kernels use: the evolve sub-steps (level_set/kernels.hpp), a
// stroke's window search and its listing's batches of four voxels (level_set/swept_window.hpp),
// the march's per-side state bytes (fast_marching.cpp), the redistance's flags pass
// (redistance_flags.cpp), the volume's whole brick rows (volume.cpp), a brick slice's bits
// (splat_slices.hpp), the splats eight at a time (splats.cpp) and the slice compare of the bricks
// around a change (splats_around.cpp), and, outside the engine, the undo records' differences (service/history.cpp).
// Each has an SSE2 form and an AVX2 form compiled for AVX2 function by
// function (__attribute__((target))) and chosen at run time, so that the binary still runs on
// CPUs without it. Every width does each voxel's (each dab's) float and double operations in the
// scalar definition's order, so every width gives the same results bit for bit; the switch lets
// tests compare them on one CPU.
#pragma once

#include <atomic>

// Where the vector forms are compiled in: the SSE2 forms wherever the target has SSE2 (all of
// x86-64), else the scalar definitions, which a build with MARZIPAN_SCALAR_KERNELS takes
// everywhere (tests/engine_scalar: a test-only build of the kernels' files that holds them to
// the fields the vector forms are pinned to); the AVX2 forms beside the SSE2 ones on x86-64
// with GCC or Clang. Only "avx2" is enabled, never "fma": a fused multiply-add would round once
// where the definitions round twice.
#if defined(__SSE2__) && !defined(MARZIPAN_SCALAR_KERNELS)
#define MARZIPAN_SSE2 1
#endif
#if defined(MARZIPAN_SSE2) && defined(__x86_64__) && defined(__GNUC__)
#define MARZIPAN_AVX2 1
#endif

namespace marzipan::simd_width {

enum class Width {
  Widest,  // AVX2 (eight floats, four doubles at once) where the build and the CPU have it, else SSE2
  Sse2,    // four floats, two doubles at once
};

// Whether this build has the AVX2 forms and this CPU (and its OS) runs them; checked once.
bool avx2Available();

namespace detail {
extern std::atomic<bool> useAvx2;
}

// Whether the kernels take their AVX2 forms now: avx2Available(), unless a test limited the width.
inline bool useAvx2() { return detail::useAvx2.load(std::memory_order_relaxed); }

// Tests only: the widest width the kernels may use from now on. Not synchronised with tools
// running on other threads; set it between applications.
void limitWidth(Width w);

}  // namespace marzipan::simd_width
