#pragma once
// Camera calibration from the ROS / OpenCV camera_info YAML (what camera_calibration and
// camera_calibration_parsers write): image_width, image_height, camera_matrix {rows, cols, data},
// distortion_model, distortion_coefficients {rows, cols, data}. rectification_matrix and
// projection_matrix are ignored (vantage works on the raw image).
//
// vantage's PinholeIntrinsics carries plumb_bob's radial k1, k2 only. p1, p2 (tangential) and k3 are
// accepted when together they move no image corner by more than kMaxIgnoredDistortionPx and are then
// ignored (the note says by how much); larger values are refused, naming the field.
#include <string>

#include "core/geometry/pinhole_intrinsics.hpp"

namespace vantage::hal {

constexpr double kMaxIgnoredDistortionPx = 0.5;

// Empty string on success (with *note saying what was ignored, possibly empty); otherwise one line
// "<file>: <field>: <problem>" and *out is unchanged.
std::string load_camera_info(const std::string& path, PinholeIntrinsics* out, std::string* note);
// The same from YAML text; source names it in messages.
std::string parse_camera_info(const std::string& yaml_text, const std::string& source, PinholeIntrinsics* out,
                              std::string* note);

}  // namespace vantage::hal
