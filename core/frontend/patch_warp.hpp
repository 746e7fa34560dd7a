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

// The normal's uncertainty in the warp. dA_k = dA / dt_k for a tilt t_k (rad) of the normal about two
// orthogonal axes of its plane (finite differences of plane_affine). Errors as plane_affine.
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

}  // namespace vantage
