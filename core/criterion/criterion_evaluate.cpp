// View evaluation of the criterion: cluster culling, splatting, depth test, sum (see criterion_model.hpp).
#include <cmath>

#include "core/criterion/criterion_model.hpp"
#include "core/criterion/block_kernel.hpp"

namespace vantage {

static_assert(criterion_kernel::kLanes == kClusterSize, "the kernels run one cluster per block");

struct CriterionModelView::ViewSetup {
  PinholeIntrinsics intrinsics;  // the camera's, for g in its pixels
  float log2_fxfy = 0.0f;        // log2(fx * fy) of the camera
  criterion_kernel::Functions kernel{};
  criterion_kernel::ViewConstants constants{};
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

criterion_kernel::Slots kernel_slots(const CriterionArrays& a) {
  return criterion_kernel::Slots{a.x,   a.y,   a.z,   a.nx,      a.ny, a.nz,     a.s00,   a.s01,
                                 a.s02, a.s11, a.s12, a.s22, a.log2_wa, a.h, a.radius};
}

criterion_kernel::Bounds kernel_bounds(const ClusterArrays& a) {
  return criterion_kernel::Bounds{a.centre_x, a.centre_y, a.centre_z, a.radius,        a.axis_x,
                                  a.axis_y,   a.axis_z,   a.sin_half_angle, a.cos_half_angle};
}

criterion_kernel::Functions criterion_kernel_functions(CriterionKernel kernel) {
  namespace ck = criterion_kernel;
#if VANTAGE_CRITERION_HAS_AVX2_KERNEL
  if (kernel == CriterionKernel::kAvx2Fma) return {ck::avx2_fma::cull, ck::avx2_fma::render, ck::avx2_fma::sum_visible};
#endif
  (void)kernel;
  return {ck::baseline::cull, ck::baseline::render, ck::baseline::sum_visible};
}

}  // namespace

const char* to_string(CriterionKernel kernel) {
  switch (kernel) {
    case CriterionKernel::kAuto:
      return "auto";
    case CriterionKernel::kBaseline:
#if defined(__x86_64__)
      return "baseline (SSE2)";
#elif defined(__aarch64__)
      return "baseline (NEON)";
#else
      return "baseline";
#endif
    case CriterionKernel::kAvx2Fma:
      return "AVX2+FMA";
  }
  return "unknown";
}

bool criterion_kernel_supported(CriterionKernel kernel) {
  switch (kernel) {
    case CriterionKernel::kAuto:
    case CriterionKernel::kBaseline:
      return true;
    case CriterionKernel::kAvx2Fma:
#if VANTAGE_CRITERION_HAS_AVX2_KERNEL
      // libgcc's CPU model; it also checks that the OS saves the AVX registers.
      __builtin_cpu_init();
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
      return false;
#endif
  }
  return false;
}

CriterionKernel best_criterion_kernel() {
  return criterion_kernel_supported(CriterionKernel::kAvx2Fma) ? CriterionKernel::kAvx2Fma : CriterionKernel::kBaseline;
}

Status CriterionScratchView::select_kernel(CriterionKernel kernel) {
  if (!criterion_kernel_supported(kernel)) return Status::kInvalidArgument;
  kernel_ = kernel;
  return Status::kOk;
}

CriterionKernel CriterionScratchView::kernel() const {
  return kernel_ == CriterionKernel::kAuto ? best_criterion_kernel() : kernel_;
}

Status CriterionModelView::prepare(const Viewpoint& view, const PinholeIntrinsics& intrinsics,
                                   CriterionScratchView& scratch, ViewSetup* setup) const {
  if (scratch.capacity() < round_up_to_clusters(count_)) return Status::kInvalidArgument;
  const Status configured = scratch.depth().configure(view, intrinsics);  // validates pose and intrinsics
  if (!ok(configured)) return configured;
  setup->intrinsics = intrinsics;
  setup->log2_fxfy = static_cast<float>(std::log2(intrinsics.fx_px * intrinsics.fy_px));
  setup->kernel = criterion_kernel_functions(scratch.kernel());
  return Status::kOk;
}

void CriterionModelView::render(ViewSetup& setup, CriterionScratchView& scratch) const {
  DepthBufferView& depth = scratch.depth();
  const BufferCamera cam = depth.camera();
  const Eigen::Matrix3f R = depth.R_cam_world();
  const Eigen::Vector3f camera = depth.position_world();
  const Frustum frustum = make_frustum(cam);

  criterion_kernel::ViewConstants& kc = setup.constants;
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
  kc.height = cam.height_px;
  kc.spare = depth.spare_index();
  kc.tolerance_radii = depth.tolerance_radii();
  kc.relative_tolerance = kRelativeDepthTolerance;
  kc.near_depth = kNearDepth;
  kc.grazing_cosine2 = kGrazingCosine * kGrazingCosine;
  kc.log2_fxfy = setup.log2_fxfy;
  kc.left_x = frustum.normal[0].x(), kc.left_z = frustum.normal[0].z();
  kc.right_x = frustum.normal[1].x(), kc.right_z = frustum.normal[1].z();
  kc.top_y = frustum.normal[2].y(), kc.top_z = frustum.normal[2].z();
  kc.bottom_y = frustum.normal[3].y(), kc.bottom_z = frustum.normal[3].z();

  // Level 1: clusters. Level 2: primitives of the kept clusters, a cluster at a time.
  const std::size_t cluster_total = cluster_count();
  const std::size_t kept = setup.kernel.cull(kernel_bounds(arrays_.clusters), kc, cluster_total, scratch.clusters_);
  scratch.clusters_total_ = cluster_total;
  scratch.clusters_kept_ = kept;
  const criterion_kernel::Target target{depth.inverse_depth_data(), scratch.pixel_, scratch.threshold_};
  scratch.clusters_rendered_ =
      setup.kernel.render(kernel_slots(arrays_), kc, scratch.clusters_, kept, target, &scratch.candidates_);
}

Status CriterionModelView::evaluate(const Viewpoint& view, const PinholeIntrinsics& intrinsics,
                                    CriterionScratchView& scratch, double* F_out) const {
  ViewSetup setup;
  const Status status = prepare(view, intrinsics, scratch, &setup);
  if (!ok(status)) return status;
  render(setup, scratch);
  // Level 3: the depth test, and the weights of the clusters with a visible lane.
  const criterion_kernel::Target target{scratch.depth().inverse_depth_data(), scratch.pixel_, scratch.threshold_};
  const double sum =
      setup.kernel.sum_visible(kernel_slots(arrays_), setup.constants, scratch.clusters_, scratch.clusters_rendered_, target);
  *F_out = sum * scale_ * scale_;
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
  const std::size_t entries = scratch.clusters_rendered_ * kClusterSize;
  for (std::size_t e = 0; e < entries; ++e) {
    if (!(buffer[scratch.pixel_[e]] <= scratch.threshold_[e])) continue;
    const std::size_t slot = static_cast<std::size_t>(scratch.clusters_[e / kClusterSize]) * kClusterSize + e % kClusterSize;
    if (count < out.size()) out[count] = arrays_.index[slot];
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
  for (std::size_t k = 0; k < scratch.clusters_rendered_; ++k) {
    if (scratch.clusters_[k] == slot / kClusterSize) {
      const std::size_t e = k * kClusterSize + slot % kClusterSize;
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
