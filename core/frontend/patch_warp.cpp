#include "core/frontend/patch_warp.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/frontend/float4.hpp"

#include "core/geometry/projection.hpp"

// The warp's and the template moments' 8-lane AVX passes: x86-64 only, each with a four-lane baseline.
#if defined(__x86_64__)
#define VANTAGE_PATCH_WARP_HAS_AVX 1
#else
#define VANTAGE_PATCH_WARP_HAS_AVX 0
#endif

namespace vantage {

Eigen::Matrix<double, 3, 2> plane_basis(const Eigen::Vector3d& n) {
  const Eigen::Vector3d helper = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  Eigen::Matrix<double, 3, 2> basis;
  basis.col(0) = n.cross(helper).normalized();
  basis.col(1) = n.cross(basis.col(0));
  return basis;
}

Status plane_affine_from_jacobians(const Eigen::Matrix<double, 2, 3>& H_ref, const Eigen::Matrix<double, 2, 3>& H_target,
                                   const Eigen::Vector3f& normal_world, Eigen::Matrix2d* A_ref_per_target,
                                   std::array<Eigen::Matrix2d, 2>* dA) {
  const Eigen::Vector3d n_raw = normal_world.cast<double>();
  const double length = n_raw.norm();
  if (!std::isfinite(length) || std::abs(length - 1.0) > 1e-3) return Status::kInvalidArgument;
  const Eigen::Vector3d n = n_raw / length;
  const Eigen::Matrix<double, 3, 2> basis = plane_basis(n);
  const Eigen::Matrix2d J_ref = H_ref * basis;        // pixels in the reference per unit on the plane
  const Eigen::Matrix2d J_target = H_target * basis;  // pixels in the target per unit on the plane
  const double det = J_target.determinant();
  // Edge-on: the plane's image in the target has (almost) no area.
  if (!(std::abs(det) > 1e-9 * J_target.squaredNorm())) return Status::kInvalidArgument;
  const Eigen::Matrix2d J_target_inv = J_target.inverse();
  const Eigen::Matrix2d A = J_ref * J_target_inv;
  if (!A.allFinite()) return Status::kInvalidArgument;
  *A_ref_per_target = A;
  if (dA != nullptr) {
    const Eigen::Vector2d w = H_ref * n - A * (H_target * n);
    (*dA)[0] = -w * J_target_inv.row(0);
    (*dA)[1] = -w * J_target_inv.row(1);
  }
  return Status::kOk;
}

namespace {

#if VANTAGE_PATCH_WARP_HAS_AVX
// plane_affine_from_jacobians for four primitives in AVX lanes (no FMA), each lane the scalar code's
// operations in the order Eigen evaluates them there (measured on 300,000 random inputs, 0 mismatches;
// the other orders 4,419 to 373,277): 3-vector squared norms and the 3-term products (H E, H n) as
// (a0 b0 + a1 b1) + a2 b2, J_target's squared norm as (j00^2 + j01^2) + (j10^2 + j11^2); the 2-term sums of
// the 2x2 products, the determinant and the inverse as written in Eigen (2-term sums commute exactly); the
// plane basis's helper axis and cross products with its zeros multiplied as Eigen does. Unused lanes
// repeat the first primitive.
__attribute__((target("avx2"))) void plane_affine_lanes4(const Eigen::Matrix<double, 2, 3>* H_ref,
                                                         const Eigen::Matrix<double, 2, 3>* H_target,
                                                         const Eigen::Vector3f* const* normal_world, std::int32_t count,
                                                         Eigen::Matrix2d* A_ref_per_target,
                                                         std::array<Eigen::Matrix2d, 2>* dA, Status* status) {
  using Double4 = double __attribute__((vector_size(32)));
  using Mask4 = std::int64_t __attribute__((vector_size(32)));
  Double4 f0, f1, f2, r[2][3], t[2][3];
  for (std::int32_t lane = 0; lane < 4; ++lane) {
    const std::int32_t k = lane < count ? lane : 0;
    f0[lane] = static_cast<double>(normal_world[k]->x());
    f1[lane] = static_cast<double>(normal_world[k]->y());
    f2[lane] = static_cast<double>(normal_world[k]->z());
    for (int row = 0; row < 2; ++row) {
      for (int col = 0; col < 3; ++col) {
        r[row][col][lane] = H_ref[k](row, col);
        t[row][col][lane] = H_target[k](row, col);
      }
    }
  }
  const Double4 zero = Double4{} + 0.0;
  const Double4 one = zero + 1.0;
  // The normal, unit length within 1e-3, renormalized.
  const Double4 length = __builtin_ia32_sqrtpd256((f0 * f0 + f1 * f1) + f2 * f2);
  const Double4 length_error = length - 1.0;
  const Double4 abs_length_error = length_error < zero ? -length_error : length_error;
  Mask4 valid = (length - length == zero) & (abs_length_error <= 1e-3 + zero);
  const Double4 n0 = f0 / length;
  const Double4 n1 = f1 / length;
  const Double4 n2 = f2 / length;
  // plane_basis: e1 = n x helper normalized (helper the x axis unless n is near it, then the y axis), e2 = n x e1.
  const Mask4 use_x = (n0 < zero ? -n0 : n0) < 0.9 + zero;
  const Double4 h0 = use_x ? one : zero;
  const Double4 h1 = use_x ? zero : one;
  const Double4 h2 = zero;
  const Double4 c0 = n1 * h2 - n2 * h1;
  const Double4 c1 = n2 * h0 - n0 * h2;
  const Double4 c2 = n0 * h1 - n1 * h0;
  const Double4 cc = (c0 * c0 + c1 * c1) + c2 * c2;
  const Double4 c_norm = __builtin_ia32_sqrtpd256(cc);
  const Mask4 positive = cc > zero;
  const Double4 e10 = positive ? c0 / c_norm : c0;
  const Double4 e11 = positive ? c1 / c_norm : c1;
  const Double4 e12 = positive ? c2 / c_norm : c2;
  const Double4 e20 = n1 * e12 - n2 * e11;
  const Double4 e21 = n2 * e10 - n0 * e12;
  const Double4 e22 = n0 * e11 - n1 * e10;
  // J = H E for both views.
  Double4 jr[2][2], jt[2][2], hrn[2], htn[2];
  for (int row = 0; row < 2; ++row) {
    jr[row][0] = (r[row][0] * e10 + r[row][1] * e11) + r[row][2] * e12;
    jr[row][1] = (r[row][0] * e20 + r[row][1] * e21) + r[row][2] * e22;
    jt[row][0] = (t[row][0] * e10 + t[row][1] * e11) + t[row][2] * e12;
    jt[row][1] = (t[row][0] * e20 + t[row][1] * e21) + t[row][2] * e22;
    hrn[row] = (r[row][0] * n0 + r[row][1] * n1) + r[row][2] * n2;
    htn[row] = (t[row][0] * n0 + t[row][1] * n1) + t[row][2] * n2;
  }
  const Double4 det = jt[0][0] * jt[1][1] - jt[1][0] * jt[0][1];
  const Double4 squared_norm = (jt[0][0] * jt[0][0] + jt[0][1] * jt[0][1]) + (jt[1][0] * jt[1][0] + jt[1][1] * jt[1][1]);
  valid &= (det < zero ? -det : det) > 1e-9 * squared_norm;
  const Double4 inv_det = 1.0 / det;
  Double4 inv[2][2];
  inv[0][0] = jt[1][1] * inv_det;
  inv[1][0] = -jt[1][0] * inv_det;
  inv[0][1] = -jt[0][1] * inv_det;
  inv[1][1] = jt[0][0] * inv_det;
  Double4 a[2][2];
  for (int row = 0; row < 2; ++row) {
    for (int col = 0; col < 2; ++col) {
      a[row][col] = jr[row][0] * inv[0][col] + jr[row][1] * inv[1][col];
      valid &= a[row][col] - a[row][col] == zero;
    }
  }
  // dA_k = -w (row k of J_target^-1), w = H_ref n - A H_target n.
  Double4 minus_w[2];
  for (int row = 0; row < 2; ++row) minus_w[row] = -(hrn[row] - (a[row][0] * htn[0] + a[row][1] * htn[1]));
  for (std::int32_t lane = 0; lane < count; ++lane) {
    if (valid[lane] == 0) {
      status[lane] = Status::kInvalidArgument;
      continue;
    }
    status[lane] = Status::kOk;
    A_ref_per_target[lane] << a[0][0][lane], a[0][1][lane], a[1][0][lane], a[1][1][lane];
    if (dA == nullptr) continue;
    for (int k = 0; k < 2; ++k) {
      dA[lane][k] << minus_w[0][lane] * inv[k][0][lane], minus_w[0][lane] * inv[k][1][lane],
          minus_w[1][lane] * inv[k][0][lane], minus_w[1][lane] * inv[k][1][lane];
    }
  }
}
#endif

}  // namespace

void plane_affine_from_jacobians_batch(const Eigen::Matrix<double, 2, 3>* H_ref,
                                       const Eigen::Matrix<double, 2, 3>* H_target,
                                       const Eigen::Vector3f* const* normal_world, std::int32_t count,
                                       Eigen::Matrix2d* A_ref_per_target, std::array<Eigen::Matrix2d, 2>* dA,
                                       Status* status) {
  if (count <= 0) return;
  if (count > kPlaneAffineBatchSize) count = kPlaneAffineBatchSize;
#if VANTAGE_PATCH_WARP_HAS_AVX
  if (__builtin_cpu_supports("avx2")) {
    plane_affine_lanes4(H_ref, H_target, normal_world, count, A_ref_per_target, dA, status);
    return;
  }
#endif
  for (std::int32_t i = 0; i < count; ++i) {
    status[i] = plane_affine_from_jacobians(H_ref[i], H_target[i], *normal_world[i], &A_ref_per_target[i],
                                            dA != nullptr ? &dA[i] : nullptr);
  }
}

namespace {

// plane_affine_from_jacobians with the Jacobians of X's projections into both views.
Status plane_affine_projected(const Eigen::Vector3d& X_world, const Eigen::Vector3f& normal_world,
                              const Viewpoint& reference, const Viewpoint& target, const PinholeIntrinsics& intrinsics,
                              Eigen::Matrix2d* A_ref_per_target, std::array<Eigen::Matrix2d, 2>* dA) {
  Eigen::Vector2d unused;
  Eigen::Matrix<double, 2, 3> H_ref;
  Eigen::Matrix<double, 2, 3> H_target;
  Status status = project_with_jacobian(X_world, reference, intrinsics, &unused, &H_ref);
  if (!ok(status)) return status;
  status = project_with_jacobian(X_world, target, intrinsics, &unused, &H_target);
  if (!ok(status)) return status;
  return plane_affine_from_jacobians(H_ref, H_target, normal_world, A_ref_per_target, dA);
}

}  // namespace

Status plane_affine(const Eigen::Vector3d& X_world, const Eigen::Vector3f& normal_world, const Viewpoint& reference,
                    const Viewpoint& target, const PinholeIntrinsics& intrinsics, Eigen::Matrix2d* A_ref_per_target) {
  const Eigen::Vector3d n = normal_world.cast<double>();
  if (!n.allFinite() || std::abs(n.norm() - 1.0) > 1e-3) return Status::kInvalidArgument;
  return plane_affine_projected(X_world, normal_world, reference, target, intrinsics, A_ref_per_target, nullptr);
}

namespace {

// {a[0], a[1], b[0], b[1]}: two 8-byte loads.
inline Float4 pair_of_pairs(const float* a, const float* b) {
  using Float2 = float __attribute__((vector_size(8)));
  Float2 pa;
  Float2 pb;
  std::memcpy(&pa, a, sizeof pa);
  std::memcpy(&pb, b, sizeof pb);
  return __builtin_shufflevector(pa, pb, 0, 1, 2, 3);
}

// Whether the 8-lane passes run: not for kBaseline, and only where the CPU has AVX2. libgcc's CPU model
// is set up by its constructor before main (match_kernel_supported's explicit initialization and kernel
// mapping would cost as much per template as the unmasked 8-lane pass saves).
#if VANTAGE_PATCH_WARP_HAS_AVX
bool use_avx2(MatchKernel kernel) { return kernel != MatchKernel::kBaseline && __builtin_cpu_supports("avx2"); }
#endif

// The warp's sampling into gray and mask (row-major p x p plus spill lanes), four target pixels at a
// time: the values are gray levels, the offsets a few pixels.
void warp_lanes4(const float* source, const Eigen::Matrix2d& A, float* gray, float* mask) {
  const Float4 limit = splat4(static_cast<float>(kPatchRadius));  // the stored patch covers offsets [-r, r]
  const Float4 a00 = splat4(static_cast<float>(A(0, 0)));
  const Float4 a01 = splat4(static_cast<float>(A(0, 1)));
  const Float4 a10 = splat4(static_cast<float>(A(1, 0)));
  const Float4 a11 = splat4(static_cast<float>(A(1, 1)));
  const Float4 zero = splat4(0.0f);
  const Float4 dx_of_group[2] = {Float4{-3.0f, -2.0f, -1.0f, 0.0f}, Float4{1.0f, 2.0f, 3.0f, 3.0f}};
  const Int4 lane_used[2] = {Int4{-1, -1, -1, -1}, Int4{-1, -1, -1, 0}};
  const Int4 last_cell = Int4{kPatchSize - 2, kPatchSize - 2, kPatchSize - 2, kPatchSize - 2};
  for (int ty = 0; ty < kPatchSize; ++ty) {
    const Float4 dy = splat4(static_cast<float>(ty - kPatchRadius));
    for (int group = 0; group < 2; ++group) {
      const Float4 ox = a00 * dx_of_group[group] + a01 * dy;
      const Float4 oy = a10 * dx_of_group[group] + a11 * dy;
      const Int4 inside = (ox <= limit) & (ox >= -limit) & (oy <= limit) & (oy >= -limit) & lane_used[group];
      // Outside lanes sample the corner (finite, then masked).
      const Float4 sx = inside ? ox + limit : zero;
      const Float4 sy = inside ? oy + limit : zero;
      Int4 x0 = __builtin_convertvector(sx, Int4);  // sx >= 0: truncation is floor
      Int4 y0 = __builtin_convertvector(sy, Int4);
      x0 = x0 > last_cell ? last_cell : x0;
      y0 = y0 > last_cell ? last_cell : y0;
      const Float4 fx = sx - __builtin_convertvector(x0, Float4);
      const Float4 fy = sy - __builtin_convertvector(y0, Float4);
      const Int4 base = y0 * kPatchSize + x0;
      // Each lane's two horizontal neighbours are adjacent floats: one 8-byte load per lane and row,
      // two lanes' pairs per vector, then the left and right values split by a shuffle.
      const Float4 top01 = pair_of_pairs(&source[base[0]], &source[base[1]]);
      const Float4 top23 = pair_of_pairs(&source[base[2]], &source[base[3]]);
      const Float4 bottom01 = pair_of_pairs(&source[base[0] + kPatchSize], &source[base[1] + kPatchSize]);
      const Float4 bottom23 = pair_of_pairs(&source[base[2] + kPatchSize], &source[base[3] + kPatchSize]);
      const Float4 top_left = __builtin_shufflevector(top01, top23, 0, 2, 4, 6);
      const Float4 top_right = __builtin_shufflevector(top01, top23, 1, 3, 5, 7);
      const Float4 bottom_left = __builtin_shufflevector(bottom01, bottom23, 0, 2, 4, 6);
      const Float4 bottom_right = __builtin_shufflevector(bottom01, bottom23, 1, 3, 5, 7);
      const Float4 top = top_left + fx * (top_right - top_left);
      const Float4 bottom = bottom_left + fx * (bottom_right - bottom_left);
      const int i = ty * kPatchSize + 4 * group;
      store4(&gray[i], inside ? top + fy * (bottom - top) : zero);
      store4(&mask[i], inside ? splat4(1.0f) : zero);
    }
  }
}

#if VANTAGE_PATCH_WARP_HAS_AVX
// The same with a template row as one group of 8 AVX lanes (the eighth unused): each lane does the
// four-lane form's operations in its order, without FMA (not enabled here), so the same bits. No
// lambdas or helpers taking 8-lane vectors: they would not inherit the target attribute.
__attribute__((target("avx2"))) void warp_lanes8(const float* source, const Eigen::Matrix2d& A, float* gray,
                                                 float* mask) {
  using Float8 = float __attribute__((vector_size(32)));
  using Int8 = std::int32_t __attribute__((vector_size(32)));
  const Float8 limit = Float8{} + static_cast<float>(kPatchRadius);
  const Float8 a00 = Float8{} + static_cast<float>(A(0, 0));
  const Float8 a01 = Float8{} + static_cast<float>(A(0, 1));
  const Float8 a10 = Float8{} + static_cast<float>(A(1, 0));
  const Float8 a11 = Float8{} + static_cast<float>(A(1, 1));
  const Float8 zero = Float8{};
  const Float8 one = Float8{} + 1.0f;
  const Float8 dx = Float8{-3.0f, -2.0f, -1.0f, 0.0f, 1.0f, 2.0f, 3.0f, 3.0f};
  const Int8 lane_used = Int8{-1, -1, -1, -1, -1, -1, -1, 0};
  const Int8 lane_all_set = Int8{} - 1;
  const Int8 last_cell = Int8{} + (kPatchSize - 2);
  const Float8 gather_all = reinterpret_cast<Float8>(lane_all_set);  // every lane gathered
  for (int ty = 0; ty < kPatchSize; ++ty) {
    const Float8 dy = Float8{} + static_cast<float>(ty - kPatchRadius);
    const Float8 ox = a00 * dx + a01 * dy;
    const Float8 oy = a10 * dx + a11 * dy;
    const Int8 inside = (ox <= limit) & (ox >= -limit) & (oy <= limit) & (oy >= -limit) & lane_used;
    const Float8 sx = inside ? ox + limit : zero;
    const Float8 sy = inside ? oy + limit : zero;
    Int8 x0 = __builtin_convertvector(sx, Int8);
    Int8 y0 = __builtin_convertvector(sy, Int8);
    x0 = x0 > last_cell ? last_cell : x0;
    y0 = y0 > last_cell ? last_cell : y0;
    const Float8 fx = sx - __builtin_convertvector(x0, Float8);
    const Float8 fy = sy - __builtin_convertvector(y0, Float8);
    const Int8 base = y0 * kPatchSize + x0;
    // The four neighbours of every lane by AVX2 gathers (vgatherdps; GCC's builtin, no intrinsics
    // header): the same values the scalar loads read. Indices stay below 5 * 7 + 5 + 8 < 64.
    const Float8 top_left = __builtin_ia32_gathersiv8sf(zero, source, base, gather_all, 4);
    const Float8 top_right = __builtin_ia32_gathersiv8sf(zero, source, base + 1, gather_all, 4);
    const Float8 bottom_left = __builtin_ia32_gathersiv8sf(zero, source, base + kPatchSize, gather_all, 4);
    const Float8 bottom_right = __builtin_ia32_gathersiv8sf(zero, source, base + (kPatchSize + 1), gather_all, 4);
    const Float8 top = top_left + fx * (top_right - top_left);
    const Float8 bottom = bottom_left + fx * (bottom_right - bottom_left);
    const Float8 value = inside ? top + fy * (bottom - top) : zero;
    const Float8 valid = inside ? one : zero;
    __builtin_memcpy(&gray[ty * kPatchSize], &value, sizeof value);
    __builtin_memcpy(&mask[ty * kPatchSize], &valid, sizeof valid);
  }
}
#endif

}  // namespace

void warp_patch_template(const std::array<std::uint8_t, kPatchPixels>& patch, const Eigen::Matrix2d& A,
                         NccTemplate* out) {
  static_assert(kPatchSize == 7, "two four-lane groups (one 8-lane group) per template row");
  alignas(16) float source[64];
  bytes_to_floats(patch.data(), kPatchPixels, kPatchPixels, source, 64);
  // Row-major p x p plus one lane: the last group of a row spills into the next row's first pixel,
  // which that row's first group then writes.
  alignas(16) float gray[kPatchPixels + 3] = {};
  alignas(16) float mask[kPatchPixels + 3] = {};
#if VANTAGE_PATCH_WARP_HAS_AVX
  if (use_avx2(MatchKernel::kAuto)) warp_lanes8(source, A, gray, mask); else
#endif
  warp_lanes4(source, A, gray, mask);
  std::array<float, kPatchPixels> gray_out;
  std::array<float, kPatchPixels> mask_out;
  std::memcpy(gray_out.data(), gray, sizeof gray_out);
  std::memcpy(mask_out.data(), mask, sizeof mask_out);
  make_template(gray_out, mask_out, out);
}

Status plane_affine_tilt_derivatives(const Eigen::Vector3d& X_world, const Eigen::Vector3f& normal_world,
                                     const Viewpoint& reference, const Viewpoint& target,
                                     const PinholeIntrinsics& intrinsics, const Eigen::Matrix2d& A_ref_per_target,
                                     std::array<Eigen::Matrix2d, 2>* dA) {
  (void)A_ref_per_target;  // recomputed with the Jacobians: the same map
  const Eigen::Vector3f n = normal_world.normalized();
  if (!n.allFinite()) return Status::kInvalidArgument;
  Eigen::Matrix2d A;
  return plane_affine_projected(X_world, n, reference, target, intrinsics, &A, dA);
}

namespace {

// {sum_lanes(a), sum_lanes(b), sum_lanes(c), sum_lanes(d)}: the four vectors transposed, then each lane
// adds (v0 + v1) + (v2 + v3) as sum_lanes does, so the same bits in a third of the instructions.
inline Float4 sum_lanes_of_four(Float4 a, Float4 b, Float4 c, Float4 d) {
  const Float4 ab_low = __builtin_shufflevector(a, b, 0, 4, 1, 5);   // a0 b0 a1 b1
  const Float4 cd_low = __builtin_shufflevector(c, d, 0, 4, 1, 5);   // c0 d0 c1 d1
  const Float4 ab_high = __builtin_shufflevector(a, b, 2, 6, 3, 7);  // a2 b2 a3 b3
  const Float4 cd_high = __builtin_shufflevector(c, d, 2, 6, 3, 7);  // c2 d2 c3 d3
  const Float4 lane0 = __builtin_shufflevector(ab_low, cd_low, 0, 1, 4, 5);
  const Float4 lane1 = __builtin_shufflevector(ab_low, cd_low, 2, 3, 6, 7);
  const Float4 lane2 = __builtin_shufflevector(ab_high, cd_high, 0, 1, 4, 5);
  const Float4 lane3 = __builtin_shufflevector(ab_high, cd_high, 2, 3, 6, 7);
  return (lane0 + lane1) + (lane2 + lane3);
}

// The moments from the lane sums of g g^T (xx, xy, yy) of the two lane groups of each row (columns
// x = -3..0 and 1..4) and the running sums of their cumulative row sums Q (sum_rows P_k =
// sum_y (4 - y) r_y, so My = 4 G - Q), all scaled by `scale`.
void moments_from_lanes(const Float4 (&g_acc)[2][3], const Float4 (&q_acc)[2][3], double scale,
                        TemplateGradientMoments* out) {
  const Float4 x_of_lane[2] = {Float4{-3.0f, -2.0f, -1.0f, 0.0f}, Float4{1.0f, 2.0f, 3.0f, 4.0f}};
  // The nine lane sums four at a time (sum_lanes_of_four: the same bits as sum_lanes one by one).
  const Float4 g_sums = sum_lanes_of_four(g_acc[0][0] + g_acc[1][0], g_acc[0][1] + g_acc[1][1],
                                          g_acc[0][2] + g_acc[1][2], q_acc[0][0] + q_acc[1][0]);
  const Float4 x_sums = sum_lanes_of_four(g_acc[0][0] * x_of_lane[0] + g_acc[1][0] * x_of_lane[1],
                                          g_acc[0][1] * x_of_lane[0] + g_acc[1][1] * x_of_lane[1],
                                          g_acc[0][2] * x_of_lane[0] + g_acc[1][2] * x_of_lane[1],
                                          q_acc[0][1] + q_acc[1][1]);
  const double q_sums[3] = {g_sums[3], x_sums[3], sum_lanes(q_acc[0][2] + q_acc[1][2])};
  double G[3];
  double Mx[3];
  double My[3];
  for (int j = 0; j < 3; ++j) {
    const double g = g_sums[j];
    Mx[j] = scale * x_sums[j];
    My[j] = scale * (4.0 * g - q_sums[j]);
    G[j] = scale * g;
  }
  out->G << G[0], G[1], G[1], G[2];
  out->Mx << Mx[0], Mx[1], Mx[1], Mx[2];
  out->My << My[0], My[1], My[1], My[2];
}

constexpr int kFrameStride = 12;  // row stride of the framed copies: the second lane group's neighbours fit
constexpr int kFrameRows = kPatchSize + 2;

// No pixel masked: extrapolating the frame linearly (v_-1 = 2 v_0 - v_1) turns the one-sided
// differences at the border into central ones, so g = (v_f - v_b) / 2 everywhere (computed as 2 g).
void frame_extrapolated(const NccTemplate& tmpl, float* v) {
  // Read but not written below: the lane past the frame (column 9) of the template's rows; the frame
  // rows' right corners (column 8) are extrapolated with their rows (four lanes at a time). Both are
  // multiplied by zero, they only need to be finite (the frame rows' column 0 and 9 are not read).
  for (int y = 1; y <= kPatchSize; ++y) v[y * kFrameStride + kPatchSize + 2] = 0.0f;
  for (int ty = 0; ty < kPatchSize; ++ty) {
    float* row = &v[(ty + 1) * kFrameStride];
    std::memcpy(row + 1, &tmpl.values[static_cast<std::size_t>(ty * kPatchSize)], kPatchSize * sizeof(float));
    row[0] = 2.0f * row[1] - row[2];
    row[kPatchSize + 1] = 2.0f * row[kPatchSize] - row[kPatchSize - 1];
  }
  const Float4 two = splat4(2.0f);
  for (int x = 1; x <= kPatchSize + 1; x += 4) {
    store4(&v[x], two * load4(&v[kFrameStride + x]) - load4(&v[2 * kFrameStride + x]));
    store4(&v[(kFrameRows - 1) * kFrameStride + x],
           two * load4(&v[(kFrameRows - 2) * kFrameStride + x]) - load4(&v[(kFrameRows - 3) * kFrameStride + x]));
  }
}

// The unmasked pass's lane sums: g g^T (xx, xy, yy) per lane group (x = -3..0 and 1..4) and the
// row-weighted sums for My.
struct UnmaskedLanes {
  Float4 xx0, xy0, yy0, xx1, xy1, yy1, xx_y, xy_y, yy_y;
};

inline __attribute__((always_inline)) void moments_from_unmasked_lanes(const UnmaskedLanes& s,
                                                                        TemplateGradientMoments* out) {
  const Float4 x0 = Float4{-3.0f, -2.0f, -1.0f, 0.0f};
  const Float4 x1 = Float4{1.0f, 2.0f, 3.0f, 4.0f};
  constexpr double kQuarter = 0.25;  // (2 g)^2
  // The nine lane sums, four at a time: {G xx, G xy, G yy, My xx}, {Mx xx, Mx xy, Mx yy, My xy}, My yy.
  const Float4 first = sum_lanes_of_four(s.xx0 + s.xx1, s.xy0 + s.xy1, s.yy0 + s.yy1, s.xx_y);
  const Float4 second = sum_lanes_of_four(s.xx0 * x0 + s.xx1 * x1, s.xy0 * x0 + s.xy1 * x1, s.yy0 * x0 + s.yy1 * x1,
                                          s.xy_y);
  const double G[3] = {kQuarter * first[0], kQuarter * first[1], kQuarter * first[2]};
  const double Mx[3] = {kQuarter * second[0], kQuarter * second[1], kQuarter * second[2]};
  const double My[3] = {kQuarter * first[3], kQuarter * second[3], kQuarter * sum_lanes(s.yy_y)};
  out->G << G[0], G[1], G[1], G[2];
  out->Mx << Mx[0], Mx[1], Mx[1], Mx[2];
  out->My << My[0], My[1], My[1], My[2];
}

// The pass over the framed template in two groups of four lanes per row.
void unmasked_lanes4(const float* v, UnmaskedLanes* out) {
  // The eighth lane of each row (the frame column) must add nothing.
  const Float4 last_lane_off = Float4{1.0f, 1.0f, 1.0f, 0.0f};
  Float4 xx0 = splat4(0.0f), xy0 = xx0, yy0 = xx0, xx1 = xx0, xy1 = xx0, yy1 = xx0;
  Float4 xx_y = xx0, xy_y = xx0, yy_y = xx0;
  for (int ty = 0; ty < kPatchSize; ++ty) {
    const int c0 = (ty + 1) * kFrameStride + 1;
    const int c1 = c0 + 4;
    const Float4 gx0 = load4(&v[c0 + 1]) - load4(&v[c0 - 1]);
    const Float4 gy0 = load4(&v[c0 + kFrameStride]) - load4(&v[c0 - kFrameStride]);
    const Float4 gx1 = (load4(&v[c1 + 1]) - load4(&v[c1 - 1])) * last_lane_off;
    const Float4 gy1 = (load4(&v[c1 + kFrameStride]) - load4(&v[c1 - kFrameStride])) * last_lane_off;
    const Float4 pxx0 = gx0 * gx0, pxy0 = gx0 * gy0, pyy0 = gy0 * gy0;
    const Float4 pxx1 = gx1 * gx1, pxy1 = gx1 * gy1, pyy1 = gy1 * gy1;
    xx0 += pxx0;
    xy0 += pxy0;
    yy0 += pyy0;
    xx1 += pxx1;
    xy1 += pxy1;
    yy1 += pyy1;
    const Float4 y = splat4(static_cast<float>(ty - kPatchRadius));
    xx_y += y * (pxx0 + pxx1);
    xy_y += y * (pxy0 + pxy1);
    yy_y += y * (pyy0 + pyy1);
  }
  *out = UnmaskedLanes{xx0, xy0, yy0, xx1, xy1, yy1, xx_y, xy_y, yy_y};
}

#if VANTAGE_PATCH_WARP_HAS_AVX
// The same pass with a row's two groups as one 8-lane AVX vector, straight from the template's rows (no
// framed copy): the frame's extrapolated columns and rows are made in the registers by the frame's own
// operation (2 v_0 - v_1, per lane), so every lane holds the value the framed copy would hold, and each
// lane does the four-lane form's operations in its order (group 0's products with 1 are exact; AVX
// without FMA, so nothing is contracted): the same bits. Lane 7 (the frame column) holds some finite
// value of the template and is multiplied by zero as before; its +-0 products cannot change a sum that
// starts at +0. Chosen at run time (use_avx2).
__attribute__((target("avx2"))) void unmasked_moments8(const float* values, TemplateGradientMoments* moments) {
  // No lambdas: they would not inherit the target attribute.
  using Float8 = float __attribute__((vector_size(32)));
  const Float8 last_lane_off = Float8{1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 0.0f};
  const Float8 two = Float8{} + 2.0f;
  // rows[1 + ty] = template row ty in lanes 0-6 (lane 7: the next row's first value; the last row is read
  // one value early and moved down a lane, so nothing past the template is read); rows[0] and rows[8]
  // the extrapolated frame rows.
  Float8 rows[kPatchSize + 2];
  for (int ty = 0; ty + 1 < kPatchSize; ++ty) __builtin_memcpy(&rows[ty + 1], &values[ty * kPatchSize], sizeof(Float8));
  Float8 last;
  __builtin_memcpy(&last, &values[(kPatchSize - 1) * kPatchSize - 1], sizeof last);
  rows[kPatchSize] = __builtin_shufflevector(last, last, 1, 2, 3, 4, 5, 6, 7, 7);
  rows[0] = two * rows[1] - rows[2];
  rows[kPatchSize + 1] = two * rows[kPatchSize] - rows[kPatchSize - 1];
  Float8 xx = Float8{}, xy = xx, yy = xx;
  Float4 xx_y = Float4{}, xy_y = xx_y, yy_y = xx_y;
  for (int ty = 0; ty < kPatchSize; ++ty) {
    const Float8 row = rows[ty + 1];
    const Float8 ahead = __builtin_shufflevector(row, row, 1, 2, 3, 4, 5, 6, 7, 7);   // v_{x+1}, x = 0..5
    const Float8 behind = __builtin_shufflevector(row, row, 0, 0, 1, 2, 3, 4, 5, 6);  // v_{x-1}, x = 1..6
    const Float8 left_end = two * row - ahead;    // lane 0: 2 v_0 - v_1, the frame's column -1
    const Float8 right_end = two * row - behind;  // lane 6: 2 v_6 - v_5, the frame's column 7
    const Float8 forward_x = __builtin_shufflevector(ahead, right_end, 0, 1, 2, 3, 4, 5, 14, 7);
    const Float8 back_x = __builtin_shufflevector(behind, left_end, 8, 1, 2, 3, 4, 5, 6, 7);
    const Float8 gx = (forward_x - back_x) * last_lane_off;
    const Float8 gy = (rows[ty + 2] - rows[ty]) * last_lane_off;
    const Float8 pxx = gx * gx, pxy = gx * gy, pyy = gy * gy;
    xx += pxx;
    xy += pxy;
    yy += pyy;
    const float y_value = static_cast<float>(ty - kPatchRadius);
    const Float4 y = Float4{y_value, y_value, y_value, y_value};
    xx_y += y * (__builtin_shufflevector(pxx, pxx, 0, 1, 2, 3) + __builtin_shufflevector(pxx, pxx, 4, 5, 6, 7));
    xy_y += y * (__builtin_shufflevector(pxy, pxy, 0, 1, 2, 3) + __builtin_shufflevector(pxy, pxy, 4, 5, 6, 7));
    yy_y += y * (__builtin_shufflevector(pyy, pyy, 0, 1, 2, 3) + __builtin_shufflevector(pyy, pyy, 4, 5, 6, 7));
  }
  // Reduced here, inlined into this function (its lanes stay in registers).
  moments_from_unmasked_lanes(
      UnmaskedLanes{__builtin_shufflevector(xx, xx, 0, 1, 2, 3), __builtin_shufflevector(xy, xy, 0, 1, 2, 3),
                    __builtin_shufflevector(yy, yy, 0, 1, 2, 3), __builtin_shufflevector(xx, xx, 4, 5, 6, 7),
                    __builtin_shufflevector(xy, xy, 4, 5, 6, 7), __builtin_shufflevector(yy, yy, 4, 5, 6, 7),
                    xx_y, xy_y, yy_y},
      moments);
}
#endif

// The masked pass over the framed template and mask (template_gradient_moments below): lane sums of
// g g^T per lane group and their running sums over the rows.
void masked_lanes4(const float* v, const float* m, Float4 (&g_acc)[2][3], Float4 (&q_acc)[2][3]) {
  const Float4 half = splat4(0.5f);
  const Float4 one = splat4(1.0f);
  const Float4 zero = splat4(0.0f);
  for (int ty = 0; ty < kPatchSize; ++ty) {
    for (int group = 0; group < 2; ++group) {
      const int c = (ty + 1) * kFrameStride + 1 + 4 * group;
      const Float4 vc = load4(&v[c]);
      const Float4 mxf = load4(&m[c + 1]);
      const Float4 mxb = load4(&m[c - 1]);
      const Float4 myf = load4(&m[c + kFrameStride]);
      const Float4 myb = load4(&m[c - kFrameStride]);
      const Float4 nx = mxf + mxb;  // in {0, 1, 2}
      const Float4 ny = myf + myb;
      const Float4 keep = ((nx > half) & (ny > half)) ? load4(&m[c]) : zero;
      const Float4 scale_x = (nx > splat4(1.5f) ? half : one) * keep;
      const Float4 scale_y = (ny > splat4(1.5f) ? half : one) * keep;
      const Float4 gx = (mxf * (load4(&v[c + 1]) - vc) + mxb * (vc - load4(&v[c - 1]))) * scale_x;
      const Float4 gy = (myf * (load4(&v[c + kFrameStride]) - vc) + myb * (vc - load4(&v[c - kFrameStride]))) * scale_y;
      g_acc[group][0] += gx * gx;
      g_acc[group][1] += gx * gy;
      g_acc[group][2] += gy * gy;
    }
    for (int group = 0; group < 2; ++group) {
      for (int j = 0; j < 3; ++j) q_acc[group][j] += g_acc[group][j];
    }
  }
}

#if VANTAGE_PATCH_WARP_HAS_AVX
// The same with a row's two groups as one 8-lane AVX vector (each lane the four-lane form's operations,
// no FMA: the same bits).
__attribute__((target("avx2"))) void masked_lanes8(const float* v, const float* m, Float4 (&g_acc)[2][3],
                                                   Float4 (&q_acc)[2][3]) {
  using Float8 = float __attribute__((vector_size(32)));
  const Float8 half = Float8{} + 0.5f;
  const Float8 one = Float8{} + 1.0f;
  const Float8 one_and_half = Float8{} + 1.5f;
  const Float8 zero = Float8{};
  Float8 g[3] = {};
  Float8 q[3] = {};
  for (int ty = 0; ty < kPatchSize; ++ty) {
    const int c = (ty + 1) * kFrameStride + 1;
    Float8 vc, vxf, vxb, vyf, vyb, mc, mxf, mxb, myf, myb;
    __builtin_memcpy(&vc, &v[c], sizeof vc);
    __builtin_memcpy(&vxf, &v[c + 1], sizeof vxf);
    __builtin_memcpy(&vxb, &v[c - 1], sizeof vxb);
    __builtin_memcpy(&vyf, &v[c + kFrameStride], sizeof vyf);
    __builtin_memcpy(&vyb, &v[c - kFrameStride], sizeof vyb);
    __builtin_memcpy(&mc, &m[c], sizeof mc);
    __builtin_memcpy(&mxf, &m[c + 1], sizeof mxf);
    __builtin_memcpy(&mxb, &m[c - 1], sizeof mxb);
    __builtin_memcpy(&myf, &m[c + kFrameStride], sizeof myf);
    __builtin_memcpy(&myb, &m[c - kFrameStride], sizeof myb);
    const Float8 nx = mxf + mxb;
    const Float8 ny = myf + myb;
    const Float8 keep = ((nx > half) & (ny > half)) ? mc : zero;
    const Float8 scale_x = (nx > one_and_half ? half : one) * keep;
    const Float8 scale_y = (ny > one_and_half ? half : one) * keep;
    const Float8 gx = (mxf * (vxf - vc) + mxb * (vc - vxb)) * scale_x;
    const Float8 gy = (myf * (vyf - vc) + myb * (vc - vyb)) * scale_y;
    g[0] += gx * gx;
    g[1] += gx * gy;
    g[2] += gy * gy;
    for (int j = 0; j < 3; ++j) q[j] += g[j];
  }
  for (int j = 0; j < 3; ++j) {
    g_acc[0][j] = __builtin_shufflevector(g[j], g[j], 0, 1, 2, 3);
    g_acc[1][j] = __builtin_shufflevector(g[j], g[j], 4, 5, 6, 7);
    q_acc[0][j] = __builtin_shufflevector(q[j], q[j], 0, 1, 2, 3);
    q_acc[1][j] = __builtin_shufflevector(q[j], q[j], 4, 5, 6, 7);
  }
}
#endif

void unmasked_moments(const NccTemplate& tmpl, TemplateGradientMoments* out, MatchKernel kernel) {
  (void)kernel;  // the baseline's only pass on other targets
#if VANTAGE_PATCH_WARP_HAS_AVX
  if (use_avx2(kernel)) {
    unmasked_moments8(tmpl.values.data(), out);  // frames the rows in its registers
    return;
  }
#endif
  alignas(32) float v[kFrameRows * kFrameStride];
  frame_extrapolated(tmpl, v);
  UnmaskedLanes lanes;
  unmasked_lanes4(v, &lanes);
  moments_from_unmasked_lanes(lanes, out);
}

}  // namespace

void template_gradient_moments(const NccTemplate& tmpl, TemplateGradientMoments* out) {
  template_gradient_moments(tmpl, out, MatchKernel::kAuto);
}

void template_gradient_moments(const NccTemplate& tmpl, TemplateGradientMoments* out, MatchKernel kernel) {
  static_assert(kPatchSize == 7, "two four-lane groups per template row");
  if (tmpl.valid_count == kPatchPixels) {
    unmasked_moments(tmpl, out, kernel);
    return;
  }
  // The template and its mask inside a frame of masked zeros, so every pixel has both neighbours on
  // each axis and the one-sided rule is arithmetic: with m_f, m_b the neighbours' masks,
  // g = (m_f (v_f - v) + m_b (v - v_b)) / (m_f + m_b), and a pixel counts when it is valid and
  // m_f + m_b > 0 on both axes. The eighth lane of each row is the frame: masked, it adds nothing.
  alignas(16) float v[kFrameRows * kFrameStride] = {};
  alignas(16) float m[kFrameRows * kFrameStride] = {};
  for (int ty = 0; ty < kPatchSize; ++ty) {
    std::memcpy(&v[(ty + 1) * kFrameStride + 1], &tmpl.values[static_cast<std::size_t>(ty * kPatchSize)],
                kPatchSize * sizeof(float));
    std::memcpy(&m[(ty + 1) * kFrameStride + 1], &tmpl.mask[static_cast<std::size_t>(ty * kPatchSize)],
                kPatchSize * sizeof(float));
  }
  // Masks as exactly 0 or 1 (make_template writes them so; a hand-made template may not).
  for (int i = 0; i < kFrameRows * kFrameStride; i += 4) {
    store4(&m[i], load4(&m[i]) > splat4(0.5f) ? splat4(1.0f) : splat4(0.0f));
  }
  Float4 g_acc[2][3] = {};
  Float4 q_acc[2][3] = {};
#if VANTAGE_PATCH_WARP_HAS_AVX
  if (use_avx2(kernel)) masked_lanes8(v, m, g_acc, q_acc); else
#endif
  masked_lanes4(v, m, g_acc, q_acc);
  moments_from_lanes(g_acc, q_acc, 1.0, out);
}

Eigen::Matrix2d warp_shift_covariance(const TemplateGradientMoments& moments, const Eigen::Matrix2d& A_ref_per_target,
                                      const std::array<Eigen::Matrix2d, 2>& dA, double tilt_variance) {
  const Eigen::Matrix2d A_inv = A_ref_per_target.inverse();
  if (!A_inv.allFinite() || !(tilt_variance > 0.0)) return Eigen::Matrix2d::Zero();
  const Eigen::Matrix2d& G = moments.G;
  if (!(G.determinant() > 1e-12 * G.squaredNorm())) return Eigen::Matrix2d::Zero();
  const Eigen::Matrix2d G_inv = G.inverse();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  for (int k = 0; k < 2; ++k) {
    // U_k = A^-1 dA_k displaces the template by U_k x at offset x; the least-squares shift is G^-1 b_k.
    const Eigen::Matrix2d U = A_inv * dA[static_cast<std::size_t>(k)];
    const Eigen::Vector2d shift = G_inv * (moments.Mx * U.col(0) + moments.My * U.col(1));
    covariance += shift * shift.transpose();
  }
  return tilt_variance * covariance;
}

Eigen::Matrix2d warp_shift_covariance(const NccTemplate& tmpl, const Eigen::Matrix2d& A_ref_per_target,
                                      const std::array<Eigen::Matrix2d, 2>& dA, double tilt_variance) {
  TemplateGradientMoments moments;
  template_gradient_moments(tmpl, &moments);
  return warp_shift_covariance(moments, A_ref_per_target, dA, tilt_variance);
}

double warp_stretch_ratio(const Eigen::Matrix2d& B, double max_ratio) {
  // The singular values from the Frobenius norm and the determinant: s1^2 + s2^2 = |B|^2, s1 s2 = |det B|.
  const double f2 = B.squaredNorm();
  const double det = std::abs(B.determinant());
  const double spread = std::sqrt(std::max(0.0, f2 * f2 - 4.0 * det * det));
  const double largest = std::sqrt(0.5 * (f2 + spread));
  const double smallest = std::sqrt(std::max(0.0, 0.5 * (f2 - spread)));
  const double ratio = largest / smallest;
  return smallest * max_ratio > largest && std::isfinite(ratio) ? ratio : max_ratio;
}

}  // namespace vantage
