#pragma once
// The image front end's normals against the truth, split by where each came from
// (ImageFrontEnd::normal_source): per source, how far the normals lie from the plane of the mesh points
// their seed patch shows (patch_plane_normal, what the normal oracle adopts), whether that agrees with the
// tilt variance they claim, and how consistent their primitives are. A diagnostic (the integration test's
// rows, `vantage-sim --normal-diagnostics`): which estimator's normals cost the model
// (core/frontend/EXPERIMENTS.md, "Session 25").
#include <array>
#include <cstdint>
#include <cstdio>

#include <Eigen/Core>

#include "core/frontend/image_front_end.hpp"
#include "sim_hal/scene/embree_scene.hpp"

namespace vantage::sim {

class NormalsBySource {
 public:
  static constexpr std::size_t kSources = static_cast<std::size_t>(NormalSource::kAdopted) + 1;

  // One primitive: its unit normal, its tilt variance (rad^2 per axis, > 0), the true patch plane's unit
  // normal, its position NEES against its seed's true point and its accepted updates.
  void add(NormalSource source, const Eigen::Vector3d& normal, double tilt_variance, const Eigen::Vector3d& patch_plane,
           double primitive_nees, std::uint32_t updates);

  // Every alive primitive of pool whose creating view front_end still holds and whose seed patch and seed
  // ray meet the mesh (the others are counted in skipped()).
  void add_pool(const EmbreeScene& scene, const ImageFrontEnd& front_end, const PrimitivePoolView& pool);

  std::size_t count(NormalSource source) const;
  double mean_angle_deg(NormalSource source) const;  // to the patch plane; 0 without primitives
  std::uint64_t skipped() const { return skipped_; }

  // A line per source that has primitives, each starting with prefix.
  void print(std::FILE* out, const char* prefix) const;

 private:
  struct Sums {
    double count = 0.0;
    double angle_deg = 0.0;
    double far_off = 0.0;  // more than 30 degrees off
    double claimed_sd_deg = 0.0;
    double angle2_over_variance = 0.0;  // each capped at kCappedRatio
    double primitive_nees = 0.0;
    double updates = 0.0;
  };
  // A few normals beyond the linear range (tens of degrees off a claim of a few) would hide the rest.
  static constexpr double kCappedRatio = 50.0;
  std::array<Sums, kSources> sums_{};
  std::uint64_t skipped_ = 0;
};

}  // namespace vantage::sim
