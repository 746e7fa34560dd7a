#include "sim_hal/scene/surface_sampler.hpp"

#include <algorithm>
#include <cmath>
#include <random>

namespace vantage::sim {

namespace {

// Uniform double in [0, 1) from the generator directly (std::uniform_real_distribution's output is not
// specified bit-for-bit across standard libraries; this is).
double unit_uniform(std::mt19937& rng) {
  const std::uint64_t hi = rng() >> 5;  // 27 bits
  const std::uint64_t lo = rng() >> 6;  // 26 bits
  return static_cast<double>((hi << 26) | lo) * (1.0 / 9007199254740992.0);
}

}  // namespace

std::vector<SurfaceSample> sample_surface(const TriangleMesh& mesh, std::size_t count, std::uint32_t seed) {
  std::vector<SurfaceSample> samples;
  const std::size_t n = mesh.triangles.size();
  if (n == 0 || count == 0) return samples;
  std::vector<double> cumulative(n);
  double total = 0.0;
  for (std::size_t t = 0; t < n; ++t) {
    total += mesh.triangle_area(t);
    cumulative[t] = total;
  }
  if (!(total > 0.0) || !std::isfinite(total)) return samples;

  std::mt19937 rng(seed);
  samples.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const double pick = unit_uniform(rng) * total;
    std::size_t t = static_cast<std::size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), pick) -
                                              cumulative.begin());
    if (t >= n) t = n - 1;
    // Uniform point on the triangle: reflect the unit square's upper half onto the lower.
    double r1 = unit_uniform(rng);
    double r2 = unit_uniform(rng);
    if (r1 + r2 > 1.0) {
      r1 = 1.0 - r1;
      r2 = 1.0 - r2;
    }
    const auto& tri = mesh.triangles[t];
    const Eigen::Vector3d a = mesh.vertices[tri[0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices[tri[1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices[tri[2]].cast<double>();
    SurfaceSample s;
    s.position = a + r1 * (b - a) + r2 * (c - a);
    s.normal = mesh.triangle_normal(t);
    s.triangle = static_cast<std::uint32_t>(t);
    samples.push_back(s);
  }
  return samples;
}

}  // namespace vantage::sim
