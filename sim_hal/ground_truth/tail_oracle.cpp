#include "sim_hal/ground_truth/tail_oracle.hpp"

#include <cmath>

#include "core/geometry/projection.hpp"
#include "sim_hal/ground_truth/gate_diagnostics.hpp"

namespace vantage::sim {

bool TailOracle::refuse(const TrackedObservation& o) {
  ++asked_;
  Eigen::Vector3d X_true;
  Eigen::Vector2d uv_true;
  if (!seed_true_point(scene_, intrinsics_, stride_px_, o.prior, o.creating_view, &X_true) ||
      !ok(project(X_true, o.view, intrinsics_, &uv_true))) {
    ++without_truth_;
    return false;
  }
  // A true point hidden in this view: whatever was matched, it was not that point.
  const Eigen::Vector3d to_truth = X_true - o.view.position_world;
  const bool hidden = scene_.first_hit(o.view.position_world, to_truth.normalized()) < to_truth.norm() - 0.05;
  const Eigen::Matrix2d C = o.match_covariance_px2();
  const Eigen::Vector2d e = o.observed_px - uv_true;
  const double half_nees = 0.5 * e.dot(C.ldlt().solve(e));
  // A covariance or match that is not finite refuses too: it states no precision to check.
  const bool refused = hidden || !C.allFinite() || !e.allFinite() || !(half_nees <= limit_);
  refused_ += refused ? 1u : 0u;
  return refused;
}

void TailOracle::on_observation(const TrackedObservation& o) { (void)o; }

void TailOracle::print(std::FILE* out) const {
  std::fprintf(out, "tail oracle: refused %llu of %llu tracked matches (%.1f %%), %llu without a truth\n",
               static_cast<unsigned long long>(refused_), static_cast<unsigned long long>(asked_),
               asked_ > 0 ? 100.0 * static_cast<double>(refused_) / static_cast<double>(asked_) : 0.0,
               static_cast<unsigned long long>(without_truth_));
}

}  // namespace vantage::sim
