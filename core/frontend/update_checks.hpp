#pragma once
// The iterated update's input and result checks (iterated_update.cpp), shared with its batched form
// (iterated_update_batch.cpp) so that both refuse exactly the same inputs.
#include <Eigen/Core>

#include "core/common/status.hpp"
#include "core/estimation/ekf.hpp"
#include "core/frontend/iterated_update.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/model/primitive.hpp"

namespace vantage::update_checks {

// The update's inputs: kOk, kNonFiniteInput when any is not finite, kNotSpd when the prior Sigma is not
// symmetric positive definite (at_prior may be null).
Status check_inputs(const Primitive& primitive, const CommonObservationError& common,
                    const Eigen::Vector2d& observation_px, const Viewpoint& view, const EkfConfig& config,
                    const ProjectionAtPrior* at_prior);

// Whether the short form Sigma - K G^T (symmetrized: Sigma_new) can be trusted: every axis keeps at least
// 1e-6 of its prior variance (below that the subtraction's rounding, ~1e-10 relative, is not small against
// the result) and it is positive definite. Otherwise the Joseph form.
bool short_form_trusted(const Eigen::Matrix3d& Sigma_new, const Eigen::Matrix3d& Sigma_prior);

}  // namespace vantage::update_checks
