#include "hal/calibration/camera_info.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

namespace vantage::hal {
namespace {

struct Failure {
  std::string field;
  std::string problem;
};

double scalar(const YAML::Node& node, const std::string& field) {
  if (!node || !node.IsScalar()) throw Failure{field, "missing or not a number"};
  try {
    const double value = node.as<double>();
    if (!std::isfinite(value)) throw Failure{field, "not finite"};
    return value;
  } catch (const YAML::Exception&) {
    throw Failure{field, "'" + node.Scalar() + "' is not a number"};
  }
}

int integer(const YAML::Node& node, const std::string& field) {
  const double value = scalar(node, field);
  if (value != std::floor(value) || value < 1 || value > 1 << 16) throw Failure{field, "not a positive integer"};
  return static_cast<int>(value);
}

std::vector<double> matrix(const YAML::Node& root, const std::string& name, int rows, int cols) {
  const YAML::Node node = root[name];
  if (!node || !node.IsMap()) throw Failure{name, "missing (needs rows, cols and data)"};
  if (integer(node["rows"], name + ".rows") != rows) throw Failure{name + ".rows", "expected " + std::to_string(rows)};
  if (integer(node["cols"], name + ".cols") != cols) throw Failure{name + ".cols", "expected " + std::to_string(cols)};
  const YAML::Node data = node["data"];
  if (!data || !data.IsSequence()) throw Failure{name + ".data", "missing or not a list"};
  const std::size_t expected = static_cast<std::size_t>(rows * cols);
  if (data.size() != expected) {
    throw Failure{name + ".data", "expected " + std::to_string(expected) + " numbers, got " + std::to_string(data.size())};
  }
  std::vector<double> values;
  for (std::size_t i = 0; i < expected; ++i) values.push_back(scalar(data[i], name + ".data[" + std::to_string(i) + "]"));
  return values;
}

// Largest pixel shift that p1, p2 and k3 cause at the image corners and edge midpoints.
double ignored_shift_px(const PinholeIntrinsics& k, double p1, double p2, double k3) {
  double worst = 0.0;
  const double us[] = {0.0, 0.5 * (k.width_px - 1), static_cast<double>(k.width_px - 1)};
  const double vs[] = {0.0, 0.5 * (k.height_px - 1), static_cast<double>(k.height_px - 1)};
  for (double u : us) {
    for (double v : vs) {
      const double x = (u - k.cx_px) / k.fx_px;
      const double y = (v - k.cy_px) / k.fy_px;
      const double r2 = x * x + y * y;
      const double radial = k3 * r2 * r2 * r2;
      const double dx = radial * x + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
      const double dy = radial * y + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
      worst = std::max(worst, std::hypot(k.fx_px * dx, k.fy_px * dy));
    }
  }
  return worst;
}

}  // namespace

std::string parse_camera_info(const std::string& yaml_text, const std::string& source, PinholeIntrinsics* out,
                              std::string* note) {
  try {
    YAML::Node root;
    try {
      root = YAML::Load(yaml_text);
    } catch (const YAML::ParserException& e) {
      return source + ": line " + std::to_string(e.mark.line + 1) + ": not valid YAML (" + e.msg + ")";
    }
    if (!root || !root.IsMap()) throw Failure{"(document)", "not a camera_info mapping"};
    PinholeIntrinsics k;
    k.width_px = integer(root["image_width"], "image_width");
    k.height_px = integer(root["image_height"], "image_height");
    const std::vector<double> m = matrix(root, "camera_matrix", 3, 3);
    if (std::fabs(m[1]) > 1e-9) throw Failure{"camera_matrix.data[1]", "skew is not supported (must be 0)"};
    if (m[3] != 0.0 || m[6] != 0.0 || m[7] != 0.0 || m[8] != 1.0) {
      throw Failure{"camera_matrix.data", "not of the form [fx 0 cx; 0 fy cy; 0 0 1]"};
    }
    k.fx_px = m[0];
    k.cx_px = m[2];
    k.fy_px = m[4];
    k.cy_px = m[5];
    const YAML::Node model = root["distortion_model"];
    if (!model || !model.IsScalar()) throw Failure{"distortion_model", "missing"};
    if (model.Scalar() != "plumb_bob") {
      throw Failure{"distortion_model", "'" + model.Scalar() + "' is not supported (only plumb_bob)"};
    }
    const std::vector<double> d = matrix(root, "distortion_coefficients", 1, 5);
    k.k1 = d[0];
    k.k2 = d[1];
    if (!ok(k.validate())) {
      throw Failure{"camera_matrix", "not a valid camera (focal lengths must be positive and the principal point inside the image)"};
    }
    const double shift_px = ignored_shift_px(k, d[2], d[3], d[4]);
    if (shift_px > kMaxIgnoredDistortionPx) {
      std::ostringstream problem;
      problem << "p1, p2, k3 move the image corners by up to " << shift_px << " px; vantage models k1, k2 only (limit "
              << kMaxIgnoredDistortionPx << " px): recalibrate with tangential and k3 terms fixed at zero";
      throw Failure{"distortion_coefficients.data", problem.str()};
    }
    std::string text;
    if (d[2] != 0.0 || d[3] != 0.0 || d[4] != 0.0) {
      std::ostringstream s;
      s << source << ": p1, p2, k3 ignored (at most " << shift_px << " px at the image corners)";
      text = s.str();
    }
    *out = k;
    if (note != nullptr) *note = text;
    return {};
  } catch (const Failure& f) {
    return source + ": " + f.field + ": " + f.problem;
  } catch (const YAML::Exception& e) {
    return source + ": " + e.what();
  }
}

std::string load_camera_info(const std::string& path, PinholeIntrinsics* out, std::string* note) {
  std::ifstream file(path);
  if (!file) return path + ": cannot open the calibration file";
  std::stringstream text;
  text << file.rdbuf();
  if (file.bad()) return path + ": read error";
  return parse_camera_info(text.str(), path, out, note);
}

}  // namespace vantage::hal
