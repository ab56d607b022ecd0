// Which vector width the splat codec's encoder (splats.cpp) takes: four points at a time in SSE2,
// or eight in AVX2, compiled for AVX2 function by function (__attribute__((target))) and chosen
// at run time where the CPU has it. Both write the bytes of the one-point encoder, lane by lane
// the same float operations in the same order; the switch lets tests compare them on one CPU.
// (The protocol links nothing of the engine: this is a switch apart from simd_width.hpp's.)
#pragma once

namespace marzipan::splat_width {

// Whether this build has the AVX2 encoder and this CPU runs it; checked once.
bool avx2Available();

// Tests only: whether the encoder may take its AVX2 form from now on (it does where
// avx2Available()). Not synchronised with encodings on other threads; set it between them.
void allowAvx2(bool allowed);

}  // namespace marzipan::splat_width
