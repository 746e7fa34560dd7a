#pragma once
// Model updates from ground truth instead of images, to compare planners apart from image matching.
// Candidate primitive sites are site_count area-weighted surface samples; each site becomes at most one
// primitive. A site is seen from a view when GroundTruth::visible_from holds (in front, inside the image
// with a patch margin, not grazing, unoccluded).
//  initialize(): a primitive for every site seen from both views, with covariance from forward
//    propagation of the two observations' pixel noise (Sigma^-1 = sum_k H_k^T R^-1 H_k, so a small
//    baseline gives a covariance elongated along depth) and position X_true + L z, z ~ N(0, I),
//    Sigma = L L^T (so the initial error is distributed as the covariance says: honest NEES).
//  update(view): for each primitive whose true point is seen from view, o = phi(X_true, view) + N(0, R),
//    then ekf_update (gated outliers and accepted updates counted); then augmentation: a primitive for
//    every site seen from this view and the previous one that has none yet, initialized as above.
//  Track loss (max_gated_in_a_row = K > 0): a primitive whose last K observations were all rejected by
//    the gate is erased (UpdateReport::gated_erased) and its site freed, so augmentation re-creates it
//    from a fresh pair. A badly initialized primitive (linearized far along its first ray) fails the gate
//    on every later view, so without this it keeps its large covariance for good.
//  Unconsumed (unconsumed_after_gated = K > 0): after K consecutive gated observations the primitive is
//    flagged primitive_flags::kUnconsumed (the criterion and the planner leave it out), until an
//    accepted update clears the flag.
// Radius: the footprint of half a patch at the creating view's depth, kPatchSize/2 * z / fx. Normal: the
// mesh normal. saliency_h = 1 (the oracle always finds its match). The image arguments are IGNORED.
// The oracle assumes it is the only writer of the pool: update() returns kInvalidArgument when the pool
// is not the one initialize() filled or its size changed behind the oracle's back.
#include <cstddef>
#include <cstdint>
#include <random>
#include <vector>

#include "core/estimation/ekf.hpp"
#include "core/frontend/measurement_source.hpp"
#include "sim_hal/scene/embree_scene.hpp"
#include "sim_hal/scene/surface_sampler.hpp"

namespace vantage::sim {

struct OracleConfig {
  PinholeIntrinsics intrinsics = PinholeIntrinsics::default_vga();
  double pixel_sigma_px = 0.5;          // R = sigma^2 I for the observations and for the EKF
  double gate_chi2 = kChiSquare2Dof95;
  // Iterations of the measurement update (core/frontend/iterated_update.hpp); 1 is the plain EKF. The
  // first updates after a small-baseline start linearize far from the truth along depth: relinearizing
  // keeps the covariance honest (EXPERIMENTS.md of core/frontend, "Measured").
  int ekf_iterations = 1;
  std::size_t site_count = 70000;       // candidate primitive sites on the surface
  double image_margin_px = kPatchSize / 2 + 1;
  double min_cos_incidence = 0.2;       // no observation at grazing angles (beyond ~78 degrees)
  bool augment = true;
  int max_gated_in_a_row = 5;           // track loss after K consecutive gated observations; 0: never
  // primitive_flags::kUnconsumed after K consecutive gated observations, cleared by an accepted update
  // (the image front end's rule, FrontEndConfig::unconsumed_after_rejections); 0: never, at most 255.
  int unconsumed_after_gated = 3;
  std::uint32_t seed = 11;
};

class OracleMeasurementSource final : public MeasurementSource {
 public:
  // Throws SimError for a bad configuration. The scene must outlive the oracle.
  OracleMeasurementSource(const EmbreeScene& scene, const OracleConfig& config);

  Status initialize(const GrayImageView& first, const Viewpoint& first_view, const GrayImageView& second,
                    const Viewpoint& second_view, PrimitivePoolView& pool, UpdateReport* report) override;
  Status update(const GrayImageView& image, const Viewpoint& view, PrimitivePoolView& pool,
                UpdateReport* report) override;
  const PinholeIntrinsics& intrinsics() const override { return config_.intrinsics; }

  // The true surface point behind primitive index (nullptr when the oracle did not create it).
  const Eigen::Vector3d* true_point(PrimitiveIndex index) const;
  const std::vector<SurfaceSample>& sites() const { return sites_; }
  // The EKF's counts and innovations since initialize(), as ImageFrontEnd::stats().ekf for the tracker.
  const EkfStats& ekf_stats() const { return ekf_stats_; }

 private:
  bool seen(const Viewpoint& view, std::size_t site) const;
  void spawn(std::size_t site, const Viewpoint& a, const Viewpoint& b, std::uint32_t creating_view,
             PrimitivePoolView& pool, UpdateReport* report);

  const EmbreeScene& scene_;
  OracleConfig config_;
  EkfConfig ekf_;
  std::vector<SurfaceSample> sites_;
  std::vector<std::uint32_t> site_of_primitive_;   // per pool index, kNoSite when none
  std::vector<std::uint8_t> site_spawned_;
  std::vector<std::uint8_t> gated_in_a_row_;       // per pool index: consecutive gated observations
  const PrimitivePoolView* pool_ = nullptr;
  std::size_t owned_count_ = 0;
  Viewpoint previous_view_;
  std::uint32_t image_index_ = 0;
  EkfStats ekf_stats_;
  std::mt19937_64 rng_;
};

}  // namespace vantage::sim
