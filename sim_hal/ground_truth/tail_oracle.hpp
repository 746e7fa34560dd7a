#pragma once
// --tail-oracle: refuses, before the update, every tracked match of the image front end that the ground
// truth puts beyond the chi2(2) 99 % quantile (NEES/2 above 4.605 over the match's own covariance
// R + B P_c B^T), or whose true point is hidden in that view. A diagnostic, never a configuration: it measures
// what a perfect test for the matches' tail would buy a mission (core/frontend/EXPERIMENTS.md, "Session
// 23"; the integration test's Matcher::kTailOracle does the same on its scenes). The truth is the seed
// ray's surface point, as for GateDiagnostics (seed_true_point).
#include <cstdint>
#include <cstdio>

#include "core/frontend/image_front_end.hpp"
#include "sim_hal/scene/embree_scene.hpp"

namespace vantage::sim {

inline constexpr double kChi2Dof2Q99Half = 4.605170185988091;  // the chi2(2) 99 % quantile over 2

class TailOracle final : public TrackObserver {
 public:
  TailOracle(const EmbreeScene& scene, const PinholeIntrinsics& intrinsics, std::int32_t seed_stride_px,
             double refuse_above_half_nees = kChi2Dof2Q99Half)
      : scene_(scene), intrinsics_(intrinsics), stride_px_(seed_stride_px), limit_(refuse_above_half_nees) {}
  bool refuse(const TrackedObservation& o) override;
  void on_observation(const TrackedObservation& o) override;
  std::uint64_t asked() const { return asked_; }
  std::uint64_t refused() const { return refused_; }
  std::uint64_t without_truth() const { return without_truth_; }  // asked, but the seed ray misses the mesh
  // One line: refused of asked, and those without a truth (never refused).
  void print(std::FILE* out) const;

 private:
  const EmbreeScene& scene_;
  PinholeIntrinsics intrinsics_;
  std::int32_t stride_px_;
  double limit_;
  std::uint64_t asked_ = 0;
  std::uint64_t refused_ = 0;
  std::uint64_t without_truth_ = 0;
};

}  // namespace vantage::sim
