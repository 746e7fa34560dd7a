#pragma once
// The iterated update's input and result checks (iterated_update.cpp), shared with its batched form
// (iterated_update_batch.cpp) so that both refuse exactly the same inputs.
#include <Eigen/Core>

#include "core/estimation/ekf.hpp"
#include "core/frontend/iterated_update.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/model/primitive.hpp"

namespace vantage::update_checks {

// Every input finite (at_prior may be null).
bool inputs_finite(const Primitive& primitive, const CommonObservationError& common, const Eigen::Vector2d& observation_px,
                   const Viewpoint& view, const EkfConfig& config, const ProjectionAtPrior* at_prior);

// Symmetric within 1e-9 of its diagonal's scale, finite and positive definite.
bool spd3(const Eigen::Matrix3d& M);

// Finite and positive definite, for a matrix symmetric by construction (0.5 (M + M^T)).
bool spd3_symmetrized(const Eigen::Matrix3d& M);

// The short form's rounding is negligible against the result only while every axis keeps at least this
// fraction of its prior variance (iterated_update.cpp, updated_covariance).
inline constexpr double kKeptFraction = 1e-6;

}  // namespace vantage::update_checks
