// View evaluation of the criterion: cluster culling, splatting, depth test, sum (see criterion_model.hpp).
#include <cmath>

#include "core/criterion/criterion_model.hpp"
#include "core/criterion/fast_math.hpp"

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
  const float r00 = R(0, 0), r01 = R(0, 1), r02 = R(0, 2);
  const float r10 = R(1, 0), r11 = R(1, 1), r12 = R(1, 2);
  const float r20 = R(2, 0), r21 = R(2, 1), r22 = R(2, 2);
  const float cam_x = camera.x(), cam_y = camera.y(), cam_z = camera.z();
  const float fx = cam.fx_px, fy = cam.fy_px, cx = cam.cx_px, cy = cam.cy_px;
  const float inv_fx = 1.0f / fx, inv_fy = 1.0f / fy;
  const float f_max = fx > fy ? fx : fy;
  const float u_max = static_cast<float>(cam.width_px) - 0.5f;
  const float v_max = static_cast<float>(cam.height_px) - 0.5f;
  const float u_clamp = static_cast<float>(cam.width_px);
  const float v_clamp = static_cast<float>(cam.height_px);
  const std::int32_t width = cam.width_px;
  const float grazing2 = kGrazingCosine * kGrazingCosine;
  const float tolerance_radii = depth.tolerance_radii();
  const float log2_fxfy = setup.log2_fxfy;

  const std::int32_t spare = depth.spare_index();

  // Per block of kClusterSize lanes: geometry for the splat and the depth test of each lane, the fast
  // single-pixel splat as a branch-free (pixel, value) pair (lanes that must not write aim at the
  // buffer's spare cell), and the lane's weight w C (computed on every lane, kept on members only).
  alignas(64) float block_u[kClusterSize];
  alignas(64) float block_v[kClusterSize];
  alignas(64) float block_iz[kClusterSize];
  alignas(64) float block_du[kClusterSize];
  alignas(64) float block_dv[kClusterSize];
  alignas(64) float block_rpx[kClusterSize];
  alignas(64) float block_iz_pixel[kClusterSize];
  alignas(64) float block_threshold[kClusterSize];
  alignas(64) float block_contribution[kClusterSize];
  alignas(64) std::int32_t block_pixel[kClusterSize];
  alignas(64) std::int32_t block_write_pixel[kClusterSize];
  alignas(64) std::int32_t block_general[kClusterSize];
  alignas(64) std::int32_t block_member[kClusterSize];
  alignas(64) std::int32_t block_has_area[kClusterSize];
  std::uint32_t general_lanes[kClusterSize];

  float* __restrict buffer = depth.inverse_depth_data();
  // The block loop uses & on comparisons, not &&: short-circuit control flow stops the vectorizer.
  std::size_t entries = 0;
  for (std::size_t k = 0; k < kept; ++k) {
    const std::size_t base = static_cast<std::size_t>(scratch.clusters_[k]) * kClusterSize;
    const float* __restrict px = arrays_.x + base;
    const float* __restrict py = arrays_.y + base;
    const float* __restrict pz = arrays_.z + base;
    const float* __restrict nx = arrays_.nx + base;
    const float* __restrict ny = arrays_.ny + base;
    const float* __restrict nz = arrays_.nz + base;
    const float* __restrict s00 = arrays_.s00 + base;
    const float* __restrict s01 = arrays_.s01 + base;
    const float* __restrict s02 = arrays_.s02 + base;
    const float* __restrict s11 = arrays_.s11 + base;
    const float* __restrict s12 = arrays_.s12 + base;
    const float* __restrict s22 = arrays_.s22 + base;
    const float* __restrict lwa = arrays_.log2_wa + base;
    const float* __restrict hh = arrays_.h + base;
    const float* __restrict rr = arrays_.radius + base;
    for (std::size_t i = 0; i < kClusterSize; ++i) {
      const float ux = px[i] - cam_x;
      const float uy = py[i] - cam_y;
      const float uz = pz[i] - cam_z;
      const float xc = r00 * ux + r01 * uy + r02 * uz;
      const float yc = r10 * ux + r11 * uy + r12 * uz;
      const float zc = r20 * ux + r21 * uy + r22 * uz;
      const float facing = -(nx[i] * ux + ny[i] * uy + nz[i] * uz);  // n . (camera - X)
      const float ncx = r00 * nx[i] + r01 * ny[i] + r02 * nz[i];
      const float ncy = r10 * nx[i] + r11 * ny[i] + r12 * nz[i];
      const float dist2 = ux * ux + uy * uy + uz * uz;
      const bool front = (zc > kNearDepth) & (facing > 0.0f);
      // Divisions, logs and roots run on every lane, unmasked: a lane behind the camera or facing away
      // computes garbage that the masks drop. This file is compiled with -fno-trapping-math and
      // -fno-math-errno (core/CMakeLists.txt): otherwise GCC will not speculate them and leaves the
      // loop scalar.
      const float inv_z = 1.0f / zc;
      const float u = fx * xc * inv_z + cx;
      const float v = fy * yc * inv_z + cy;
      // 1/z gradients of the disc's plane n_cam . X = k with k = -facing (see splat_math).
      const bool grazing = facing * facing < grazing2 * dist2;
      const float minus_inv_facing = -1.0f / facing;
      const float inv_k = grazing ? 0.0f : minus_inv_facing;
      const float du = ncx * inv_k * inv_fx;
      const float dv = ncy * inv_k * inv_fy;
      const float radius = rr[i];
      const float radius_px = radius * f_max * inv_z;
      const bool in_image = (u >= -0.5f) & (v >= -0.5f) & (u < u_max) & (v < v_max);
      float uc = u > -1.0f ? u : -1.0f;
      uc = uc < u_clamp ? uc : u_clamp;
      float vc = v > -1.0f ? v : -1.0f;
      vc = vc < v_clamp ? vc : v_clamp;
      const std::int32_t pi = static_cast<std::int32_t>(uc + 0.5f);
      const std::int32_t pj = static_cast<std::int32_t>(vc + 0.5f);
      const std::int32_t pixel = pj * width + pi;
      const float iz_pixel = inv_z + du * (static_cast<float>(pi) - u) + dv * (static_cast<float>(pj) - v);
      // splat_math::visibility_threshold, inlined: one division, and the select on its sign happens in
      // the append loop (<= 0 means the tolerance reaches the camera: always visible).
      const float threshold = iz_pixel / (1.0f - kRelativeDepthTolerance - tolerance_radii * radius * iz_pixel);
      // f = |Sigma v|: with Sigma' = Sigma / scale, f' = |Sigma' u| / |u|, u = X - x (never negative in
      // float, unlike a stored Sigma^2).
      const float su_x = s00[i] * ux + s01[i] * uy + s02[i] * uz;
      const float su_y = s01[i] * ux + s11[i] * uy + s12[i] * uz;
      const float su_z = s02[i] * ux + s12[i] * uy + s22[i] * uz;
      const float qu = su_x * su_x + su_y * su_y + su_z * su_z;
      // w C = 2^(log2(w' (pi r^2)^h) + h log2(fx fy facing / z^3)) * |u| / |Sigma' u|.
      const float log2_g_rest = fast::log2(facing * inv_z * inv_z * inv_z);
      const float weight = fast::exp2(lwa[i] + hh[i] * (log2_fxfy + log2_g_rest)) * std::sqrt(dist2 / qu);
      const bool member = front & in_image;
      const bool fast_splat = member & (radius_px < 0.5f);
      block_u[i] = u;
      block_v[i] = v;
      block_iz[i] = inv_z;
      block_du[i] = du;
      block_dv[i] = dv;
      block_rpx[i] = radius_px;
      block_iz_pixel[i] = iz_pixel;
      block_threshold[i] = threshold;
      block_contribution[i] = weight;  // raw: masked in the scalar loop (a select here makes GCC branch)
      block_has_area[i] = radius > 0.0f ? 1 : 0;
      block_pixel[i] = pixel;
      block_write_pixel[i] = fast_splat ? pixel : spare;
      // Larger or off-centre footprints go to the general splat, unless the square misses the image.
      const bool overlaps = (u + radius_px >= -0.5f) & (v + radius_px >= -0.5f) & (u - radius_px < u_max) &
                            (v - radius_px < v_max);
      block_general[i] = (front & overlaps & !fast_splat) ? 1 : 0;
      block_member[i] = member ? 1 : 0;
    }
    // Scalar, branch-free: the single-pixel splats, the member entries, and the list of lanes that need
    // the general (multi-pixel or partly outside) splat.
    std::size_t general_count = 0;
    for (std::size_t i = 0; i < kClusterSize; ++i) {
      float& cell = buffer[block_write_pixel[i]];
      const float iz = block_iz_pixel[i];
      cell = iz > cell ? iz : cell;
      scratch.pixel_[entries] = block_pixel[i];
      scratch.threshold_[entries] = block_threshold[i] > 0.0f ? block_threshold[i] : 3.0e38f;
      scratch.contribution_[entries] = block_has_area[i] != 0 ? block_contribution[i] : 0.0f;
      scratch.slot_[entries] = static_cast<std::uint32_t>(base + i);
      entries += static_cast<std::size_t>(block_member[i]);
      general_lanes[general_count] = static_cast<std::uint32_t>(i);
      general_count += static_cast<std::size_t>(block_general[i]);
    }
    for (std::size_t g = 0; g < general_count; ++g) {
      const std::uint32_t i = general_lanes[g];
      depth.splat_projected(block_u[i], block_v[i], block_iz[i], block_du[i], block_dv[i], block_rpx[i]);
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
