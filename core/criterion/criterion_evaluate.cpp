// View evaluation of the criterion: cluster culling, splatting, depth test, sum (see criterion_model.hpp).
#include <cmath>

#include "core/criterion/criterion_model.hpp"
#include "core/criterion/block_kernel.hpp"

namespace vantage {

struct CriterionModelView::ViewSetup {
  PinholeIntrinsics intrinsics;  // the camera's, for g in its pixels
  float log2_fxfy = 0.0f;        // log2(fx * fy) of the camera
};

namespace {

// Side planes of the buffer's frustum in the camera frame, inward unit normals through the origin.
struct Frustum {
  Eigen::Vector3f normal[4];
};

Frustum make_frustum(const BufferCamera& cam) {
  const float x_left = (-0.5f - cam.cx_px) / cam.fx_px;
  const float x_right = (static_cast<float>(cam.width_px) - 0.5f - cam.cx_px) / cam.fx_px;
  const float y_top = (-0.5f - cam.cy_px) / cam.fy_px;
  const float y_bottom = (static_cast<float>(cam.height_px) - 0.5f - cam.cy_px) / cam.fy_px;
  Frustum f;
  f.normal[0] = Eigen::Vector3f(1.0f, 0.0f, -x_left).normalized();
  f.normal[1] = Eigen::Vector3f(-1.0f, 0.0f, x_right).normalized();
  f.normal[2] = Eigen::Vector3f(0.0f, 1.0f, -y_top).normalized();
  f.normal[3] = Eigen::Vector3f(0.0f, -1.0f, y_bottom).normalized();
  return f;
}

// True when no primitive of the cluster can be front-facing and in the frustum from the camera.
bool cull_cluster(const ClusterBounds& b, const Eigen::Matrix3f& R_cam_world, const Eigen::Vector3f& camera_world,
                  const Frustum& frustum) {
  const Eigen::Vector3f centre(b.centre_x, b.centre_y, b.centre_z);
  const Eigen::Vector3f centre_cam = R_cam_world * (centre - camera_world);
  if (centre_cam.z() < kNearDepth - b.radius) return true;
  for (const Eigen::Vector3f& n : frustum.normal) {
    if (n.dot(centre_cam) < -b.radius) return true;
  }
  // Normal cone (axis a, half-angle alpha) against the directions from the sphere to the camera, which
  // lie within beta = asin(r / d) of (camera - centre): every primitive faces away when
  // angle(a, camera - centre) > 90 deg + alpha + beta.
  if (b.cos_half_angle <= 0.0f) return false;
  const Eigen::Vector3f to_camera = camera_world - centre;
  const float d = to_camera.norm();
  if (!(d > b.radius)) return false;
  const float sin_beta = b.radius / d;
  const float cos_beta = std::sqrt(1.0f - sin_beta * sin_beta);
  const float cos_sum = b.cos_half_angle * cos_beta - b.sin_half_angle * sin_beta;  // cos(alpha + beta)
  if (cos_sum <= 0.0f) return false;
  const float sin_sum = b.sin_half_angle * cos_beta + b.cos_half_angle * sin_beta;
  const Eigen::Vector3f axis(b.axis_x, b.axis_y, b.axis_z);
  return axis.dot(to_camera) < -sin_sum * d;
}

}  // namespace

Status CriterionModelView::prepare(const Viewpoint& view, const PinholeIntrinsics& intrinsics,
                                   CriterionScratchView& scratch, ViewSetup* setup) const {
  if (scratch.capacity() < round_up_to_clusters(count_)) return Status::kInvalidArgument;
  const Status configured = scratch.depth().configure(view, intrinsics);  // validates pose and intrinsics
  if (!ok(configured)) return configured;
  setup->intrinsics = intrinsics;
  setup->log2_fxfy = static_cast<float>(std::log2(intrinsics.fx_px * intrinsics.fy_px));
  return Status::kOk;
}

void CriterionModelView::render(const ViewSetup& setup, CriterionScratchView& scratch) const {
  DepthBufferView& depth = scratch.depth();
  const BufferCamera cam = depth.camera();
  const Eigen::Matrix3f R = depth.R_cam_world();
  const Eigen::Vector3f camera = depth.position_world();
  const Frustum frustum = make_frustum(cam);

  // Level 1: clusters.
  const std::size_t cluster_total = cluster_count();
  std::size_t kept = 0;
  for (std::size_t c = 0; c < cluster_total; ++c) {
    if (!cull_cluster(arrays_.clusters[c], R, camera, frustum)) scratch.clusters_[kept++] = static_cast<std::uint32_t>(c);
  }
  scratch.clusters_total_ = cluster_total;
  scratch.clusters_kept_ = kept;

  // Level 2: primitives of the kept clusters, kClusterSize at a time through a vectorizable block.
  BlockConstants kc;
  kc.r00 = R(0, 0), kc.r01 = R(0, 1), kc.r02 = R(0, 2);
  kc.r10 = R(1, 0), kc.r11 = R(1, 1), kc.r12 = R(1, 2);
  kc.r20 = R(2, 0), kc.r21 = R(2, 1), kc.r22 = R(2, 2);
  kc.cam_x = camera.x(), kc.cam_y = camera.y(), kc.cam_z = camera.z();
  kc.fx = cam.fx_px, kc.fy = cam.fy_px, kc.cx = cam.cx_px, kc.cy = cam.cy_px;
  kc.inv_fx = 1.0f / kc.fx, kc.inv_fy = 1.0f / kc.fy;
  kc.f_max = kc.fx > kc.fy ? kc.fx : kc.fy;
  kc.u_max = static_cast<float>(cam.width_px) - 0.5f;
  kc.v_max = static_cast<float>(cam.height_px) - 0.5f;
  kc.u_clamp = static_cast<float>(cam.width_px);
  kc.v_clamp = static_cast<float>(cam.height_px);
  kc.width = cam.width_px;
  kc.spare = depth.spare_index();
  kc.tolerance_radii = depth.tolerance_radii();
  kc.log2_fxfy = setup.log2_fxfy;

  BlockOutput out;
  std::uint32_t general_lanes[kClusterSize];
  float* __restrict buffer = depth.inverse_depth_data();
  std::size_t entries = 0;
  for (std::size_t k = 0; k < kept; ++k) {
    const std::size_t base = static_cast<std::size_t>(scratch.clusters_[k]) * kClusterSize;
    block_kernel(arrays_, base, kc, out);
    // Scalar, branch-free: the single-pixel splats, the member entries, and the list of lanes that need
    // the general (multi-pixel or partly outside) splat.
    std::size_t general_count = 0;
    for (std::size_t i = 0; i < kClusterSize; ++i) {
      float& cell = buffer[out.write_pixel[i]];
      const float iz = out.iz_pixel[i];
      cell = iz > cell ? iz : cell;
      scratch.pixel_[entries] = out.pixel[i];
      scratch.threshold_[entries] = out.threshold[i] > 0.0f ? out.threshold[i] : 3.0e38f;
      scratch.contribution_[entries] = out.has_area[i] != 0 ? out.contribution[i] : 0.0f;
      scratch.slot_[entries] = static_cast<std::uint32_t>(base + i);
      entries += static_cast<std::size_t>(out.member[i]);
      general_lanes[general_count] = static_cast<std::uint32_t>(i);
      general_count += static_cast<std::size_t>(out.general[i]);
    }
    for (std::size_t g = 0; g < general_count; ++g) {
      const std::uint32_t i = general_lanes[g];
      depth.splat_projected(out.u[i], out.v[i], out.iz[i], out.du[i], out.dv[i], out.rpx[i]);
    }
  }
  scratch.entry_count_ = entries;
}

Status CriterionModelView::evaluate(const Viewpoint& view, const PinholeIntrinsics& intrinsics,
                                    CriterionScratchView& scratch, double* F_out) const {
  ViewSetup setup;
  const Status status = prepare(view, intrinsics, scratch, &setup);
  if (!ok(status)) return status;
  render(setup, scratch);
  // Level 3: the depth test and the sum; four accumulators break the dependency chain.
  const float* __restrict buffer = scratch.depth().inverse_depth_data();
  const std::int32_t* __restrict pixel = scratch.pixel_;
  const float* __restrict threshold = scratch.threshold_;
  const float* __restrict contribution = scratch.contribution_;
  const std::size_t n = scratch.entry_count_;
  double sum[4] = {0.0, 0.0, 0.0, 0.0};
  std::size_t e = 0;
  for (; e + 4 <= n; e += 4) {
    for (std::size_t l = 0; l < 4; ++l) {
      sum[l] += buffer[pixel[e + l]] <= threshold[e + l] ? contribution[e + l] : 0.0f;
    }
  }
  for (; e < n; ++e) sum[0] += buffer[pixel[e]] <= threshold[e] ? contribution[e] : 0.0f;
  const double scale2 = scale_ * scale_;
  *F_out = (sum[0] + sum[1] + sum[2] + sum[3]) * scale2;
  return Status::kOk;
}

Status CriterionModelView::visible_primitives(const Viewpoint& view, const PinholeIntrinsics& intrinsics,
                                              CriterionScratchView& scratch, Span<PrimitiveIndex> out,
                                              std::size_t* count_out) const {
  *count_out = 0;
  ViewSetup setup;
  const Status status = prepare(view, intrinsics, scratch, &setup);
  if (!ok(status)) return status;
  render(setup, scratch);
  const float* buffer = scratch.depth().inverse_depth_data();
  std::size_t count = 0;
  for (std::size_t e = 0; e < scratch.entry_count_; ++e) {
    if (!(buffer[scratch.pixel_[e]] <= scratch.threshold_[e])) continue;
    if (count < out.size()) out[count] = arrays_.index[scratch.slot_[e]];
    ++count;
  }
  *count_out = count;
  return count <= out.size() ? Status::kOk : Status::kPoolFull;
}

Status CriterionModelView::primitive_terms(const Viewpoint& view, const PinholeIntrinsics& intrinsics,
                                           CriterionScratchView& scratch, PrimitiveIndex index,
                                           CriterionTerms* out) const {
  std::size_t slot = count_;
  for (std::size_t s = 0; s < count_; ++s) {
    if (arrays_.index[s] == index) {
      slot = s;
      break;
    }
  }
  if (slot == count_) return Status::kNotFound;
  ViewSetup setup;
  const Status status = prepare(view, intrinsics, scratch, &setup);
  if (!ok(status)) return status;
  render(setup, scratch);
  const float* buffer = scratch.depth().inverse_depth_data();
  bool visible = false;
  for (std::size_t e = 0; e < scratch.entry_count_; ++e) {
    if (scratch.slot_[e] == slot) {
      visible = buffer[scratch.pixel_[e]] <= scratch.threshold_[e];
      break;
    }
  }
  // Double-precision terms from the cached (float) slot data, in true units.
  const Eigen::Vector3d X(arrays_.x[slot], arrays_.y[slot], arrays_.z[slot]);
  const Eigen::Vector3d n(arrays_.nx[slot], arrays_.ny[slot], arrays_.nz[slot]);
  Eigen::Matrix3d S;
  S << arrays_.s00[slot], arrays_.s01[slot], arrays_.s02[slot], arrays_.s01[slot], arrays_.s11[slot],
      arrays_.s12[slot], arrays_.s02[slot], arrays_.s12[slot], arrays_.s22[slot];
  const Eigen::Vector3d to_primitive = X - view.position_world;
  const Eigen::Vector3d v = to_primitive.normalized();
  const double h = arrays_.h[slot];
  const double radius = arrays_.radius[slot];
  const double log2_area = radius > 0.0 ? std::log2(3.14159265358979323846 * radius * radius) : 0.0;
  CriterionTerms t;
  t.h = h;
  t.w = std::exp2(static_cast<double>(arrays_.log2_wa[slot]) - h * log2_area) * scale_ * scale_ * scale_;
  t.f = (S * v).norm() * scale_;  // || v^T Psi || = || Sigma v ||
  t.visible = visible;
  if (visible && radius > 0.0) {
    const double z = (view.R_world_cam.transpose() * to_primitive).z();
    const double facing = -n.dot(to_primitive);
    t.g_px2 = 3.14159265358979323846 * radius * radius * intrinsics.fx_px * intrinsics.fy_px * facing / (z * z * z);
    t.contribution = t.w * std::pow(t.g_px2, h) / t.f;
  }
  *out = t;
  return Status::kOk;
}

}  // namespace vantage
