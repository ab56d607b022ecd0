// Decimation of a surface mesh to a triangle budget or an error bound, with meshoptimizer's
// edge-collapse simplifier, edge flips that take out its long sagging chords, then its vertex
// cache and vertex fetch reordering; and the measure of how far a mesh strays from the solid's
// surface.
//
// Conventions: positions and errors in vu. Simplification only collapses edges onto existing
// vertices, so every kept vertex is a vertex of the source (with its normal and colour); triangles keep
// their counter-clockwise-from-outside orientation. Deterministic (no dependence on threads).
#pragma once

#include <cstddef>
#include <optional>

#include "marching_cubes.hpp"
#include "thread_pool.hpp"
#include "volume.hpp"

namespace marzipan {

struct DecimateOptions {
  // Stop collapsing once the mesh has at most this many triangles (>= 1).
  std::optional<std::size_t> maxTriangles;
  // Do not collapse an edge whose error, as meshoptimizer estimates it (a quadric distance),
  // would pass this many vu (> 0). The measured error (surfaceDeviation) is reported apart.
  std::optional<double> maxError;
};

struct DecimateResult {
  Mesh mesh;
  std::size_t sourceTriangles = 0;
  double maxError = 0;  // surfaceDeviation of the result, vu
};

// With neither option set the mesh only gets reordered. Throws EngineError(InvalidArgument)
// for maxTriangles 0 or maxError not finite and > 0. The budget may not be reached when no
// further collapse keeps the mesh valid (or within maxError): the result says what it reached.
DecimateResult decimateMesh(const Mesh& m, const Volume& vol, const DecimateOptions& options,
                            ThreadPool& pool = ThreadPool::serial());

// The largest |d| of the volume's trilinear interpolant at 15 points of every triangle (its
// vertices and a barycentric grid of step 1/4): how far the mesh lies from the zero set, in vu,
// where the field is a distance. Beyond the band the field is clamped, so a value at the band
// width means "at least that far".
double surfaceDeviation(const Mesh& m, const Volume& vol, ThreadPool& pool = ThreadPool::serial());

}  // namespace marzipan
