#include "sim_hal/oracle/oracle_measurement_source.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>

#include "core/frontend/iterated_update.hpp"
#include "core/geometry/projection.hpp"
#include "sim_hal/ground_truth/ground_truth.hpp"
#include "sim_hal/sim_error.hpp"

namespace vantage::sim {

namespace {

constexpr std::uint32_t kNoSite = 0xFFFFFFFFu;

}  // namespace

OracleMeasurementSource::OracleMeasurementSource(const EmbreeScene& scene, const OracleConfig& config)
    : scene_(scene), config_(config), rng_(config.seed) {
  if (!ok(config_.intrinsics.validate())) throw SimError("oracle: invalid intrinsics");
  if (!(config_.pixel_sigma_px > 0.0) || !std::isfinite(config_.pixel_sigma_px)) {
    throw SimError("oracle: pixel_sigma_px must be positive");
  }
  if (config_.site_count == 0) throw SimError("oracle: site_count must be positive");
  if (config_.max_gated_in_a_row < 0 || config_.max_gated_in_a_row > 255) {
    throw SimError("oracle: max_gated_in_a_row must be 0..255");
  }
  if (config_.unconsumed_after_gated < 0 || config_.unconsumed_after_gated > 255) {
    throw SimError("oracle: unconsumed_after_gated must be 0..255");
  }
  if (config_.ekf_iterations < 1 || config_.ekf_iterations > 20) throw SimError("oracle: ekf_iterations must be 1..20");
  if (!(config_.image_margin_px >= 0.0) || !(config_.min_cos_incidence >= 0.0 && config_.min_cos_incidence < 1.0)) {
    throw SimError("oracle: image_margin_px must be >= 0 and min_cos_incidence in [0, 1)");
  }
  ekf_.R_px2 = Eigen::Matrix2d::Identity() * (config_.pixel_sigma_px * config_.pixel_sigma_px);
  ekf_.gate_chi2 = config_.gate_chi2;
  if (!ok(ekf_.validate())) throw SimError("oracle: invalid EKF configuration (gate_chi2)");
  sites_ = sample_surface(scene_.mesh(), config_.site_count, config_.seed);
  site_spawned_.assign(sites_.size(), 0);
}

const Eigen::Vector3d* OracleMeasurementSource::true_point(PrimitiveIndex index) const {
  if (index >= site_of_primitive_.size() || site_of_primitive_[index] == kNoSite) return nullptr;
  return &sites_[site_of_primitive_[index]].position;
}

bool OracleMeasurementSource::seen(const Viewpoint& view, std::size_t site) const {
  return GroundTruth::visible_from(scene_, config_.intrinsics, view, sites_[site].position, sites_[site].normal,
                                   config_.image_margin_px, config_.min_cos_incidence);
}

void OracleMeasurementSource::spawn(std::size_t site, const Viewpoint& a, const Viewpoint& b,
                                    std::uint32_t creating_view, PrimitivePoolView& pool, UpdateReport* report) {
  const SurfaceSample& s = sites_[site];
  const double inv_r = 1.0 / (config_.pixel_sigma_px * config_.pixel_sigma_px);
  Eigen::Vector2d uv;
  Eigen::Matrix<double, 2, 3> H;
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  for (const Viewpoint* v : {&a, &b}) {
    if (!ok(project_with_jacobian(s.position, *v, config_.intrinsics, &uv, &H))) return;
    information += inv_r * H.transpose() * H;
  }
  // Two views along (nearly) the same ray leave depth unobservable: no primitive until a better pair.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(information);
  if (eig.info() != Eigen::Success || !(eig.eigenvalues()(0) > 1e-12 * eig.eigenvalues()(2))) return;
  Eigen::Matrix3d Sigma = eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
  Sigma = 0.5 * (Sigma + Sigma.transpose());
  const Eigen::LLT<Eigen::Matrix3d> llt(Sigma);
  if (llt.info() != Eigen::Success) return;
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Vector3d z(normal(rng_), normal(rng_), normal(rng_));

  Primitive p;
  p.X_world = s.position + llt.matrixL() * z;
  p.Sigma_world = Sigma;
  p.normal_world = s.normal.cast<float>();
  const double depth = (b.R_world_cam.transpose() * (s.position - b.position_world)).z();
  p.radius = static_cast<float>(0.5 * kPatchSize * depth / config_.intrinsics.fx_px);
  p.saliency_h = 1.0f;
  p.creating_view = creating_view;
  PrimitiveIndex index = kInvalidPrimitive;
  const Status status = pool.insert(p, &index);
  if (status == Status::kPoolFull) {
    if (report != nullptr) ++report->pool_full_rejections;
    return;
  }
  if (!ok(status)) return;
  if (index >= site_of_primitive_.size()) site_of_primitive_.resize(pool.capacity(), kNoSite);
  if (index >= gated_in_a_row_.size()) gated_in_a_row_.resize(pool.capacity(), 0);
  site_of_primitive_[index] = static_cast<std::uint32_t>(site);
  gated_in_a_row_[index] = 0;
  site_spawned_[site] = 1;
  ++owned_count_;
  if (report != nullptr) ++report->spawned;
}

Status OracleMeasurementSource::initialize(const GrayImageView& /*first*/, const Viewpoint& first_view,
                                           const GrayImageView& /*second*/, const Viewpoint& second_view,
                                           PrimitivePoolView& pool, UpdateReport* report) {
  Status s = first_view.validate();
  if (ok(s)) s = second_view.validate();
  if (!ok(s)) return s;
  if (pool.size() != 0) return Status::kInvalidArgument;  // the oracle builds the model from scratch
  UpdateReport local;
  pool_ = &pool;
  owned_count_ = 0;
  ekf_stats_ = EkfStats{};
  site_of_primitive_.assign(pool.capacity(), kNoSite);
  gated_in_a_row_.assign(pool.capacity(), 0);
  std::fill(site_spawned_.begin(), site_spawned_.end(), 0);
  image_index_ = 1;  // images 0 and 1 are the initial pair
  for (std::size_t i = 0; i < sites_.size(); ++i) {
    if (seen(first_view, i) && seen(second_view, i)) spawn(i, first_view, second_view, image_index_, pool, &local);
  }
  previous_view_ = second_view;
  pool.mark_modified();
  if (report != nullptr) *report = local;
  return Status::kOk;
}

Status OracleMeasurementSource::update(const GrayImageView& /*image*/, const Viewpoint& view, PrimitivePoolView& pool,
                                       UpdateReport* report) {
  const Status s = view.validate();
  if (!ok(s)) return s;
  if (pool_ != &pool || pool.size() != owned_count_) return Status::kInvalidArgument;
  UpdateReport local;
  ++image_index_;
  std::normal_distribution<double> normal(0.0, config_.pixel_sigma_px);
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (!pool.is_alive(i) || site_of_primitive_[i] == kNoSite) continue;
    const std::size_t site = site_of_primitive_[i];
    if (!seen(view, site)) continue;
    ++local.predicted_in_view;
    Eigen::Vector2d uv;
    if (!ok(project(sites_[site].position, view, config_.intrinsics, &uv))) continue;
    ++local.matched;
    const Eigen::Vector2d o = uv + Eigen::Vector2d(normal(rng_), normal(rng_));
    const Status u =
        config_.ekf_iterations > 1
            ? iterated_ekf_update(pool[i], o, view, config_.intrinsics, ekf_, config_.ekf_iterations, &ekf_stats_)
            : ekf_update(pool[i], o, view, config_.intrinsics, ekf_, &ekf_stats_);
    if (ok(u)) {
      ++local.updated;
      gated_in_a_row_[i] = 0;
      pool[i].flags =
          static_cast<std::uint16_t>(pool[i].flags & ~(primitive_flags::kLostTrack | primitive_flags::kUnconsumed));
    } else if (u == Status::kGatedOutlier) {
      ++local.gated_outliers;
      if (gated_in_a_row_[i] < 255) ++gated_in_a_row_[i];
      // Images do not consume its uncertainty: the criterion leaves it out until an update is accepted.
      if (config_.unconsumed_after_gated > 0 && gated_in_a_row_[i] >= config_.unconsumed_after_gated) {
        pool[i].flags |= primitive_flags::kUnconsumed;
      }
      // Track loss: its estimate disagrees with every recent observation; free the site to re-spawn it.
      if (config_.max_gated_in_a_row > 0 && gated_in_a_row_[i] >= config_.max_gated_in_a_row && ok(pool.erase(i))) {
        site_of_primitive_[i] = kNoSite;
        site_spawned_[site] = 0;
        gated_in_a_row_[i] = 0;
        --owned_count_;
        ++local.gated_erased;
      }
    }
  }
  if (config_.augment) {
    for (std::size_t i = 0; i < sites_.size(); ++i) {
      if (site_spawned_[i] == 0 && seen(view, i) && seen(previous_view_, i)) {
        spawn(i, previous_view_, view, image_index_, pool, &local);
      }
    }
  }
  previous_view_ = view;
  pool.mark_modified();
  if (report != nullptr) *report = local;
  return Status::kOk;
}

}  // namespace vantage::sim
