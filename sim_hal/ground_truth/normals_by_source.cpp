#include "sim_hal/ground_truth/normals_by_source.hpp"

#include <algorithm>
#include <cmath>

#include "sim_hal/ground_truth/gate_diagnostics.hpp"
#include "sim_hal/ground_truth/normal_oracle.hpp"

namespace vantage::sim {

namespace {

constexpr double kDegreesPerRadian = 180.0 / M_PI;

constexpr std::array<const char*, NormalsBySource::kSources> kSourceNames = {
    "facing prior", "spawn fit", "refit", "photometric", "inverse warp", "adopted"};

}  // namespace

void NormalsBySource::add(NormalSource source, const Eigen::Vector3d& normal, double tilt_variance,
                          const Eigen::Vector3d& patch_plane, double primitive_nees, std::uint32_t updates) {
  Sums& s = sums_[static_cast<std::size_t>(source)];
  // Either orientation: a normal says which plane, the camera which side.
  const double angle = std::acos(std::min(1.0, std::abs(normal.dot(patch_plane))));
  s.count += 1.0;
  s.angle_deg += angle * kDegreesPerRadian;
  s.far_off += angle > 30.0 / kDegreesPerRadian ? 1.0 : 0.0;
  s.claimed_sd_deg += std::sqrt(tilt_variance) * kDegreesPerRadian;
  s.angle2_over_variance += std::min(kCappedRatio, angle * angle / tilt_variance);
  s.primitive_nees += primitive_nees;
  s.updates += updates;
}

void NormalsBySource::add_pool(const EmbreeScene& scene, const ImageFrontEnd& front_end, const PrimitivePoolView& pool) {
  const PinholeIntrinsics& k = front_end.intrinsics();
  const std::int32_t stride = front_end.config().seed_stride_px;
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (!pool.is_alive(i)) continue;
    const Primitive& p = pool[i];
    Viewpoint creating;
    Eigen::Vector2d seed;
    Eigen::Vector3d plane;
    Eigen::Vector3d truth;
    if (!ok(front_end.view_pose(p.creating_view, &creating)) || !seed_px_of(k, stride, p, creating, &seed) ||
        !patch_plane_normal(scene, k, seed, creating, &plane) ||
        !seed_true_point(scene, k, stride, p, creating, &truth)) {
      ++skipped_;
      continue;
    }
    const Eigen::Vector3d e = p.X_world - truth;
    add(front_end.normal_source(i), p.normal_world.cast<double>().normalized(), front_end.normal_tilt_variance(i), plane,
        e.dot(p.Sigma_world.ldlt().solve(e)), p.observation_count);
  }
}

std::size_t NormalsBySource::count(NormalSource source) const {
  return static_cast<std::size_t>(sums_[static_cast<std::size_t>(source)].count);
}

double NormalsBySource::mean_angle_deg(NormalSource source) const {
  const Sums& s = sums_[static_cast<std::size_t>(source)];
  return s.count > 0.0 ? s.angle_deg / s.count : 0.0;
}

void NormalsBySource::print(std::FILE* out, const char* prefix) const {
  for (std::size_t k = 0; k < kSources; ++k) {
    const Sums& s = sums_[k];
    if (s.count == 0.0) continue;
    std::fprintf(out,
                 "%snormals from %s: N=%.0f mean angle to the seed patch's plane %.1f deg, more than 30 deg off %.3f, "
                 "claimed sd %.1f deg, mean angle^2 / tilt variance %.2f (2 when consistent; each capped at %.0f), "
                 "the primitives' mean NEES %.3f, mean updates %.1f\n",
                 prefix, kSourceNames[k], s.count, s.angle_deg / s.count, s.far_off / s.count, s.claimed_sd_deg / s.count,
                 s.angle2_over_variance / s.count, kCappedRatio, s.primitive_nees / s.count, s.updates / s.count);
  }
}

}  // namespace vantage::sim
