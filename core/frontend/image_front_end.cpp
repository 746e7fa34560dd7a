#include "core/frontend/image_front_end.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "core/frontend/iterated_update.hpp"
#include "core/frontend/match_covariance.hpp"
#include "core/frontend/patch_warp.hpp"
#include "core/frontend/photometric_normal.hpp"
#include "core/frontend/surface_fit.hpp"
#include "core/frontend/triangulation.hpp"
#include "core/geometry/projection.hpp"
#include "core/image/binomial_smooth.hpp"

namespace vantage {

namespace {

constexpr std::uint8_t kCellUpdated = 1u << 0;
constexpr std::uint8_t kCellSpawned = 1u << 1;
constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
static_assert(2 * kFrontEndMaxHalfWindow + 3 <= kWindowSearchMaxBox, "the widest search box fits search_window");

UpdateReport& report_or(UpdateReport* report, UpdateReport& fallback) {
  UpdateReport& out = report != nullptr ? *report : fallback;
  out = UpdateReport{};
  return out;
}

bool finite_positive(double value) { return std::isfinite(value) && value > 0.0; }

double focal_mean(const PinholeIntrinsics& k) { return 0.5 * (k.fx_px + k.fy_px); }

// floor() for values well inside the int range, without the library call's generality.
std::int32_t floor_to_int(double value) {
  const std::int32_t truncated = static_cast<std::int32_t>(value);
  return truncated - (value < truncated ? 1 : 0);
}

// std::ceil without the library call for 0 <= value < 2^30 (the search windows' half sizes); anything
// else (NaN, huge) goes to std::ceil.
double ceil_small(double value) {
  if (!(value >= 0.0 && value < 1073741824.0)) return std::ceil(value);
  const std::int32_t truncated = static_cast<std::int32_t>(value);
  return static_cast<double>(truncated + (truncated < value ? 1 : 0));
}

// Largest standard deviation bound: sqrt(trace Sigma) >= sqrt(lambda_max).
double sigma_bound(const Eigen::Matrix3d& Sigma) { return std::sqrt(Sigma.trace()); }

// The reference patch seen through the plane-induced map A (warped when A differs from identity by more
// than min_deviation), and B: where a shift of the patch's feature shows in this image.
void reference_template(const std::array<std::uint8_t, kPatchPixels>& patch, const Eigen::Matrix2d& A,
                        double min_deviation, NccTemplate* tmpl, Eigen::Matrix2d* B) {
  if ((A - Eigen::Matrix2d::Identity()).norm() > min_deviation) {
    warp_patch_template(patch, A, tmpl);
    *B = A.inverse();
  } else {
    make_template(patch, tmpl);
    B->setIdentity();
  }
}

// A new primitive's match is made with the unwarped seed patch, i.e. on the hypothesis that the
// surface faces the reference camera; its normal is in fact unknown (tilt variance facing_tilt_variance
// per axis), and through the plane-induced map between the two views that uncertainty displaces the
// match as it does a tracked one's (warp_shift_covariance). Zero when the map cannot be formed.
Eigen::Matrix2d spawn_warp_covariance(const NccTemplate& tmpl, const Eigen::Vector3d& X_world,
                                      const Viewpoint& reference_view, const Viewpoint& other_view,
                                      const PinholeIntrinsics& intrinsics, double facing_tilt_variance) {
  Eigen::Vector2d unused;
  Eigen::Matrix<double, 2, 3> H_reference;
  Eigen::Matrix<double, 2, 3> H_other;
  Eigen::Matrix2d A;
  std::array<Eigen::Matrix2d, 2> dA;
  const Eigen::Vector3f facing = (reference_view.position_world - X_world).normalized().cast<float>();
  if (!ok(project_with_jacobian(X_world, reference_view, intrinsics, &unused, &H_reference)) ||
      !ok(project_with_jacobian(X_world, other_view, intrinsics, &unused, &H_other)) ||
      !ok(plane_affine_from_jacobians(H_reference, H_other, facing, &A, &dA))) {
    return Eigen::Matrix2d::Zero();
  }
  const Eigen::Matrix2d covariance = warp_shift_covariance(tmpl, A, dA, facing_tilt_variance);
  return covariance.allFinite() ? covariance : Eigen::Matrix2d::Zero();
}

// A prediction's facing cosine (the normal against the direction to the camera) and the point its
// occlusion test takes: the centre pulled toward the camera by occlusion_sigmas of its own uncertainty
// along the ray, so an uncertain primitive is not hidden by the surface it may lie on.
void facing_and_pulled(const Primitive& p, const Eigen::Vector3d& camera, double occlusion_sigmas, double* facing,
                       Eigen::Vector3f* pulled_world) {
  const Eigen::Vector3d to_camera = camera - p.X_world;
  const double distance = to_camera.norm();
  *facing = p.normal_world.cast<double>().dot(to_camera) / distance;
  const Eigen::Vector3d ray = -to_camera / distance;
  const double sigma_ray = std::sqrt(ray.dot(p.Sigma_world * ray));
  *pulled_world = (p.X_world - occlusion_sigmas * sigma_ray * ray).cast<float>();
}

#if defined(__x86_64__)
// facing_and_pulled for four primitives in AVX lanes (no FMA),
// each lane the scalar code's operations in the order Eigen evaluates them there (measured on random
// inputs: |to_camera|^2 as (t0^2 + t1^2) + t2^2, the facing dot as n0 t0 + (n1 t1 + n2 t2), Sigma ray's
// first two rows as (a0 b0 + a1 b1) + a2 b2 and its third as a0 b0 + (a1 b1 + a2 b2), ray . (Sigma ray) as
// (a0 b0 + a1 b1) + a2 b2): the same bits. Unused lanes repeat the first primitive.
__attribute__((target("avx2"))) void facing_and_pulled_lanes4(const Primitive* const* primitives, std::int32_t count,
                                                              const Eigen::Vector3d& camera, double occlusion_sigmas,
                                                              double* facing, Eigen::Vector3f* pulled_world) {
  using Double4 = double __attribute__((vector_size(32)));
  Double4 x, y, z, n0, n1, n2, s[3][3];
  for (std::int32_t lane = 0; lane < 4; ++lane) {
    const Primitive& p = *primitives[lane < count ? lane : 0];
    x[lane] = p.X_world.x();
    y[lane] = p.X_world.y();
    z[lane] = p.X_world.z();
    n0[lane] = static_cast<double>(p.normal_world.x());
    n1[lane] = static_cast<double>(p.normal_world.y());
    n2[lane] = static_cast<double>(p.normal_world.z());
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) s[r][c][lane] = p.Sigma_world(r, c);
    }
  }
  const Double4 t0 = camera.x() - x;
  const Double4 t1 = camera.y() - y;
  const Double4 t2 = camera.z() - z;
  const Double4 distance = __builtin_ia32_sqrtpd256((t0 * t0 + t1 * t1) + t2 * t2);
  const Double4 cosine = (n0 * t0 + (n1 * t1 + n2 * t2)) / distance;
  const Double4 ray0 = (-t0) / distance;
  const Double4 ray1 = (-t1) / distance;
  const Double4 ray2 = (-t2) / distance;
  const Double4 sr0 = (s[0][0] * ray0 + s[0][1] * ray1) + s[0][2] * ray2;
  const Double4 sr1 = (s[1][0] * ray0 + s[1][1] * ray1) + s[1][2] * ray2;
  const Double4 sr2 = s[2][0] * ray0 + (s[2][1] * ray1 + s[2][2] * ray2);
  const Double4 sigma_ray = __builtin_ia32_sqrtpd256((ray0 * sr0 + ray1 * sr1) + ray2 * sr2);
  const Double4 pull = occlusion_sigmas * sigma_ray;
  const Double4 px = x - pull * ray0;
  const Double4 py = y - pull * ray1;
  const Double4 pz = z - pull * ray2;
  for (std::int32_t lane = 0; lane < count; ++lane) {
    facing[lane] = cosine[lane];
    pulled_world[lane] = Eigen::Vector3f(static_cast<float>(px[lane]), static_cast<float>(py[lane]),
                                         static_cast<float>(pz[lane]));
  }
}
#endif

}  // namespace

// inline: two or three calls per match, a handful of operations each.
inline Eigen::Matrix2d ImageFrontEnd::measurement_R(const Eigen::Matrix2d& fit_covariance_px2) const {
  if (!config_.adaptive_R || !fit_covariance_px2.allFinite()) return config_.ekf.R_px2;
  return fit_covariance_px2 + match_floor_px2_;
}

Eigen::Matrix2d ImageFrontEnd::tilt_floor_excess_px2(const Primitive& p, const Viewpoint& view,
                                                     const Viewpoint* creating) const {
  const Eigen::Vector3d n = p.normal_world.cast<double>();
  const auto tilt_cos = [&](const Eigen::Vector3d& camera_world) {
    const Eigen::Vector3d sight = camera_world - p.X_world;
    const double length = sight.norm();
    return length > 0.0 ? std::abs(n.dot(sight)) / length : 1.0;
  };
  double cos_tilt = tilt_cos(view.position_world);
  if (creating != nullptr) cos_tilt = std::min(cos_tilt, tilt_cos(creating->position_world));
  cos_tilt = std::max(cos_tilt, kMatchFloorMinCos);
  // (sigma / cos^k)^2 - sigma^2, per axis.
  return (std::pow(cos_tilt, -2.0 * config_.match_floor_tilt_power) - 1.0) * match_floor_px2_;
}

Status FrontEndConfig::validate() const {
  const double values[] = {min_texture_stddev_gray, ncc_min, spawn_ncc_min, inverse_warp_ncc_min, uniqueness_ratio,
                           depth_min, depth_max, max_initial_sigma, warp_min_deviation, min_facing_cos,
                           min_image_stddev_gray, max_clipped_fraction, merge_max_sigma, merge_max_normal_angle_deg,
                           merge_plane_sigmas, merge_max_radius_px, occlusion_sigmas, match_sigma_floor_rad,
                           facing_normal_tilt_variance, photometric_normal_min_tilt_variance,
                           direct_fit_max_px, confirm_min_depth_information, epipolar_guard_fraction,
                           normal_refit_residual_floor, normal_spawn_residual_floor, max_match_sigma_rad,
                           view_correlated_error_scale, view_correlation_deg, deformation_error_scale,
                           deformation_error_power, spawn_back_match_max_px};
  for (double v : values) {
    if (!std::isfinite(v)) return Status::kNonFiniteInput;
  }
  const Status ekf_status = ekf.validate();
  if (!ok(ekf_status)) return ekf_status;
  if (seed_stride_px < kFrontEndMinSeedStride || seed_stride_px > 64) return Status::kInvalidArgument;
  // Every NCC threshold lies strictly between 0 and 1.
  auto ncc_threshold = [](float t) { return t > 0.0f && t < 1.0f; };
  if (!(min_texture_stddev_gray >= 0.0f) || !ncc_threshold(ncc_min) || !ncc_threshold(spawn_ncc_min) ||
      !ncc_threshold(inverse_warp_ncc_min)) {
    return Status::kInvalidArgument;
  }
  if (!(uniqueness_ratio > 0.0f && uniqueness_ratio <= 1.0f)) return Status::kInvalidArgument;
  if (ekf_iterations < 1 || ekf_iterations > 20) return Status::kInvalidArgument;
  if (max_rejected_in_a_row > 255 || unconsumed_after_rejections > 255) return Status::kInvalidArgument;
  if (subpixel_iterations < 0 || subpixel_iterations > 20) return Status::kInvalidArgument;
  if (max_search_half_window_px < 1 || max_search_half_window_px > kFrontEndMaxHalfWindow) {
    return Status::kInvalidArgument;
  }
  if (normal_fit_ring_cells < 1 || normal_fit_ring_cells > kFrontEndMaxNormalFitRing) return Status::kInvalidArgument;
  if (!(direct_fit_max_px >= 0.0)) return Status::kInvalidArgument;
  if (!(confirm_min_depth_information >= 0.0)) return Status::kInvalidArgument;
  if (!(normal_refit_residual_floor >= 0.0) || !(normal_spawn_residual_floor >= 0.0)) return Status::kInvalidArgument;
  if (!(depth_min > 0.0) || !(depth_max > depth_min)) return Status::kInvalidArgument;
  if (!(epipolar_guard_fraction >= 0.0 && epipolar_guard_fraction <= kMaxEpipolarGuardFraction)) {
    return Status::kInvalidArgument;
  }
  if (!(spawn_back_match_max_px >= 0.0)) return Status::kInvalidArgument;
  if (!finite_positive(max_initial_sigma) || !(warp_min_deviation >= 0.0)) return Status::kInvalidArgument;
  if (!(min_facing_cos > -1.0 && min_facing_cos < 1.0)) return Status::kInvalidArgument;
  if (!(min_image_stddev_gray >= 0.0f) || !(max_clipped_fraction > 0.0f && max_clipped_fraction <= 1.0f)) {
    return Status::kInvalidArgument;
  }
  if (!(occlusion_sigmas >= 0.0) || !finite_positive(match_sigma_floor_rad) || !(match_sigma_floor_rad < 0.01)) {
    return Status::kInvalidArgument;
  }
  if (!(max_match_sigma_rad >= 0.0 && max_match_sigma_rad < 0.01)) return Status::kInvalidArgument;
  if (!(view_correlated_error_scale >= 0.0) || !finite_positive(view_correlation_deg)) return Status::kInvalidArgument;
  if (!(deformation_error_scale >= 0.0) ||
      !(deformation_error_power > 0.0 && deformation_error_power <= kMaxDeformationErrorPower)) {
    return Status::kInvalidArgument;
  }
  if (!(match_floor_tilt_power >= 0.0 && match_floor_tilt_power <= kMaxMatchFloorTiltPower)) {
    return Status::kInvalidArgument;
  }
  if (!(facing_normal_tilt_variance >= 0.0) || !(photometric_normal_min_tilt_variance >= 0.0)) {
    return Status::kInvalidArgument;
  }
  if (!finite_positive(merge_max_sigma) || !finite_positive(merge_max_normal_angle_deg) ||
      !finite_positive(merge_plane_sigmas) || !finite_positive(merge_max_radius_px)) {
    return Status::kInvalidArgument;
  }
  return Status::kOk;
}

Eigen::Matrix2d FrontEndConfig::match_floor_px2(const PinholeIntrinsics& intrinsics) const {
  const double floor_x_px = match_sigma_floor_rad * intrinsics.fx_px;
  const double floor_y_px = match_sigma_floor_rad * intrinsics.fy_px;
  Eigen::Matrix2d covariance;
  covariance << floor_x_px * floor_x_px, 0.0, 0.0, floor_y_px * floor_y_px;
  return covariance;
}

Status ImageFrontEnd::configure(const PinholeIntrinsics& intrinsics, const FrontEndConfig& config) {
  configured_ = false;
  initialized_ = false;
  const Status k_status = intrinsics.validate();
  if (!ok(k_status)) return k_status;
  if (intrinsics.width_px > kFrontEndMaxWidth || intrinsics.height_px > kFrontEndMaxHeight ||
      intrinsics.width_px < kPatchSize + 2 || intrinsics.height_px < kPatchSize + 2) {
    return Status::kInvalidArgument;
  }
  const Status c_status = config.validate();
  if (!ok(c_status)) return c_status;
  intrinsics_ = intrinsics;
  config_ = config;
  match_floor_px2_ = config.match_floor_px2(intrinsics);
  const double max_match_sigma_px = config.max_match_sigma_rad * focal_mean(intrinsics);
  max_match_variance_px2_ = max_match_sigma_px * max_match_sigma_px;
  stats_ = FrontEndStats{};
  next_view_index_ = 0;
  cells_x_ = intrinsics.width_px / config.seed_stride_px;
  cells_y_ = intrinsics.height_px / config.seed_stride_px;
  configured_ = true;
  return Status::kOk;
}

Status ImageFrontEnd::view_pose(std::uint32_t view_index, Viewpoint* pose) const {
  if (view_index >= next_view_index_ || next_view_index_ - view_index > kFrontEndMaxViews) return Status::kNotFound;
  *pose = view_poses_[view_index % kFrontEndMaxViews];
  return Status::kOk;
}

Status ImageFrontEnd::check_frame(const GrayImageView& image, const Viewpoint& view) {
  if (!ok(image.validate()) || image.width_px != intrinsics_.width_px || image.height_px != intrinsics_.height_px) {
    ++stats_.rejected_invalid_image;
    return Status::kInvalidImage;
  }
  const Status pose_status = view.validate();
  if (!ok(pose_status)) {
    ++stats_.rejected_bad_pose;
    return pose_status;
  }
  // Content: a sparse sample is enough to tell a constant, black or saturated frame.
  double sum = 0.0;
  double sum_sq = 0.0;
  std::uint32_t clipped = 0;
  std::uint32_t count = 0;
  for (std::int32_t y = 0; y < image.height_px; y += 4) {
    for (std::int32_t x = 0; x < image.width_px; x += 4) {
      const std::uint8_t value = image.at(x, y);
      sum += value;
      sum_sq += static_cast<double>(value) * value;
      clipped += (value == 0 || value == 255) ? 1u : 0u;
      ++count;
    }
  }
  const double mean = sum / count;
  const double variance = sum_sq / count - mean * mean;
  if (!(variance >= static_cast<double>(config_.min_image_stddev_gray) * config_.min_image_stddev_gray) ||
      static_cast<double>(clipped) > static_cast<double>(config_.max_clipped_fraction) * count) {
    ++stats_.rejected_unusable_image;
    return Status::kUnusableImage;
  }
  return Status::kOk;
}

void ImageFrontEnd::reset_cells() {
  const std::size_t cells = static_cast<std::size_t>(cells_x_) * cells_y_;
  for (std::size_t i = 0; i < cells; ++i) {
    cell_primitive_[i] = kInvalidPrimitive;
    cell_depth_[i] = 0.0f;
    cell_covered_[i] = 0;
    cell_state_[i] = 0;
  }
}

std::size_t ImageFrontEnd::cell_of(const Eigen::Vector2d& uv_px) const {
  // uv_px lies inside the image (track()'s predictions): floor_to_int is floor here, without the libm call.
  std::int32_t cx = floor_to_int((uv_px.x() + 0.5) / config_.seed_stride_px);
  std::int32_t cy = floor_to_int((uv_px.y() + 0.5) / config_.seed_stride_px);
  cx = cx < 0 ? 0 : (cx >= cells_x_ ? cells_x_ - 1 : cx);
  cy = cy < 0 ? 0 : (cy >= cells_y_ ? cells_y_ - 1 : cy);
  return static_cast<std::size_t>(cy) * cells_x_ + cx;
}

static_assert(kFrontEndMaxWidth <= kBinomialSmoothMaxWidth, "every frame the front end takes can be smoothed");

GrayImageView ImageFrontEnd::working_frame(const GrayImageView& image,
                                           GrayImageBuffer<kFrontEndMaxWidth, kFrontEndMaxHeight>* into) const {
  if (!config_.presmooth) return image;
  // Neither can fail: check_frame() took the intrinsics' size, which configure() bounded by the capacity.
  (void)into->resize(image.width_px, image.height_px);
  (void)binomial_smooth3(image, into->view());
  return into->view().as_const();
}

void ImageFrontEnd::remember(const GrayImageView& image, const Viewpoint& view) {
  previous_view_ = view;
  view_poses_[next_view_index_ % kFrontEndMaxViews] = view;
  ++next_view_index_;
  if (image.pixels == previous_image_.view().pixels) return;  // initialize() smoothed it into place
  // resize cannot fail: configure() bounded the size by the buffer's capacity.
  if (!ok(previous_image_.resize(image.width_px, image.height_px))) return;
  const MutableGrayImageView copy = previous_image_.view();
  for (std::int32_t y = 0; y < image.height_px; ++y) {
    const std::uint8_t* src = image.pixels + static_cast<std::ptrdiff_t>(y) * image.stride_bytes;
    std::uint8_t* dst = copy.pixels + static_cast<std::ptrdiff_t>(y) * copy.stride_bytes;
    for (std::int32_t x = 0; x < image.width_px; ++x) dst[x] = src[x];
  }
}

Status ImageFrontEnd::initialize(const GrayImageView& first, const Viewpoint& first_view, const GrayImageView& second,
                                 const Viewpoint& second_view, PrimitivePoolView& pool, UpdateReport* report) {
  UpdateReport fallback;
  UpdateReport& out = report_or(report, fallback);
  if (!configured_) {
    ++stats_.rejected_not_initialized;
    return Status::kNotInitialized;
  }
  Status status = check_frame(first, first_view);
  if (!ok(status)) return status;
  status = check_frame(second, second_view);
  if (!ok(status)) return status;
  if ((first_view.position_world - second_view.position_world).norm() <= 1e-9) {
    ++stats_.rejected_bad_pose;  // no baseline: nothing to triangulate
    return Status::kInvalidArgument;
  }
  initialized_ = false;
  next_view_index_ = 0;
  const std::uint32_t first_index = next_view_index_;
  view_poses_[0] = first_view;
  next_view_index_ = 1;
  forget_primitive_tables();
  reset_cells();
  const GrayImageView first_frame = working_frame(first, &smoothed_image_);
  const GrayImageView second_frame = working_frame(second, &previous_image_);
  spawn(first_frame, first_view, first_index, second_frame, second_view, first_index + 1, pool, out);
  remember(second_frame, second_view);
  initialized_ = true;
  ++stats_.frames_accepted;
  if (out.spawned > 0) pool.mark_modified();
  return Status::kOk;
}

void ImageFrontEnd::forget_primitive_tables() {
  // Primitives someone else put in the pool have a normal nobody fitted (the facing-camera prior), no
  // recorded patch noise and no rejection history.
  normal_tilt_variance_.fill(static_cast<float>(config_.facing_normal_tilt_variance));
  normal_source_.fill(NormalSource::kFacingPrior);
  for (TemplateNoise& noise : template_noise_) {
    noise.cross_covariance.setZero();
    noise.covariance_px2.setZero();
    noise.correlated_cross_covariance.setZero();
    noise.correlated_view = 0;
    noise.correlated_trace = 0.0f;
  }
  rejected_in_a_row_.fill(0);
}

Status ImageFrontEnd::update(const GrayImageView& image, const Viewpoint& view, PrimitivePoolView& pool,
                             UpdateReport* report) {
  UpdateReport fallback;
  UpdateReport& out = report_or(report, fallback);
  if (!configured_ || !initialized_) {
    ++stats_.rejected_not_initialized;
    return Status::kNotInitialized;
  }
  const Status status = check_frame(image, view);
  if (!ok(status)) return status;
  const GrayImageView frame = working_frame(image, &smoothed_image_);
  reset_cells();
  track(frame, view, pool, out);
  refit_normals(view, pool);
  if (config_.merge_enabled) merge_neighbours(view, pool, out);
  // A new view from (almost) the previous position has no baseline to triangulate new surface from.
  if ((view.position_world - previous_view_.position_world).norm() > 1e-6 * (1.0 + view.position_world.norm())) {
    const std::uint32_t index = next_view_index_;
    spawn(frame, view, index, previous_image_.view().as_const(), previous_view_, index - 1, pool, out);
  }
  remember(frame, view);
  ++stats_.frames_accepted;
  if (out.updated > 0 || out.spawned > 0 || out.merged > 0) pool.mark_modified();
  return Status::kOk;
}

void ImageFrontEnd::track(const GrayImageView& image, const Viewpoint& view, PrimitivePoolView& pool,
                          UpdateReport& report) {
  const double focal = focal_mean(intrinsics_);
  const double stride = config_.seed_stride_px;
  MatchConfig match{config_.ncc_min, config_.uniqueness_ratio, config_.subpixel_iterations};
  match.require_converged_fit = config_.require_converged_fit;
  const Span<float> scratch(window_scratch_.data(), window_scratch_.size());
  const Eigen::Matrix3d R_cam_world = view.R_world_cam.transpose();
  tracking_view_ = view;
  // Occluders first: every primitive in front of the camera, pushed back by its uncertainty.
  const double k_sigma = config_.occlusion_sigmas;
  const bool occlusion = config_.occlusion_enabled && ok(depth_buffer_.configure(view, intrinsics_));
  if (occlusion) {
    // Four discs per splat_batch call (the same pixels and values as splat() one by one).
    DiscBatch discs;
    for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
      if (!pool.is_alive(i)) continue;
      const Primitive& p = pool[i];
      const Eigen::Vector3d ray = (p.X_world - view.position_world).normalized();
      const double sigma_ray = std::sqrt(ray.dot(p.Sigma_world * ray));
      discs.push((p.X_world + k_sigma * sigma_ray * ray).cast<float>(), p.normal_world, p.radius);
      if (discs.full()) (void)depth_buffer_.splat_batch(discs);
    }
    (void)depth_buffer_.splat_batch(discs);
  }
  NccTemplate tmpl;
  // The next few alive primitives' predictions, made ahead so their occlusion tests share one lane batch
  // (nothing in this loop changes another primitive, so they are what the loop would compute).
  PredictionBatch ahead;
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (!pool.is_alive(i)) continue;
    Primitive& p = pool[i];
    if (ahead.next >= ahead.count || ahead.index[ahead.next] != i) predict_batch(i, view, occlusion, pool, &ahead);
    const std::int32_t slot = ahead.next++;
    // References into `ahead`: it is refilled only at a later primitive.
    const Eigen::Vector2d& predicted = ahead.predicted[slot];
    const Eigen::Matrix<double, 2, 3>& H = ahead.H[slot];
    if (!ahead.in_view[slot]) {
      // Not even seen in the first image after its creation: nothing confirms it (confirm_spawns).
      if (p.observation_count == 0 && p.creating_view < next_view_index_) {
        flush_updates(view, pool, report);  // erasures in the unbatched order: the pool reuses freed slots by it
        drop_unconfirmed(i, kNoCell, pool);
      }
      continue;
    }
    ++report.predicted_in_view;
    ++stats_.tracks_predicted;

    // Coverage: the footprint's disc in this image, and the nearest primitive per cell.
    const double depth = (R_cam_world * (p.X_world - view.position_world)).z();
    const double radius_px = p.radius * focal / depth;
    const std::size_t centre_cell = cell_of(predicted);
    for (int held = 0; held < pending_count_; ++held) {
      if (pending_updates_[held].centre_cell != centre_cell) continue;
      flush_updates(view, pool, report);  // its bookkeeping may free or mark this cell: first, as unbatched
      break;
    }
    if (cell_primitive_[centre_cell] == kInvalidPrimitive || depth < cell_depth_[centre_cell]) {
      cell_primitive_[centre_cell] = i;
      cell_depth_[centre_cell] = static_cast<float>(depth);
    }
    const double reach = radius_px + 0.5 * stride;
    // predicted is inside the image (predicted_in_view), reach a few cells: floor_to_int is exact here.
    const double inv_stride = 1.0 / stride;
    const std::int32_t cx0 = floor_to_int((predicted.x() - reach) * inv_stride);
    const std::int32_t cx1 = floor_to_int((predicted.x() + reach) * inv_stride);
    const std::int32_t cy0 = floor_to_int((predicted.y() - reach) * inv_stride);
    const std::int32_t cy1 = floor_to_int((predicted.y() + reach) * inv_stride);
    const double reach2 = reach * reach;
    // Bounds and the prediction in locals: the byte stores below may alias any member, so the compiler
    // would reload them after each one.
    const std::int32_t cx_begin = cx0 < 0 ? 0 : cx0;
    const std::int32_t cx_end = cx1 < cells_x_ ? cx1 + 1 : cells_x_;
    const std::int32_t cy_end = cy1 < cells_y_ ? cy1 + 1 : cells_y_;
    const double px = predicted.x();
    const double py = predicted.y();
    std::uint8_t* const covered = cell_covered_.data();
    const std::size_t row_cells = static_cast<std::size_t>(cells_x_);
    for (std::int32_t cy = cy0 < 0 ? 0 : cy0; cy < cy_end; ++cy) {
      const double dy = (cy + 0.5) * stride - 0.5 - py;
      std::uint8_t* const row = covered + static_cast<std::size_t>(cy) * row_cells;
      for (std::int32_t cx = cx_begin; cx < cx_end; ++cx) {
        const double dx = (cx + 0.5) * stride - 0.5 - px;
        if (dx * dx + dy * dy <= reach2) row[cx] = 1;
      }
    }

    // The reference patch, warped by the primitive's plane when the creating view saw it differently
    // (tmpl, declared before the loop: both template makers write every field).
    Viewpoint creating;
    Eigen::Matrix2d A = Eigen::Matrix2d::Identity();
    std::array<Eigen::Matrix2d, 2> dA;
    Eigen::Matrix<double, 2, 3> H_creating;
    const bool have_creating = ok(view_pose(p.creating_view, &creating));
    if (have_creating) {
      // The map and its tilt derivatives from the creating view's Jacobian and this view's (H), made in
      // the prediction batch.
      if (!ok(ahead.creating_status[slot]) || !ok(ahead.plane_status[slot])) {
        ++report.failed_matches;  // seen edge-on: nothing to correlate
        ++stats_.track_failures.edge_on;
        flush_updates(view, pool, report);  // a rejection may erase (see above)
        reject_observation(i, centre_cell, pool, report);
        continue;
      }
      H_creating = ahead.H_creating[slot];
      A = ahead.A[slot];
      dA = ahead.dA[slot];
    }
    // The match and its measurement model, filled in as they are made.
    MatchedObservation matched;
    matched.centre_cell = centre_cell;
    matched.have_creating = have_creating;
    matched.predicted_px = predicted;
    matched.H = H;
    reference_template(p.patch, A, config_.warp_min_deviation, &tmpl, &matched.B);

    MatchOutcome outcome = MatchOutcome::kNoRoom;
    matched.observed_px = predicted;
    Eigen::Matrix2d fit_covariance = Eigen::Matrix2d::Zero();
    bool beyond_search = false;
    // Fewer than half the template's pixels inside the reference patch: the window is not searched.
    const bool template_usable = tmpl.valid_count >= kPatchPixels / 2;
    if (template_usable) {
      const Eigen::Matrix2d prior = H * p.Sigma_world * H.transpose();
      const Eigen::Matrix2d S = prior + config_.ekf.R_px2;
      WindowQuery query;
      query.predicted_px = predicted;
      query.S_inv = S.inverse();
      query.gate_chi2 = 9.0;  // the 3-sigma ellipse
      const double half_w = ceil_small(3.0 * std::sqrt(S(0, 0)));
      const double half_h = ceil_small(3.0 * std::sqrt(S(1, 1)));
      const double cap = config_.max_search_half_window_px;
      beyond_search = half_w > cap || half_h > cap;
      query.half_width_px = static_cast<std::int32_t>(half_w < 1.0 ? 1.0 : (half_w > cap ? cap : half_w));
      query.half_height_px = static_cast<std::int32_t>(half_h < 1.0 ? 1.0 : (half_h > cap ? cap : half_h));
      float best = 0.0f;
      // A prior known to within about a pixel: the fit from the prediction, the window searched only if it
      // fails (WindowQuery::direct_fit). The prior's largest 3-sigma semi-axis, without the fixed R that
      // sizes the window.
      const double half_trace = 0.5 * prior.trace();
      const double largest = half_trace + std::sqrt(std::max(0.0, half_trace * half_trace - prior.determinant()));
      query.direct_fit = 9.0 * largest <= config_.direct_fit_max_px * config_.direct_fit_max_px;
      outcome = search_window(image, tmpl, query, match, scratch, &matched.observed_px, &best, &fit_covariance);
    }
    // A template the warp masked: the image warped instead (inverse_warp_masked).
    matched.inverse_warped = !template_usable && config_.inverse_warp_masked && have_creating &&
                             match_by_inverse_warp(i, image, creating, view, predicted, A, pool, &matched.observed_px,
                                                   &fit_covariance);
    const bool inverse_warped = matched.inverse_warped;
    if (inverse_warped) {
      outcome = MatchOutcome::kMatched;
      ++stats_.tracks_inverse_warped;
    }
    if (outcome != MatchOutcome::kMatched) {
      ++report.failed_matches;
      count_track_failure(template_usable, outcome);
      flush_updates(view, pool, report);  // a rejection may erase (see above)
      reject_observation(i, centre_cell, pool, report, beyond_search);
      continue;
    }
    // What the normal's uncertainty does to the match through the warp (FrontEndConfig); only a match uses it.
    Eigen::Matrix2d& warp_covariance = matched.warp_covariance_px2;
    // (An inverse-warp match's covariance holds the normal's share already.)
    if (config_.model_normal_uncertainty && have_creating && !inverse_warped) {
      warp_covariance = warp_shift_covariance(tmpl, A, dA, normal_tilt_variance(i));
    }
    // A poorly known normal that matters here (its warp covariance outweighs the match's own): estimate it
    // from this view's appearance, then match with its warp.
    if (config_.photometric_normal && have_creating && !inverse_warped &&
        normal_tilt_variance(i) > config_.photometric_normal_min_tilt_variance &&
        warp_covariance.trace() > measurement_R(fit_covariance).trace()) {
      (void)refine_normal_photometric(i, image, creating, view, H_creating, H, pool, &tmpl, &matched.B,
                                      &warp_covariance, &matched.observed_px, &fit_covariance);
    }
    if (!inverse_warped) correlate_fit_covariance(image, tmpl, matched.observed_px, &fit_covariance);
    EkfConfig& ekf = matched.ekf;
    ekf = config_.ekf;
    CommonObservationError& common = matched.common;
    // Only a primitive whose patch noise was recorded at its creation splits the fit covariance.
    const bool template_noise = config_.model_template_noise && config_.adaptive_R && i < kFrontEndMaxPrimitives &&
                                fit_covariance.allFinite() && template_noise_[i].covariance_px2.trace() > 0.0f;
    Eigen::Matrix2d deformation = Eigen::Matrix2d::Zero();
    if (template_noise) {
      deformation = deformation_error_px2(matched.B);
      common_error_for_match(i, pool[i], view, deformation, &common);
      common.B = matched.B;
      ekf.R_px2 = measurement_R(0.5 * fit_covariance) + warp_covariance;
    } else {
      ekf.R_px2 = measurement_R(fit_covariance) + warp_covariance;
    }
    if (config_.match_floor_tilt_power > 0.0 && config_.adaptive_R && fit_covariance.allFinite()) {
      ekf.R_px2 += tilt_floor_excess_px2(pool[i], view, have_creating ? &creating : nullptr);
    }
    // Not used, and not held against the primitive either: its normal, not its point, is in doubt (a
    // rejection would erase an unconfirmed new primitive and count toward track loss).
    if (match_too_uncertain(ekf.R_px2, common, deformation)) {
      ++report.failed_matches;
      ++stats_.track_failures.too_uncertain;
      continue;
    }
    ++report.matched;
    ++stats_.tracks_matched;
    matched.template_noise = template_noise;
    matched.beyond_search = beyond_search;
    hold_update(i, matched, creating, view, pool, report);
  }
  flush_updates(view, pool, report);
}

void ImageFrontEnd::hold_update(PrimitiveIndex i, const MatchedObservation& matched, const Viewpoint& creating,
                                const Viewpoint& view, PrimitivePoolView& pool, UpdateReport& report) {
  Primitive& p = pool[i];
  // The update, held for a batch of kUpdateBatchSize (one at a time when an observer watches).
  PendingUpdate& pending = pending_updates_[pending_count_];
  pending.index = i;
  pending.centre_cell = matched.centre_cell;
  pending.template_noise = matched.template_noise;
  // A provisional primitive's prior, to tell whether this update constrained its depth.
  pending.provisional = (p.flags & primitive_flags::kProvisional) != 0;
  if (pending.provisional) {
    pending.Sigma_prior = p.Sigma_world;
  } else {
    pending.Sigma_prior.setZero();
  }
  pending.have_creating = matched.have_creating;
  pending.beyond_search = matched.beyond_search;
  pending.creating = creating;
  pending.common = matched.common;
  if (observer_ != nullptr) {
    const Status updated = observed_update(i, p, matched, &pending.common, view, creating);
    after_update(pending, updated, pool, report);
    return;
  }
  ConsiderUpdateRequest& request = update_requests_[pending_count_];
  request.primitive = &p;
  request.common = &pending.common;
  request.observation_px = matched.observed_px;
  request.config = matched.ekf;
  request.at_prior.predicted_px = matched.predicted_px;
  request.at_prior.H = matched.H;
  if (++pending_count_ == kUpdateBatchSize) flush_updates(view, pool, report);
}

void ImageFrontEnd::flush_updates(const Viewpoint& view, PrimitivePoolView& pool, UpdateReport& report) {
  if (pending_count_ == 0) return;
  std::array<Status, kUpdateBatchSize> updated;
  iterated_consider_update_batch(update_requests_.data(), pending_count_, view, intrinsics_, config_.ekf_iterations,
                                 &stats_.ekf, updated.data());
  const int count = pending_count_;
  pending_count_ = 0;
  for (int held = 0; held < count; ++held) after_update(pending_updates_[held], updated[held], pool, report);
}

void ImageFrontEnd::after_update(const PendingUpdate& pending, Status updated, PrimitivePoolView& pool,
                                 UpdateReport& report) {
  const PrimitiveIndex i = pending.index;
  const std::size_t centre_cell = pending.centre_cell;
  Primitive& p = pool[i];
  if (ok(updated) && pending.template_noise) {
    TemplateNoise& noise = template_noise_[i];
    if (pending.common.has_part) {
      // The update carried the sum c + s, and c's part apart (common_error_for_match).
      noise.cross_covariance = pending.common.part_cross_covariance.cast<float>();
      noise.correlated_cross_covariance =
          (pending.common.cross_covariance - pending.common.part_cross_covariance).cast<float>();
      noise.correlated_view = next_view_index_;
      noise.correlated_trace =
          static_cast<float>((pending.common.covariance_px2 - pending.common.part_covariance_px2).trace());
    } else {
      noise.cross_covariance = pending.common.cross_covariance.cast<float>();
    }
  }
  if (ok(updated)) {
    ++report.updated;
    if (i < kFrontEndMaxPrimitives) rejected_in_a_row_[i] = 0;
    p.flags &= static_cast<std::uint16_t>(~(primitive_flags::kLostTrack | primitive_flags::kUnconsumed));
    if (cell_primitive_[centre_cell] == i) cell_state_[centre_cell] |= kCellUpdated;
    if (pending.provisional) {
      judge_provisional(i, pending.Sigma_prior, pending.have_creating ? &pending.creating : nullptr, centre_cell, pool,
                        report);
    }
  } else if (updated == Status::kGatedOutlier) {
    ++report.gated_outliers;
    reject_observation(i, centre_cell, pool, report, pending.beyond_search);
  }
}

Status ImageFrontEnd::observed_update(PrimitiveIndex i, Primitive& p, const MatchedObservation& matched,
                                      CommonObservationError* common, const Viewpoint& view,
                                      const Viewpoint& creating) {
  TrackedObservation seen;
  seen.index = i;
  seen.prior = p;
  seen.predicted_px = matched.predicted_px;
  seen.observed_px = matched.observed_px;
  seen.R_px2 = matched.ekf.R_px2;
  seen.warp_covariance_px2 = matched.warp_covariance_px2;
  seen.common_covariance_px2 = common->covariance_px2;
  seen.common_cross_covariance = common->cross_covariance;
  seen.B = matched.B;
  seen.view = view;
  seen.creating_view = creating;
  seen.inverse_warped = matched.inverse_warped;
  if (observer_->refuse(seen)) {
    seen.refused = true;
    seen.outcome = Status::kGatedOutlier;
    observer_->on_observation(seen);
    return seen.outcome;
  }
  seen.outcome = iterated_consider_update(p, common, matched.observed_px, view, intrinsics_, matched.ekf,
                                          config_.ekf_iterations, ProjectionAtPrior{matched.predicted_px, matched.H},
                                          &stats_.ekf);
  observer_->on_observation(seen);
  return seen.outcome;
}

void ImageFrontEnd::predict_batch(PrimitiveIndex first, const Viewpoint& view, bool occlusion,
                                  const PrimitivePoolView& pool, PredictionBatch* batch) const {
  batch->count = 0;
  batch->next = 0;
  static_assert(kDiscBatchSize == kProjectionBatchSize, "one projection batch per prediction batch");
  std::array<const Eigen::Vector3d*, kDiscBatchSize> points{};
  for (PrimitiveIndex i = first; i < pool.index_bound() && batch->count < kDiscBatchSize; ++i) {
    if (!pool.is_alive(i)) continue;
    batch->index[batch->count] = i;
    points[batch->count++] = &pool[i].X_world;
  }
  // The projections and Jacobians of the batch at once (the same bits as one by one).
  std::array<Status, kDiscBatchSize> projected{};
  project_with_jacobian_batch(points.data(), batch->count, view, intrinsics_, batch->predicted.data(), batch->H.data(),
                              projected.data());
  // In view: projected inside the image and facing the camera; the occlusion test follows.
  std::array<const Primitive*, kDiscBatchSize> primitives{};
  for (std::int32_t slot = 0; slot < batch->count; ++slot) primitives[slot] = &pool[batch->index[slot]];
  std::array<double, kDiscBatchSize> facing{};
  std::array<Eigen::Vector3f, kDiscBatchSize> pulled;
#if defined(__x86_64__)
  if (__builtin_cpu_supports("avx2") && batch->count > 1) {
    facing_and_pulled_lanes4(primitives.data(), batch->count, view.position_world, config_.occlusion_sigmas,
                             facing.data(), pulled.data());
  } else
#endif
  {
    for (std::int32_t slot = 0; slot < batch->count; ++slot) {
      facing_and_pulled(*primitives[slot], view.position_world, config_.occlusion_sigmas, &facing[slot], &pulled[slot]);
    }
  }
  DiscBatch discs;
  std::array<std::int32_t, kDiscBatchSize> lane_of{};  // the disc lane of each prediction's occlusion test
  for (std::int32_t slot = 0; slot < batch->count; ++slot) {
    batch->in_view[slot] = ok(projected[slot]) && in_image(batch->predicted[slot], intrinsics_, kPatchRadius + 1.0) &&
                           facing[slot] > config_.min_facing_cos;
    lane_of[slot] = -1;
    if (batch->in_view[slot] && occlusion) {
      lane_of[slot] = discs.count;
      discs.push(pulled[slot], primitives[slot]->normal_world, primitives[slot]->radius);
    }
  }
  if (discs.count > 0) {
    std::array<bool, kDiscBatchSize> visible;
    depth_buffer_.is_visible_batch(discs, &visible);
    for (std::int32_t slot = 0; slot < batch->count; ++slot) {
      if (lane_of[slot] >= 0) batch->in_view[slot] = visible[lane_of[slot]];
    }
  }
  // The in-view primitives' projections into their creating views, for track()'s plane maps: all four
  // from one creating view (primitives spawned together) in one batch, otherwise one by one (a slot out of
  // view or without its creating view's pose gets kNotFound, as track()'s view_pose).
  if (batch->count == 0) return;
  const std::uint32_t creating_view = primitives[0]->creating_view;
  bool one_view = batch->count == kDiscBatchSize;
  for (std::int32_t slot = 0; slot < batch->count && one_view; ++slot) {
    one_view = batch->in_view[slot] && primitives[slot]->creating_view == creating_view;
  }
  Viewpoint creating;
  if (one_view && ok(view_pose(creating_view, &creating))) {
    std::array<Eigen::Vector2d, kDiscBatchSize> uv;
    project_with_jacobian_batch(points.data(), kDiscBatchSize, creating, intrinsics_, uv.data(),
                                batch->H_creating.data(), batch->creating_status.data());
  } else {
    for (std::int32_t slot = 0; slot < batch->count; ++slot) {
      batch->creating_status[slot] = Status::kNotFound;
      if (!batch->in_view[slot] || !ok(view_pose(primitives[slot]->creating_view, &creating))) continue;
      Eigen::Vector2d uv;
      batch->creating_status[slot] =
          project_with_jacobian(*points[slot], creating, intrinsics_, &uv, &batch->H_creating[slot]);
    }
  }
  // Their plane maps from the Jacobians in both views, in lanes (a slot whose creating projection failed
  // gets a map track() does not read).
  static_assert(kPlaneAffineBatchSize == kDiscBatchSize, "one plane map batch per prediction batch");
  std::array<const Eigen::Vector3f*, kDiscBatchSize> normals{};
  for (std::int32_t slot = 0; slot < batch->count; ++slot) normals[slot] = &primitives[slot]->normal_world;
  plane_affine_from_jacobians_batch(batch->H_creating.data(), batch->H.data(), normals.data(), batch->count,
                                    batch->A.data(), batch->dA.data(), batch->plane_status.data());
}

bool ImageFrontEnd::refine_normal_photometric(PrimitiveIndex i, const GrayImageView& image, const Viewpoint& creating,
                                              const Viewpoint& view, const Eigen::Matrix<double, 2, 3>& H_creating,
                                              const Eigen::Matrix<double, 2, 3>& H_view, PrimitivePoolView& pool,
                                              NccTemplate* tmpl_out,
                                              Eigen::Matrix2d* B,
                                              Eigen::Matrix2d* warp_covariance, Eigen::Vector2d* observed,
                                              Eigen::Matrix2d* fit_covariance) {
  if (config_.subpixel_iterations < 1 || !config_.adaptive_R) return false;
  Primitive& p = pool[i];
  PhotometricNormalQuery query;
  query.X_world = p.X_world;
  query.normal_world = p.normal_world;
  // Every estimate uses the same reference patch, so their errors are not independent: the prior is the
  // facing prior's width (the current normal only linearizes), and the estimate replaces the normal when
  // it knows it better, as a plane fit does; it is not fused with the earlier ones.
  const double current_variance = normal_tilt_variance(i);
  query.prior_tilt_variance = std::max(config_.facing_normal_tilt_variance, current_variance);
  query.reference = creating;
  query.target = view;
  query.uv_target_px = *observed;
  query.min_facing_cos = config_.min_facing_cos;
  PhotometricNormalEstimate estimate;
  if (!ok(estimate_photometric_normal(image, p.patch, query, intrinsics_, &estimate)) ||
      !(estimate.tilt_variance < current_variance)) {
    return false;
  }
  // The match again, with the template warped by the estimated plane (its map and tilt derivatives from
  // the Jacobians track() already has).
  Eigen::Matrix2d A;
  std::array<Eigen::Matrix2d, 2> dA;
  if (!ok(plane_affine_from_jacobians(H_creating, H_view, estimate.normal_world, &A, &dA))) return false;
  NccTemplate tmpl;
  Eigen::Matrix2d B_new;
  reference_template(p.patch, A, config_.warp_min_deviation, &tmpl, &B_new);
  if (tmpl.valid_count < kPatchPixels / 2) return false;
  Eigen::Vector2d uv = *observed;
  Eigen::Matrix2d covariance;
  double last_step_px = 0.0;
  if (!refine_subpixel(image, tmpl, static_cast<std::int32_t>(std::lround(observed->x())),
                       static_cast<std::int32_t>(std::lround(observed->y())), config_.subpixel_iterations, &uv,
                       &covariance, MatchKernel::kAuto, &last_step_px)) {
    return false;
  }
  // Under require_converged_fit the refit must converge by the window search's rule too; if it does not, the
  // estimate is not used and the window search's match stands, as when the refit fails.
  if (config_.require_converged_fit && !(last_step_px < kSubpixelConvergedStepPx)) {
    ++stats_.photometric_refits_unconverged;
    return false;
  }
  const Eigen::Matrix2d warp = config_.model_normal_uncertainty
                                  ? warp_shift_covariance(tmpl, A, dA, estimate.tilt_variance)
                                  : Eigen::Matrix2d::Zero();
  p.normal_world = estimate.normal_world;
  set_normal_tilt_variance(i, estimate.tilt_variance, NormalSource::kPhotometric);
  ++stats_.photometric_normals;
  *tmpl_out = tmpl;
  *B = B_new;
  *warp_covariance = warp;
  *observed = uv;
  *fit_covariance = covariance;
  return true;
}

bool ImageFrontEnd::match_by_inverse_warp(PrimitiveIndex i, const GrayImageView& image, const Viewpoint& creating,
                                          const Viewpoint& view, const Eigen::Vector2d& predicted,
                                          const Eigen::Matrix2d& A, PrimitivePoolView& pool,
                                          Eigen::Vector2d* observed, Eigen::Matrix2d* covariance_px2) {
  Primitive& p = pool[i];
  PhotometricNormalQuery query;
  query.X_world = p.X_world;
  query.normal_world = p.normal_world;
  query.prior_tilt_variance = normal_tilt_variance(i);
  query.reference = creating;
  query.target = view;
  query.uv_target_px = predicted;  // the fit starts there and may move 1.5 px: a prior known that well
  query.min_facing_cos = config_.min_facing_cos;
  if (!(query.prior_tilt_variance > 0.0)) return false;
  PhotometricNormalEstimate estimate;
  if (!ok(estimate_photometric_normal(image, p.patch, query, intrinsics_, &estimate))) return false;
  // The NCC threshold in the fit's terms: NCC^2 = signal / (signal + residual variance), the signal the
  // gain times the reference patch's variance.
  NccTemplate reference;
  make_template(p.patch, &reference);
  const double signal = estimate.gain * estimate.gain * reference.stddev_gray * reference.stddev_gray;
  const double ncc_min = config_.inverse_warp_ncc_min;
  if (!(estimate.gain > 0.0) || !(estimate.residual_variance_gray2 * ncc_min * ncc_min <= signal * (1.0 - ncc_min * ncc_min)) ||
      !estimate.shift_covariance_px2.allFinite()) {
    return false;
  }
  if (estimate.tilt_variance < normal_tilt_variance(i)) {
    p.normal_world = estimate.normal_world;
    set_normal_tilt_variance(i, estimate.tilt_variance, NormalSource::kInverseWarp);
  }
  *observed = estimate.uv_target_px;
  // The 49 reference samples lie on an image area of 49 / |det A| pixels: where that is smaller they are
  // denser than the pixels whose noise they interpolate, and the fit, which counts each sample as
  // independent, holds |det A| times the information the image has.
  const double samples_per_pixel = std::abs(A.determinant());
  *covariance_px2 = estimate.shift_covariance_px2 * (samples_per_pixel > 1.0 ? samples_per_pixel : 1.0);
  return true;
}

void ImageFrontEnd::correlate_fit_covariance(const GrayImageView& image, const NccTemplate& tmpl,
                                             const Eigen::Vector2d& uv_px, Eigen::Matrix2d* fit_covariance) const {
  if (!config_.correlated_fit_covariance || !config_.adaptive_R || !fit_covariance->allFinite()) return;
  Eigen::Matrix2d correlated;
  if (correlated_match_covariance(image, tmpl, uv_px, &correlated)) *fit_covariance = correlated;
}

void ImageFrontEnd::reject_observation(PrimitiveIndex i, std::size_t centre_cell, PrimitivePoolView& pool,
                                       UpdateReport& report, bool beyond_search) {
  Primitive& p = pool[i];
  p.flags |= primitive_flags::kLostTrack;
  if (p.observation_count == 0) drop_unconfirmed(i, centre_cell, pool);
  if (pool.is_alive(i) && config_.erase_provisional_rejected && (p.flags & primitive_flags::kProvisional) != 0 &&
      depth_would_show(p, tracking_view_)) {
    erase_tracked(i, centre_cell, pool, report, &stats_.provisional_erased);
  }
  if (pool.is_alive(i)) count_rejection(i, centre_cell, pool, report, beyond_search);
}

bool ImageFrontEnd::match_too_uncertain(const Eigen::Matrix2d& R_px2, const CommonObservationError& common,
                                        const Eigen::Matrix2d& deformation_px2) const {
  if (!(max_match_variance_px2_ > 0.0)) return false;
  double variance_sum = R_px2.trace() + common.projected_px2().trace();
  if (config_.deformation_error_scale > 0.0) {
    variance_sum -= (common.B * deformation_px2 * common.B.transpose()).trace();
  }
  // A NaN covariance is refused too: nothing can weigh it.
  return !(0.5 * variance_sum <= max_match_variance_px2_);
}

void ImageFrontEnd::count_track_failure(bool template_usable, MatchOutcome outcome) {
  TrackFailureCounts& f = stats_.track_failures;
  if (!template_usable) {
    ++f.template_masked;  // the window was not searched
    return;
  }
  switch (outcome) {
    case MatchOutcome::kBelowThreshold: ++f.below_threshold; break;
    case MatchOutcome::kAmbiguous: ++f.ambiguous; break;
    case MatchOutcome::kNoSubpixel: ++f.no_subpixel; break;
    case MatchOutcome::kNoRoom: ++f.no_room; break;
    case MatchOutcome::kMatched: break;           // not a failure: never passed
    case MatchOutcome::kBeyondDepthRange: break;  // the epipolar search's only, never the window's
  }
}

void ImageFrontEnd::drop_unconfirmed(PrimitiveIndex i, std::size_t centre_cell, PrimitivePoolView& pool) {
  if (!config_.confirm_spawns || !ok(pool.erase(i))) return;
  ++stats_.unconfirmed_erased;
  forget_cell(i, centre_cell);
}

void ImageFrontEnd::judge_provisional(PrimitiveIndex i, const Eigen::Matrix3d& Sigma_prior, const Viewpoint* creating,
                                      std::size_t centre_cell, PrimitivePoolView& pool, UpdateReport& report) {
  Primitive& p = pool[i];
  // The depth a spawn match fixes is along the seed ray; without the creating pose, the prior's long axis.
  Eigen::Vector3d ray = creating != nullptr ? Eigen::Vector3d(p.X_world - creating->position_world)
                                            : Eigen::Vector3d::Zero();
  if (!(ray.norm() > 0.0)) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
    eigen.computeDirect(Sigma_prior);
    ray = eigen.eigenvectors().col(2);
  }
  ray.normalize();
  const double prior_variance = ray.dot(Sigma_prior * ray);
  const double posterior_variance = ray.dot(p.Sigma_world * ray);
  if (posterior_variance * (1.0 + config_.confirm_min_depth_information) <= prior_variance) {
    p.flags &= static_cast<std::uint16_t>(~primitive_flags::kProvisional);
    ++stats_.parallax_confirmed;
    return;
  }
  if (config_.provisional_max_updates == 0 || p.observation_count < config_.provisional_max_updates) return;
  erase_tracked(i, centre_cell, pool, report, &stats_.provisional_erased);
}

void ImageFrontEnd::erase_tracked(PrimitiveIndex i, std::size_t centre_cell, PrimitivePoolView& pool,
                                  UpdateReport& report, std::uint64_t* erased_count) {
  if (!ok(pool.erase(i))) return;
  ++*erased_count;
  ++report.gated_erased;
  if (i < kFrontEndMaxPrimitives) rejected_in_a_row_[i] = 0;
  forget_cell(i, centre_cell);
}

bool ImageFrontEnd::depth_would_show(const Primitive& p, const Viewpoint& view) const {
  Viewpoint creating;
  Eigen::Vector2d uv;
  Eigen::Matrix<double, 2, 3> H;
  if (!ok(view_pose(p.creating_view, &creating)) || !ok(project_with_jacobian(p.X_world, view, intrinsics_, &uv, &H))) {
    return false;
  }
  const Eigen::Vector3d ray = (p.X_world - creating.position_world).normalized();
  const Eigen::Vector2d shift = std::sqrt(ray.dot(p.Sigma_world * ray)) * (H * ray);
  return shift.dot(config_.ekf.R_px2.inverse() * shift) >= config_.confirm_min_depth_information;
}

void ImageFrontEnd::forget_cell(PrimitiveIndex i, std::size_t centre_cell) {
  if (centre_cell < cell_primitive_.size() && cell_primitive_[centre_cell] == i) {
    cell_primitive_[centre_cell] = kInvalidPrimitive;
    cell_state_[centre_cell] = 0;
  }
}

void ImageFrontEnd::count_rejection(PrimitiveIndex i, std::size_t centre_cell, PrimitivePoolView& pool,
                                    UpdateReport& report, bool beyond_search) {
  const std::uint32_t flag_at = config_.unconsumed_after_rejections;
  const std::uint32_t erase_at = config_.max_rejected_in_a_row;
  if ((flag_at == 0 && erase_at == 0) || i >= kFrontEndMaxPrimitives) return;
  if (rejected_in_a_row_[i] < 255) ++rejected_in_a_row_[i];
  const bool unconsumed = flag_at > 0 && rejected_in_a_row_[i] >= flag_at;
  if (unconsumed) pool[i].flags |= primitive_flags::kUnconsumed;
  const bool unsearchable = unconsumed && beyond_search && config_.erase_unsearchable;
  if (!unsearchable && (erase_at == 0 || rejected_in_a_row_[i] < erase_at)) return;
  erase_tracked(i, centre_cell, pool, report, unsearchable ? &stats_.unsearchable_erased : &stats_.gated_erased);
}

void ImageFrontEnd::refit_normals(const Viewpoint& view, PrimitivePoolView& pool) {
  const double focal = focal_mean(intrinsics_);
  for (std::int32_t cy = 0; cy < cells_y_; ++cy) {
    for (std::int32_t cx = 0; cx < cells_x_; ++cx) {
      const std::size_t cell = static_cast<std::size_t>(cy) * cells_x_ + cx;
      if ((cell_state_[cell] & kCellUpdated) == 0 || !pool.is_alive(cell_primitive_[cell])) continue;
      Primitive& p = pool[cell_primitive_[cell]];
      // Refit at n, 2n, 4n, 8n updates (n = normal_refit_observations): the normal follows the estimates
      // as they sharpen, at an amortized cost of a few fits per primitive.
      const std::uint32_t n = config_.normal_refit_observations;
      const std::uint32_t count = p.observation_count;
      if (count != n && count != 2 * n && count != 4 * n && count != 8 * n) continue;
      const double spacing = config_.seed_stride_px * cell_depth_[cell] / focal;
      // Only neighbours known to a fraction of their spacing say anything about the plane.
      fit_normal(cell_primitive_[cell], cx, cy, spacing, 0.25 * spacing, view.position_world, false, NormalSource::kRefit,
                 pool);
    }
  }
}

void ImageFrontEnd::fit_normal(PrimitiveIndex i, std::int32_t cx, std::int32_t cy, double spacing, double max_sigma,
                               const Eigen::Vector3d& camera_world, bool along_rays, NormalSource source,
                               PrimitivePoolView& pool) {
  Primitive& p = pool[i];
  std::array<Eigen::Vector3d, kFrontEndMaxNormalFitNeighbours> neighbours;
  std::array<Eigen::Matrix3d, kFrontEndMaxNormalFitNeighbours> sigmas;
  const std::size_t used = neighbour_positions(cx, cy, pool, max_sigma, &neighbours, &sigmas);
  Eigen::Vector3f normal;
  double tilt_variance = 0.0;
  const Span<const Eigen::Vector3d> points(neighbours.data(), used);
  const Span<const Eigen::Matrix3d> covariances(sigmas.data(), used);
  if (along_rays) {
    // Depth edges are the chi^2 test's to find: the distance only bounds where the ring's farthest cell
    // can lie on a surface seen at up to 75 degrees incidence (footprint_radius's limit).
    RayPlaneFitConfig fit;
    fit.max_neighbour_distance =
        config_.normal_fit_ring_cells * std::sqrt(2.0) * spacing / kFootprintMinCosIncidence;
    fit.residual_tilt_floor = config_.normal_spawn_residual_floor;
    fit.floored_claim_limit = config_.facing_normal_tilt_variance;
    if (!fit_plane_normal_along_rays(p.X_world, p.Sigma_world, points, covariances, camera_world, fit, &normal,
                                     &tilt_variance)) {
      return;
    }
  } else {
    // Farther neighbours lie across a depth edge.
    PlaneFitConfig fit;
    fit.max_neighbour_distance = 3.0 * spacing;
    fit.residual_tilt_floor = config_.normal_refit_residual_floor;
    if (!fit_plane_normal(p.X_world, p.Sigma_world, points, covariances, camera_world, fit, &normal, &tilt_variance)) {
      return;
    }
  }
  if (config_.model_normal_uncertainty &&
      !normal_refit_replaces(normal_source(i), normal_tilt_variance(i), source, tilt_variance,
                             config_.refit_supersedes_spawn_fit)) {
    return;
  }
  p.normal_world = normal;
  set_normal_tilt_variance(i, tilt_variance, source);
}

bool ImageFrontEnd::spawn_patch_noise_px2(const Eigen::Matrix2d& fit_covariance_px2, Eigen::Matrix2d* P_c) const {
  if (!config_.model_template_noise || !config_.adaptive_R || !fit_covariance_px2.allFinite()) return false;
  *P_c = 0.5 * fit_covariance_px2;
  return true;
}

void ImageFrontEnd::remember_template_noise(PrimitiveIndex i, const Primitive& p, const Viewpoint& other_view,
                                            std::uint32_t other_index, const Eigen::Matrix2d& R_other_px2,
                                            const Eigen::Matrix2d& fit_covariance_px2) {
  if (i >= kFrontEndMaxPrimitives) return;
  TemplateNoise& noise = template_noise_[i];
  noise.cross_covariance.setZero();
  noise.covariance_px2.setZero();
  noise.correlated_cross_covariance.setZero();
  noise.correlated_view = other_index;
  noise.correlated_trace = 0.0f;
  Eigen::Vector2d unused;
  Eigen::Matrix<double, 2, 3> H;
  // The template's half of the first match's fit covariance; the triangulated error carries it through
  // the other image's observation: X_hat - X = Sigma H^T R^-1 (c + e) + ..., so C = Sigma H^T R^-1 P_c
  // (the unwarped epipolar match: B = I).
  Eigen::Matrix2d P_c;
  if (!spawn_patch_noise_px2(fit_covariance_px2, &P_c) ||
      !ok(project_with_jacobian(p.X_world, other_view, intrinsics_, &unused, &H))) {
    return;
  }
  noise.covariance_px2 = P_c.cast<float>();
  const Eigen::Matrix<double, 3, 2> gain_px = p.Sigma_world * H.transpose() * R_other_px2.inverse();
  noise.cross_covariance = (gain_px * P_c).cast<float>();
  // The view-correlated error s displaced that match too (R_other_px2 holds its covariance, see spawn).
  noise.correlated_cross_covariance = (gain_px * (config_.view_correlated_error_scale * P_c)).cast<float>();
  noise.correlated_trace = static_cast<float>(config_.view_correlated_error_scale * P_c.trace());
}

void ImageFrontEnd::common_error_for_match(PrimitiveIndex i, const Primitive& p, const Viewpoint& view,
                                           const Eigen::Matrix2d& deformation_px2,
                                           CommonObservationError* common) const {
  const TemplateNoise& noise = template_noise_[i];
  common->covariance_px2 = noise.covariance_px2.cast<double>();
  common->cross_covariance = noise.cross_covariance.cast<double>();
  const double scale = config_.view_correlated_error_scale;
  const bool deformation = config_.deformation_error_scale > 0.0;
  if (!(scale > 0.0) && !deformation) return;
  // c + s: covariance P_c (1 + scale), cross-covariance C_c + rho C_s with rho the correlation between s
  // here and s at its last update's view (a view no longer in the table is taken as uncorrelated).
  double rho = 0.0;
  Viewpoint last;
  if (ok(view_pose(noise.correlated_view, &last))) {
    const Eigen::Vector3d a = last.position_world - p.X_world;
    const Eigen::Vector3d b = view.position_world - p.X_world;
    const double angle_deg = std::atan2(a.cross(b).norm(), a.dot(b)) * (180.0 / EIGEN_PI);
    rho = std::exp(-angle_deg / config_.view_correlation_deg);
  }
  common->has_part = true;
  common->part_covariance_px2 = common->covariance_px2;
  common->part_cross_covariance = common->cross_covariance;
  common->covariance_px2 *= 1.0 + scale;
  if (deformation) {
    common->covariance_px2 += deformation_px2;
    // s_k = rho (sd_k / sd_last) s_last + w: a varying variance scales the carried part by the ratio of the
    // standard deviations (none to carry after a match whose s had no variance).
    const double s_trace = scale * common->part_covariance_px2.trace() + deformation_px2.trace();
    rho = noise.correlated_trace > 0.0f ? rho * std::sqrt(s_trace / noise.correlated_trace) : 0.0;
  }
  common->cross_covariance += rho * noise.correlated_cross_covariance.cast<double>();
}

Eigen::Matrix2d ImageFrontEnd::deformation_error_px2(const Eigen::Matrix2d& B) const {
  const double scale = config_.deformation_error_scale;
  if (!(scale > 0.0)) return Eigen::Matrix2d::Zero();
  const double ratio = warp_stretch_ratio(B, kMaxDeformationStretchRatio);
  return scale * std::pow(ratio - 1.0, config_.deformation_error_power) * match_floor_px2_;
}

double ImageFrontEnd::normal_tilt_variance(PrimitiveIndex i) const {
  return i < kFrontEndMaxPrimitives ? normal_tilt_variance_[i] : config_.facing_normal_tilt_variance;
}

Status ImageFrontEnd::adopt_normal(PrimitiveIndex i, const Eigen::Vector3d& normal_world, double tilt_variance,
                                   PrimitivePoolView& pool) {
  if (i >= kFrontEndMaxPrimitives || i >= pool.index_bound() || !pool.is_alive(i)) return Status::kNotFound;
  if (!normal_world.allFinite() || !std::isfinite(tilt_variance)) return Status::kNonFiniteInput;
  if (!(std::abs(normal_world.norm() - 1.0) <= 1e-3) || !(tilt_variance > 0.0)) return Status::kInvalidArgument;
  pool[i].normal_world = normal_world.normalized().cast<float>();
  set_normal_tilt_variance(i, tilt_variance, NormalSource::kAdopted);
  return Status::kOk;
}

void ImageFrontEnd::set_normal_tilt_variance(PrimitiveIndex i, double variance, NormalSource source) {
  if (i >= kFrontEndMaxPrimitives) return;
  normal_tilt_variance_[i] = static_cast<float>(variance);
  normal_source_[i] = source;
}

bool normal_refit_replaces(NormalSource current, double current_tilt_variance, NormalSource fit,
                           double fit_tilt_variance, bool refit_supersedes_spawn_fit) {
  if (refit_supersedes_spawn_fit && fit == NormalSource::kRefit &&
      (current == NormalSource::kSpawnFit || current == NormalSource::kFacingPrior)) {
    return true;
  }
  return fit_tilt_variance < current_tilt_variance;
}

NormalSource ImageFrontEnd::normal_source(PrimitiveIndex i) const {
  return i < kFrontEndMaxPrimitives ? normal_source_[i] : NormalSource::kFacingPrior;
}

Eigen::Matrix2d ImageFrontEnd::template_noise_covariance_px2(PrimitiveIndex i) const {
  if (i >= kFrontEndMaxPrimitives) return Eigen::Matrix2d::Zero();
  return template_noise_[i].covariance_px2.cast<double>();
}

std::size_t ImageFrontEnd::neighbour_positions(std::int32_t cx, std::int32_t cy, const PrimitivePoolView& pool,
                                               double max_sigma,
                                               std::array<Eigen::Vector3d, kFrontEndMaxNormalFitNeighbours>* out,
                                               std::array<Eigen::Matrix3d, kFrontEndMaxNormalFitNeighbours>* sigmas) const {
  std::size_t count = 0;
  const std::int32_t ring = config_.normal_fit_ring_cells;  // validated: 1..kFrontEndMaxNormalFitRing
  for (std::int32_t dy = -ring; dy <= ring; ++dy) {
    for (std::int32_t dx = -ring; dx <= ring; ++dx) {
      const std::int32_t nx = cx + dx;
      const std::int32_t ny = cy + dy;
      if ((dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= cells_x_ || ny >= cells_y_) continue;
      const PrimitiveIndex j = cell_primitive_[static_cast<std::size_t>(ny) * cells_x_ + nx];
      if (j == kInvalidPrimitive || !pool.is_alive(j)) continue;
      if (std::isfinite(max_sigma) && !(sigma_bound(pool[j].Sigma_world) < max_sigma)) continue;
      if (sigmas != nullptr) (*sigmas)[count] = pool[j].Sigma_world;
      (*out)[count++] = pool[j].X_world;
    }
  }
  return count;
}

void ImageFrontEnd::merge_neighbours(const Viewpoint& view, PrimitivePoolView& pool, UpdateReport& report) {
  const double focal = focal_mean(intrinsics_);
  const double cos_max_angle = std::cos(config_.merge_max_normal_angle_deg * kDegToRad);
  auto well_estimated = [&](const Primitive& p) {
    return p.observation_count >= config_.merge_min_observations && sigma_bound(p.Sigma_world) <= config_.merge_max_sigma;
  };
  for (std::int32_t cy = 0; cy < cells_y_; ++cy) {
    for (std::int32_t cx = 0; cx < cells_x_; ++cx) {
      const std::size_t cell = static_cast<std::size_t>(cy) * cells_x_ + cx;
      const PrimitiveIndex a = cell_primitive_[cell];
      if (a == kInvalidPrimitive) continue;
      // Right and down neighbours: each adjacent pair is looked at once.
      const std::int32_t offsets[2][2] = {{1, 0}, {0, 1}};
      for (const auto& offset : offsets) {
        if (!pool.is_alive(a)) break;
        const std::int32_t nx = cx + offset[0];
        const std::int32_t ny = cy + offset[1];
        if (nx >= cells_x_ || ny >= cells_y_) continue;
        const std::size_t other_cell = static_cast<std::size_t>(ny) * cells_x_ + nx;
        const PrimitiveIndex b = cell_primitive_[other_cell];
        if (b == kInvalidPrimitive || b == a || !pool.is_alive(b)) continue;
        Primitive& pa = pool[a];
        Primitive& pb = pool[b];
        if (!well_estimated(pa) || !well_estimated(pb)) continue;
        if (!(pa.normal_world.dot(pb.normal_world) >= cos_max_angle)) continue;
        // The better-estimated one survives and keeps its position, covariance and patch, so its EKF
        // stays what it was; only its footprint grows to cover the other's.
        const bool a_survives = pa.Sigma_world.trace() <= pb.Sigma_world.trace();
        Primitive& keep = a_survives ? pa : pb;
        const Primitive& drop = a_survives ? pb : pa;
        const Eigen::Vector3d n = keep.normal_world.cast<double>();
        const Eigen::Vector3d offset_world = drop.X_world - keep.X_world;
        const double plane_sigma = std::sqrt(n.dot((keep.Sigma_world + drop.Sigma_world) * n));
        if (!(std::abs(n.dot(offset_world)) <= config_.merge_plane_sigmas * plane_sigma)) continue;
        const double separation = offset_world.norm();
        if (!(separation <= static_cast<double>(keep.radius) + drop.radius)) continue;
        const double grown = std::max(static_cast<double>(keep.radius), separation + drop.radius);
        const double depth = (view.R_world_cam.transpose() * (keep.X_world - view.position_world)).z();
        if (!(depth > 0.0) || !(grown * focal / depth <= config_.merge_max_radius_px)) continue;
        keep.radius = static_cast<float>(grown);
        keep.flags |= primitive_flags::kMerged;
        const PrimitiveIndex dropped = a_survives ? b : a;
        if (!ok(pool.erase(dropped))) continue;
        ++report.merged;
        // The survivor now answers for both cells.
        const PrimitiveIndex kept = a_survives ? a : b;
        cell_primitive_[cell] = kept;
        cell_primitive_[other_cell] = kept;
      }
    }
  }
}

void ImageFrontEnd::spawn(const GrayImageView& reference, const Viewpoint& reference_view,
                          std::uint32_t reference_index, const GrayImageView& other, const Viewpoint& other_view,
                          std::uint32_t other_index, PrimitivePoolView& pool, UpdateReport& report) {
  const double focal = focal_mean(intrinsics_);
  const std::int32_t stride = config_.seed_stride_px;
  const MatchConfig match{config_.spawn_ncc_min, config_.uniqueness_ratio, config_.subpixel_iterations};
  const Span<float> ncc_scratch(epipolar_ncc_.data(), epipolar_ncc_.size());
  const Span<std::int32_t> xy_scratch(epipolar_xy_.data(), epipolar_xy_.size());
  const Eigen::Matrix3d R_cam_world = reference_view.R_world_cam.transpose();
  EpipolarQuery query;
  query.first = reference_view;
  query.second = other_view;
  query.depth_min = config_.depth_min;
  query.depth_max = config_.depth_max;
  query.guard_fraction = config_.epipolar_guard_fraction;
  TwoViewObservation observation;
  observation.view_a = reference_view;
  observation.view_b = other_view;
  observation.R_a_px2 = config_.adaptive_R ? match_floor_px2_ : config_.ekf.R_px2;
  observation.R_b_px2 = config_.ekf.R_px2;
  bool pool_full = false;
  for (std::int32_t cy = 0; cy < cells_y_ && !pool_full; ++cy) {
    for (std::int32_t cx = 0; cx < cells_x_; ++cx) {
      const std::size_t cell = static_cast<std::size_t>(cy) * cells_x_ + cx;
      if (cell_covered_[cell] != 0 || cell_primitive_[cell] != kInvalidPrimitive) continue;
      const std::int32_t sx = cx * stride + stride / 2;
      const std::int32_t sy = cy * stride + stride / 2;
      if (!patch_inside(reference, sx, sy, 1)) continue;
      Primitive p;
      extract_patch(reference, sx, sy, &p.patch);
      NccTemplate tmpl;
      make_template(p.patch, &tmpl);
      if (tmpl.stddev_gray < config_.min_texture_stddev_gray) continue;
      ++stats_.seeds_tried;
      query.uv_first_px = Eigen::Vector2d(sx, sy);
      Eigen::Vector2d matched_px;
      float best = 0.0f;
      Eigen::Matrix2d fit_covariance;
      const MatchOutcome outcome = search_epipolar(other, tmpl, query, intrinsics_, match, ncc_scratch, xy_scratch,
                                                   &matched_px, &best, &fit_covariance);
      if (outcome != MatchOutcome::kMatched) {
        if (outcome == MatchOutcome::kBeyondDepthRange) ++stats_.seeds_beyond_depth_range;
        continue;
      }
      ++stats_.seeds_matched;
      if (config_.spawn_back_match_max_px > 0.0 &&
          !matches_back(reference, other, query, matched_px, match, ncc_scratch, xy_scratch)) {
        ++stats_.seeds_rejected_back_match;
        continue;
      }
      correlate_fit_covariance(other, tmpl, matched_px, &fit_covariance);
      observation.uv_a_px = query.uv_first_px;
      observation.uv_b_px = matched_px;
      observation.R_b_px2 = measurement_R(fit_covariance);
      // The view-correlated error's share of this match (FrontEndConfig::view_correlated_error_scale x P_c).
      Eigen::Matrix2d P_c;
      if (config_.view_correlated_error_scale > 0.0 && spawn_patch_noise_px2(fit_covariance, &P_c)) {
        observation.R_b_px2 += config_.view_correlated_error_scale * P_c;
      }
      bool triangulated = ok(triangulate_two_views(observation, intrinsics_, &p.X_world, &p.Sigma_world));
      if (triangulated && config_.model_normal_uncertainty && config_.model_spawn_normal_uncertainty && config_.adaptive_R) {
        // Again with the unknown normal's share of the match error (spawn_warp_covariance, at X).
        observation.R_b_px2 += spawn_warp_covariance(tmpl, p.X_world, reference_view, other_view, intrinsics_,
                                                     config_.facing_normal_tilt_variance);
        triangulated = ok(triangulate_two_views(observation, intrinsics_, &p.X_world, &p.Sigma_world));
      }
      if (!triangulated || sigma_bound(p.Sigma_world) > config_.max_initial_sigma) {
        ++stats_.seeds_rejected_triangulation;
        continue;
      }
      const double depth = (R_cam_world * (p.X_world - reference_view.position_world)).z();
      if (!(depth >= config_.depth_min && depth <= config_.depth_max)) {
        ++stats_.seeds_rejected_triangulation;
        continue;
      }
      const Eigen::Vector3d to_camera = (reference_view.position_world - p.X_world).normalized();
      p.normal_world = to_camera.cast<float>();  // until the plane fit below knows better
      p.radius = static_cast<float>(footprint_radius(stride, depth, focal, 1.0));
      p.saliency_h = compute_saliency_h(p.patch, config_.saliency);
      p.creating_view = reference_index;
      // Its depth rests on this one match until a view with parallax confirms it (judge_provisional).
      if (config_.confirm_min_depth_information > 0.0) p.flags |= primitive_flags::kProvisional;
      PrimitiveIndex index = kInvalidPrimitive;
      const Status inserted = pool.insert(p, &index);
      if (inserted == Status::kPoolFull) {
        ++report.pool_full_rejections;
        pool_full = true;
        break;
      }
      if (!ok(inserted)) continue;
      ++report.spawned;
      if (index < kFrontEndMaxPrimitives) rejected_in_a_row_[index] = 0;
      set_normal_tilt_variance(index, config_.facing_normal_tilt_variance, NormalSource::kFacingPrior);
      remember_template_noise(index, p, other_view, other_index, observation.R_b_px2, fit_covariance);
      cell_primitive_[cell] = index;
      cell_depth_[cell] = static_cast<float>(depth);
      cell_state_[cell] |= kCellSpawned;
    }
  }
  // Normals of the new primitives from their neighbours (new or tracked), then radii for the incidence.
  // With the fit along the rays the radius stays the facing footprint: tracking marks a primitive's disc
  // as a circle of its radius in the image, so a radius stretched by 1 / cos(incidence) would cover the
  // neighbouring cells and keep them from spawning (EXPERIMENTS.md, "Session 21").
  const bool along_rays = config_.spawn_normal_fit_along_rays;
  for (std::int32_t cy = 0; cy < cells_y_; ++cy) {
    for (std::int32_t cx = 0; cx < cells_x_; ++cx) {
      const std::size_t cell = static_cast<std::size_t>(cy) * cells_x_ + cx;
      if ((cell_state_[cell] & kCellSpawned) == 0) continue;
      const PrimitiveIndex i = cell_primitive_[cell];
      fit_normal(i, cx, cy, stride * cell_depth_[cell] / focal, std::numeric_limits<double>::infinity(),
                 reference_view.position_world, along_rays, NormalSource::kSpawnFit, pool);
      // No plane among its neighbours: erased before tracking (later cells' fits no longer see it).
      if (config_.spawn_requires_plane_fit && normal_source(i) == NormalSource::kFacingPrior && ok(pool.erase(i))) {
        forget_cell(i, cell);
        --report.spawned;
        ++stats_.seeds_rejected_no_plane_fit;
        continue;
      }
      if (along_rays) continue;
      Primitive& p = pool[i];
      const Eigen::Vector3d to_camera = (reference_view.position_world - p.X_world).normalized();
      p.radius = static_cast<float>(
          footprint_radius(stride, cell_depth_[cell], focal, to_camera.dot(p.normal_world.cast<double>())));
    }
  }
}

bool ImageFrontEnd::matches_back(const GrayImageView& reference, const GrayImageView& other,
                                 const EpipolarQuery& forward, const Eigen::Vector2d& matched_px,
                                 const MatchConfig& match, Span<float> ncc_scratch,
                                 Span<std::int32_t> xy_scratch) {
  const std::int32_t bx = static_cast<std::int32_t>(std::lround(matched_px.x()));
  const std::int32_t by = static_cast<std::int32_t>(std::lround(matched_px.y()));
  if (!patch_inside(other, bx, by, 1)) return true;
  std::array<std::uint8_t, kPatchPixels> patch;
  extract_patch(other, bx, by, &patch);
  NccTemplate back_template;
  make_template(patch, &back_template);
  EpipolarQuery back = forward;
  back.first = forward.second;
  back.second = forward.first;
  back.uv_first_px = Eigen::Vector2d(bx, by);
  Eigen::Vector2d back_px;
  float best = 0.0f;
  const MatchOutcome outcome =
      search_epipolar(reference, back_template, back, intrinsics_, match, ncc_scratch, xy_scratch, &back_px, &best);
  if (outcome == MatchOutcome::kNoRoom) return true;
  if (outcome != MatchOutcome::kMatched) return false;
  // Between two nearby views the local map is close to the identity, so the pixel the back search
  // started from lies about its offset from the match away from the seed.
  const Eigen::Vector2d expected = forward.uv_first_px + (back.uv_first_px - matched_px);
  return (back_px - expected).norm() <= config_.spawn_back_match_max_px;
}

}  // namespace vantage
