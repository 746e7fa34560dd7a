#pragma once
// --gate-diagnostics: classifies the image front end's tracked observations against the simulator's ground
// truth, to tell why the Mahalanobis gate rejects what it rejects (core/frontend/README.md, "Consistency").
// A primitive's true point is where the ray of its seed pixel meets the surface (the seed pixel defines
// the point a primitive stands for; it is recovered by snapping X's projection into the creating view to
// the seed lattice, as tests/integration/frontend_consistency_test.cpp does). Each observation is then:
// no truth (the seed ray misses the mesh), occluded (the true point is hidden in this view: an occlusion
// misprediction), wrong (> 2 px from the true point's projection), off (1-2 px), or correct (<= 1 px:
// a gated correct match means the filter was over-confident). For correct matches it splits the
// innovation into the prior's part (truth projection vs prediction against H Sigma H^T) and the match's
// part (observation vs truth projection against B P_c B^T + R), and per primitive it splits the match
// errors, taken back into the creating image by B^-1, into the part common to all of a primitive's
// matches and the part that varies (what P_c and R model). By the updates a primitive had, it splits the
// prior NEES along the creating ray and along the true surface normal, and it measures how a match's
// error correlates with the primitive's previous one by the view change between them (core/frontend/
// EXPERIMENTS.md, "Session 38": the errors of matches from nearby views are not independent), and by how
// unevenly the warp stretches the reference patch, the error of the matches against what R and the common
// error model (FrontEndConfig::deformation_error_scale's calibration, "Session 39").
#include <cstdio>
#include <map>

#include "core/frontend/image_front_end.hpp"
#include "sim_hal/scene/embree_scene.hpp"

namespace vantage::sim {

// The seed pixel a primitive stands for: its projection uv_px into the creating view snapped to the
// front end's seed lattice (cell centres floor(stride / 2) + k stride). Its surface point is the ground
// truth of the front end's consistency figures (here and in tests/integration).
Eigen::Vector2d nearest_seed_px(const Eigen::Vector2d& uv_px, double stride_px);

// The seed pixel of primitive p: its projection into the creating view, snapped (nearest_seed_px). False,
// output untouched, when p is behind the creating camera.
bool seed_px_of(const PinholeIntrinsics& intrinsics, std::int32_t stride_px, const Primitive& p,
                const Viewpoint& creating, Eigen::Vector2d* seed_px);

// A primitive's true point: where the ray of its seed pixel (seed_px_of) meets the surface. False when p
// is behind the creating camera or the ray misses the mesh.
bool seed_true_point(const EmbreeScene& scene, const PinholeIntrinsics& intrinsics, std::int32_t stride_px,
                     const Primitive& p, const Viewpoint& creating, Eigen::Vector3d* X_true);

class GateDiagnostics final : public TrackObserver {
 public:
  // front_end: for the pose of the image a new primitive was matched against (the one before its creating
  // view), to relate a new primitive's consistency to its spawn baseline.
  GateDiagnostics(const sim::EmbreeScene& scene, const ImageFrontEnd& front_end, std::int32_t seed_stride_px)
      : scene_(scene), front_end_(front_end), intrinsics_(front_end.intrinsics()), stride_px_(seed_stride_px) {}
  void on_observation(const TrackedObservation& o) override;
  void print(std::FILE* out) const;

 private:
  struct Bucket {
    double observations = 0, no_truth = 0, occluded = 0, wrong = 0, off = 0, correct = 0;
    // Over correct matches:
    double prior_nees = 0, prior_chi2 = 0, prior_chi2_tail = 0, match_chi2 = 0, match_chi2_tail = 0, error_px = 0;
    double angle_deg = 0, young = 0;
  };
  struct PerPrimitive {
    double matches = 0;
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    Eigen::Matrix2d sum_sq = Eigen::Matrix2d::Zero();
    Eigen::Matrix2d P_c = Eigen::Matrix2d::Zero();
    Eigen::Matrix2d R = Eigen::Matrix2d::Zero();
    double angle_deg = 0;                                      // summed view change from the creating view
    Eigen::Vector2d last_error = Eigen::Vector2d::Zero();      // the last correct match's, creating image
    Eigen::Vector3d last_from_view = Eigen::Vector3d::Zero();  // its unit direction from the point to the camera
  };
  struct ByCount {
    double observations = 0, gated = 0, prior_nees = 0;
    double prior_along_ray = 0, prior_along_normal = 0, with_normal = 0;  // 1-dof parts (with_normal: hits)
  };
  // Consecutive correct matches by their view change: pairs, sum of e_k . e_k-1, sum of the mean |e|^2.
  struct Lag {
    double pairs = 0, product = 0, square = 0;
  };
  static constexpr int kLagBins = 7;  // 0-1, 1-2, 2-4, 4-8, 8-16, 16-32, 32+ degrees
  // Observations by the ratio r of the warp's singular values: how many, how many correct, and over the
  // correct ones the squared error and the modelled R and common error in this image (traces, px^2).
  struct ByDeformation {
    double observations = 0, correct = 0, error_sq = 0, R = 0, common = 0;
  };
  static constexpr int kDeformationBins = 7;  // r - 1: 0-0.05, 0.05-0.1, 0.1-0.2, 0.2-0.4, 0.4-0.7, 0.7-1, 1+
  static void print_bucket(std::FILE* out, const char* name, const Bucket& b);

  const sim::EmbreeScene& scene_;
  const ImageFrontEnd& front_end_;
  PinholeIntrinsics intrinsics_;
  std::int32_t stride_px_;
  Bucket gated_, accepted_;
  ByCount by_count_[6];           // correct matches, by observation_count / 4
  ByCount by_spawn_baseline_[6];  // first re-observations, by spawn baseline angle / 2 deg
  Lag lags_[kLagBins];
  ByDeformation by_deformation_[kDeformationBins];
  std::map<std::uint64_t, PerPrimitive> primitives_;  // by (index, creating view)
};

}  // namespace vantage::sim
