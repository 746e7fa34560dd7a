#pragma once
// The covariance of a subpixel match (the photometric fit I(p + d) = alpha * t + beta of
// patch_search.hpp's refine_subpixel) with the residuals' spatial correlation taken into account
// (correlated_residuals.hpp): the fit taken as white is optimistic, by about 2.8 on average in the
// front end's matches (core/frontend/EXPERIMENTS.md).
#include <Eigen/Core>

#include "core/frontend/ncc.hpp"
#include "core/image/gray_image.hpp"

namespace vantage {

// At the match uv_px (the patch centre in the image) of template tmpl: gain and offset by least squares,
// then the shift block of the sandwich covariance of (shift, gain, offset) with the residuals' lag-one
// correlations. False, output untouched, when the patch (with a pixel more for the gradient) leaves the
// image or the fit is singular.
bool correlated_match_covariance(const GrayImageView& image, const NccTemplate& tmpl, const Eigen::Vector2d& uv_px,
                                 Eigen::Matrix2d* covariance_px2);

}  // namespace vantage
