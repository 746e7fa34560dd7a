#pragma once
// Warping the reference patch S of a primitive into a new view. The primitive's plane (through X with
// normal n) induces a homography between the creating view and the new view; over a p x p patch it is
// its first-order (affine) part at X: A maps a pixel offset around X's projection in the target view to
// the offset around X's projection in the reference view (the second-order terms reach a few hundredths
// of a pixel at the corners of a 7x7 patch for a 45 degree change of view: core test).
#include <array>
#include <cstdint>

#include <Eigen/Core>

#include "core/common/status.hpp"
#include "core/frontend/ncc.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"

namespace vantage {

// kBehindCamera when X is behind either camera, kInvalidArgument when the plane is seen edge-on from the
// target (singular map) or n is not unit length.
Status plane_affine(const Eigen::Vector3d& X_world, const Eigen::Vector3f& normal_world, const Viewpoint& reference,
                    const Viewpoint& target, const PinholeIntrinsics& intrinsics, Eigen::Matrix2d* A_ref_per_target);

// The template seen from the target: the stored patch sampled (bilinear) at A * offset; target pixels
// that map outside the stored patch are masked.
void warp_patch_template(const std::array<std::uint8_t, kPatchPixels>& patch, const Eigen::Matrix2d& A_ref_per_target,
                         NccTemplate* out);

// An orthonormal basis [e1 e2] of the plane with unit normal n: the tilt axes of dA below and of the
// photometric normal's estimate.
Eigen::Matrix<double, 3, 2> plane_basis(const Eigen::Vector3d& n);

// How unevenly the 2x2 map B stretches a patch: the ratio of its larger to its smaller singular value (1 when
// it stretches evenly, whatever its scale or rotation), at most max_ratio (so also for a singular or
// non-finite map).
double warp_stretch_ratio(const Eigen::Matrix2d& B, double max_ratio);

// plane_affine and its tilt derivatives from the two views' projection Jacobians at X (as
// project_with_jacobian gives them; the tracker has the target's from its prediction already):
// A = J_ref J_target^-1 with J = H E for a basis E = [e1 e2] of the plane (A does not depend on which).
// Tilting the normal by t toward e_k turns the basis by -t n e_k^T, so, exactly to first order,
// dA_k = -(H_ref n - A H_target n) (row k of J_target^-1): rank one. dA may be null. Errors as
// plane_affine except kBehindCamera (the caller's projections decide that).
Status plane_affine_from_jacobians(const Eigen::Matrix<double, 2, 3>& H_ref, const Eigen::Matrix<double, 2, 3>& H_target,
                                   const Eigen::Vector3f& normal_world, Eigen::Matrix2d* A_ref_per_target,
                                   std::array<Eigen::Matrix2d, 2>* dA);

// plane_affine_from_jacobians for up to kPlaneAffineBatchSize primitives (the tracker's prediction batch):
// four at a time in AVX lanes where the CPU has AVX2 (x86-64; elsewhere one by one), each lane the scalar
// function's operations in the order Eigen evaluates them (no FMA): the same bits on x86-64 (core test).
// H_ref, H_target, normal_world, status hold count entries, A_ref_per_target and dA (may be null) too,
// written only where status[i] is kOk.
inline constexpr std::int32_t kPlaneAffineBatchSize = 4;
void plane_affine_from_jacobians_batch(const Eigen::Matrix<double, 2, 3>* H_ref,
                                       const Eigen::Matrix<double, 2, 3>* H_target,
                                       const Eigen::Vector3f* const* normal_world, std::int32_t count,
                                       Eigen::Matrix2d* A_ref_per_target, std::array<Eigen::Matrix2d, 2>* dA,
                                       Status* status);

// The normal's uncertainty in the warp. dA_k = dA / dt_k for a tilt t_k (rad) of the normal about two
// orthogonal axes of its plane (analytic, see plane_affine_from_jacobians). Errors as plane_affine.
Status plane_affine_tilt_derivatives(const Eigen::Vector3d& X_world, const Eigen::Vector3f& normal_world,
                                     const Viewpoint& reference, const Viewpoint& target,
                                     const PinholeIntrinsics& intrinsics, const Eigen::Matrix2d& A_ref_per_target,
                                     std::array<Eigen::Matrix2d, 2>* dA);

// Covariance (px^2) of a match position when the template was warped by A but the true map is
// A + sum_k dA_k t_k, t ~ N(0, tilt_variance I): the template then equals the target's appearance
// displaced by u(x) = A^-1 dA x at offset x, and the least-squares shift (J^T J)^-1 sum_x g g^T u(x)
// (g the template gradient) is the match error, linear in t. Zero when the template has no gradient.
Eigen::Matrix2d warp_shift_covariance(const NccTemplate& tmpl, const Eigen::Matrix2d& A_ref_per_target,
                                      const std::array<Eigen::Matrix2d, 2>& dA, double tilt_variance);

// What warp_shift_covariance needs of a template, one pass over its pixels: with g the template's
// gradient (central differences, one-sided at the mask's edge, pixels without either neighbour on an
// axis left out) and x = (x, y) the offset from the patch centre, G = sum g g^T, Mx = sum g g^T x,
// My = sum g g^T y. Then sum g g^T U x = Mx U.col(0) + My U.col(1) for any 2x2 U.
struct TemplateGradientMoments {
  Eigen::Matrix2d G = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d Mx = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d My = Eigen::Matrix2d::Zero();
};
void template_gradient_moments(const NccTemplate& tmpl, TemplateGradientMoments* out);
// The same with a chosen build of the unmasked pass: kBaseline four lanes, otherwise one 8-lane AVX
// vector per row where the CPU has AVX2 (x86-64). Both builds give the same bits (no FMA in either).
void template_gradient_moments(const NccTemplate& tmpl, TemplateGradientMoments* out, MatchKernel kernel);

// warp_shift_covariance from the template's moments: a handful of 2x2 products per call.
Eigen::Matrix2d warp_shift_covariance(const TemplateGradientMoments& moments, const Eigen::Matrix2d& A_ref_per_target,
                                      const std::array<Eigen::Matrix2d, 2>& dA, double tilt_variance);

}  // namespace vantage
