// Which vector width the level-set tools' evolve sub-steps and a stroke's window search use
// (level_set.cpp). Every width does each voxel's (each dab's) float and double operations in
// the scalar definition's order, so every width gives the same field bit for bit; the switch
// lets tests compare them on one CPU.
#pragma once

namespace marzipan::evolve_width {

enum class Width {
  Widest,  // AVX2 (eight voxels, four dabs at once) where the build and the CPU have it, else SSE2
  Sse2,    // four voxels, two dabs at once
};

// Whether this build has the AVX2 kernels and this CPU (and its OS) runs them; checked once.
bool avx2Available();

// Tests only: the widest width evolve may use from now on. Not synchronised with tools that
// are running on other threads; set it between applications.
void limitWidth(Width w);

}  // namespace marzipan::evolve_width
