#include "sim_hal/scene/scene_config.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <toml++/toml.h>

#include "sim_hal/sim_error.hpp"

namespace vantage::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;

[[noreturn]] void fail(const std::string& source, const std::string& field, const std::string& what) {
  throw SimError(source + ": " + field + ": " + what);
}

// Reads one table, refusing keys it does not know and values of the wrong type.
class TableReader {
 public:
  TableReader(const toml::table& table, std::string source, std::string prefix)
      : table_(table), source_(std::move(source)), prefix_(std::move(prefix)) {}

  std::string field(std::string_view key) const { return prefix_.empty() ? std::string(key) : prefix_ + "." + std::string(key); }
  [[noreturn]] void fail_field(std::string_view key, const std::string& what) const { fail(source_, field(key), what); }

  const toml::node* get(std::string_view key) {
    known_.emplace_back(key);
    return table_.get(key);
  }
  std::optional<double> number(std::string_view key) {
    const toml::node* node = get(key);
    if (node == nullptr) return std::nullopt;
    if (!node->is_number()) fail_field(key, "expected a number");
    const double v = node->value<double>().value();
    if (!std::isfinite(v)) fail_field(key, "must be finite");
    return v;
  }
  std::optional<std::int64_t> integer(std::string_view key) {
    const toml::node* node = get(key);
    if (node == nullptr) return std::nullopt;
    if (!node->is_integer()) fail_field(key, "expected an integer");
    return node->value<std::int64_t>().value();
  }
  std::optional<std::string> string(std::string_view key) {
    const toml::node* node = get(key);
    if (node == nullptr) return std::nullopt;
    if (!node->is_string()) fail_field(key, "expected a string");
    return node->value<std::string>().value();
  }
  std::optional<Eigen::Vector3d> vector3(std::string_view key) {
    const toml::node* node = get(key);
    if (node == nullptr) return std::nullopt;
    const toml::array* array = node->as_array();
    if (array == nullptr || array->size() != 3) fail_field(key, "expected an array of 3 numbers");
    Eigen::Vector3d v;
    for (std::size_t i = 0; i < 3; ++i) {
      const toml::node* e = array->get(i);
      if (e == nullptr || !e->is_number()) fail_field(key, "expected an array of 3 numbers");
      v[static_cast<Eigen::Index>(i)] = e->value<double>().value();
    }
    if (!v.allFinite()) fail_field(key, "must be finite");
    return v;
  }
  const toml::table* subtable(std::string_view key) {
    const toml::node* node = get(key);
    if (node == nullptr) return nullptr;
    if (!node->is_table()) fail_field(key, "expected a table");
    return node->as_table();
  }
  // Call last: any key not asked for is unknown.
  void refuse_unknown() const {
    for (const auto& [key, value] : table_) {
      bool known = false;
      for (const auto& k : known_) known = known || k == key.str();
      if (!known) fail(source_, field(key.str()), "unknown field");
    }
  }
  const std::string& source() const { return source_; }

 private:
  const toml::table& table_;
  std::string source_;
  std::string prefix_;
  std::vector<std::string> known_;
};

void require(bool condition, const std::string& source, const std::string& field, const std::string& what) {
  if (!condition) fail(source, field, what);
}

void read_mesh(TableReader& r, SceneConfig& c) {
  if (auto v = r.string("path")) c.mesh_path = *v;
  if (auto v = r.string("up_axis")) {
    if (*v == "x") c.up_axis = UpAxis::kX;
    else if (*v == "y") c.up_axis = UpAxis::kY;
    else if (*v == "z") c.up_axis = UpAxis::kZ;
    else r.fail_field("up_axis", "expected \"x\", \"y\" or \"z\", got \"" + *v + "\"");
  }
  if (auto v = r.number("scale")) c.scale = *v;
  if (auto v = r.number("target_area_fraction")) c.target_area_fraction = *v;
  if (auto v = r.number("viewing_distance")) c.viewing_distance = *v;
  r.refuse_unknown();
}

void read_camera(TableReader& r, SceneConfig& c) {
  PinholeIntrinsics& k = c.intrinsics;
  if (auto v = r.integer("width_px")) {
    if (*v <= 0 || *v > 8192) r.fail_field("width_px", "must be in [1, 8192]");
    k.width_px = static_cast<std::int32_t>(*v);
  }
  if (auto v = r.integer("height_px")) {
    if (*v <= 0 || *v > 8192) r.fail_field("height_px", "must be in [1, 8192]");
    k.height_px = static_cast<std::int32_t>(*v);
  }
  const std::optional<double> fov = r.number("vertical_fov_deg");
  const std::optional<double> fx = r.number("fx_px");
  const std::optional<double> fy = r.number("fy_px");
  const std::optional<double> cx = r.number("cx_px");
  const std::optional<double> cy = r.number("cy_px");
  if (fov && (fx || fy)) r.fail_field("vertical_fov_deg", "give either vertical_fov_deg or fx_px/fy_px, not both");
  if (fov) {
    if (!(*fov > 0.0 && *fov < 180.0)) r.fail_field("vertical_fov_deg", "must be in (0, 180)");
    k.fy_px = 0.5 * k.height_px / std::tan(0.5 * *fov * kPi / 180.0);
    k.fx_px = k.fy_px;
  } else if (!fx && !fy) {
    // Keep the default 45 degree vertical field of view at the configured height.
    k.fy_px = 0.5 * k.height_px / std::tan(0.5 * 45.0 * kPi / 180.0);
    k.fx_px = k.fy_px;
  }
  if (fx) k.fx_px = *fx;
  if (fy) k.fy_px = *fy;
  if (fx && !fy) k.fy_px = *fx;
  if (fy && !fx) k.fx_px = *fy;
  k.cx_px = cx ? *cx : 0.5 * (k.width_px - 1);
  k.cy_px = cy ? *cy : 0.5 * (k.height_px - 1);
  if (auto v = r.number("k1")) k.k1 = *v;
  if (auto v = r.number("k2")) k.k2 = *v;
  if (auto v = r.integer("render_threads")) {
    if (*v < 1 || *v > 64) r.fail_field("render_threads", "must be in [1, 64]");
    c.render_threads = static_cast<int>(*v);
  }
  if (auto v = r.integer("pixel_samples_per_axis")) {
    if (*v < 1 || *v > kMaxPixelSamplesPerAxis) {
      r.fail_field("pixel_samples_per_axis", "must be in [1, " + std::to_string(kMaxPixelSamplesPerAxis) + "], got " +
                                                 std::to_string(*v));
    }
    c.shading.samples_per_axis = static_cast<int>(*v);
  }
  if (auto v = r.number("pixel_noise_sigma")) c.shading.pixel_noise_sigma = *v;
  if (auto v = r.integer("background_gray")) {
    if (*v < 0 || *v > 255) r.fail_field("background_gray", "must be in [0, 255]");
    c.shading.background_gray = static_cast<std::uint8_t>(*v);
  }
  r.refuse_unknown();
}

void read_grid(TableReader& r, SceneConfig& c) {
  if (auto v = r.integer("cells_per_side")) {
    if (*v < 2 || *v > 1024) r.fail_field("cells_per_side", "must be in [2, 1024]");
    c.grid.cells_per_side = static_cast<std::int32_t>(*v);
  }
  if (auto v = r.number("cell_size")) c.grid.cell_size_m = *v;
  if (auto v = r.number("elevation")) c.grid.elevation_m = *v;
  if (auto v = r.number("occupancy_margin")) c.occupancy_margin = *v;
  r.refuse_unknown();
}

void read_lighting(TableReader& r, SceneConfig& c) {
  if (auto v = r.number("ambient")) c.shading.ambient = *v;
  if (auto v = r.string("normals")) {
    if (*v == "flat") c.shading.normals = NormalMode::kFlat;
    else if (*v == "smooth") c.shading.normals = NormalMode::kSmooth;
    else r.fail_field("normals", "expected \"flat\" or \"smooth\", got \"" + *v + "\"");
  }
  if (const toml::node* node = r.get("lights")) {
    const toml::array* lights = node->as_array();
    if (lights == nullptr) r.fail_field("lights", "expected an array of tables ([[lighting.lights]])");
    c.shading.lights.clear();
    for (std::size_t i = 0; i < lights->size(); ++i) {
      const std::string name = r.field("lights") + "[" + std::to_string(i) + "]";
      const toml::table* t = lights->get(i)->as_table();
      if (t == nullptr) fail(r.source(), name, "expected a table");
      TableReader lr(*t, r.source(), name);
      DirectionalLight light;
      const auto direction = lr.vector3("direction");
      if (!direction) fail(r.source(), name + ".direction", "missing");
      if (!(direction->norm() > 1e-9)) fail(r.source(), name + ".direction", "must not be zero");
      light.direction_world = direction->normalized();
      if (auto v = lr.number("intensity")) light.intensity = *v;
      if (light.intensity < 0.0) fail(r.source(), name + ".intensity", "must be >= 0");
      lr.refuse_unknown();
      c.shading.lights.push_back(light);
    }
  }
  r.refuse_unknown();
}

void read_albedo(TableReader& r, SceneConfig& c) {
  if (auto v = r.string("mode")) {
    if (*v == "texture") c.shading.albedo.mode = AlbedoMode::kTexture;
    else if (*v == "constant") c.shading.albedo.mode = AlbedoMode::kConstant;
    else r.fail_field("mode", "expected \"texture\" or \"constant\", got \"" + *v + "\"");
  }
  if (auto v = r.number("constant")) c.shading.albedo.constant = *v;
  if (auto v = r.number("texture_contrast")) c.shading.albedo.texture_contrast = *v;
  if (auto v = r.number("texture_feature_size")) c.shading.albedo.texture_feature_size = *v;
  r.refuse_unknown();
}

void read_robot(TableReader& r, SceneConfig& c) {
  if (auto v = r.number("speed")) c.robot_speed = *v;
  if (auto v = r.number("position_noise_sigma")) c.pose_noise.position_sigma = *v;
  if (auto v = r.number("rotation_noise_sigma_deg")) c.pose_noise.rotation_sigma_rad = *v * kPi / 180.0;
  r.refuse_unknown();
}

SceneConfig from_table(const toml::table& root, const std::string& source) {
  SceneConfig c = SceneConfig::paper_defaults();
  c.source = source;
  TableReader r(root, source, "");
  if (auto v = r.integer("seed")) {
    if (*v < 0 || *v > 0xFFFFFFFFll) r.fail_field("seed", "must be in [0, 2^32)");
    c.seed = static_cast<std::uint32_t>(*v);
  }
  struct Section {
    const char* name;
    void (*read)(TableReader&, SceneConfig&);
  };
  const Section sections[] = {{"mesh", read_mesh},     {"camera", read_camera}, {"grid", read_grid},
                              {"lighting", read_lighting}, {"albedo", read_albedo}, {"robot", read_robot}};
  for (const Section& s : sections) {
    if (const toml::table* t = r.subtable(s.name)) {
      TableReader sub(*t, source, s.name);
      s.read(sub, c);
    }
  }
  r.refuse_unknown();
  validate_scene_config(c);
  return c;
}

}  // namespace

const char* to_string(AlbedoMode mode) { return mode == AlbedoMode::kTexture ? "texture" : "constant"; }
const char* to_string(NormalMode mode) { return mode == NormalMode::kFlat ? "flat" : "smooth"; }

SceneConfig SceneConfig::paper_defaults() {
  SceneConfig c;
  // A key light from above one side and a weaker fill from the other, so no side is left at ambient only.
  c.shading.lights = {DirectionalLight{Eigen::Vector3d(1.0, -1.0, 1.5).normalized(), 0.55},
                      DirectionalLight{Eigen::Vector3d(-1.0, 1.0, 0.5).normalized(), 0.30}};
  c.shading.ambient = 0.2;
  return c;
}

void validate_scene_config(const SceneConfig& c) {
  const std::string& s = c.source;
  require(!c.mesh_path.empty(), s, "mesh.path", "must not be empty");
  require(c.scale >= 0.0 && std::isfinite(c.scale), s, "mesh.scale", "must be >= 0 (0 = fit to the image)");
  require(c.target_area_fraction > 0.0 && c.target_area_fraction < 1.0, s, "mesh.target_area_fraction",
          "must be in (0, 1)");
  require(c.viewing_distance > 0.0 && std::isfinite(c.viewing_distance), s, "mesh.viewing_distance", "must be positive");
  const PinholeIntrinsics& k = c.intrinsics;
  require(k.width_px > 0, s, "camera.width_px", "must be positive");
  require(k.height_px > 0, s, "camera.height_px", "must be positive");
  require(k.fx_px > 0.0 && std::isfinite(k.fx_px), s, "camera.fx_px", "must be positive");
  require(k.fy_px > 0.0 && std::isfinite(k.fy_px), s, "camera.fy_px", "must be positive");
  require(k.cx_px >= 0.0 && k.cx_px <= k.width_px, s, "camera.cx_px", "must lie inside the image");
  require(k.cy_px >= 0.0 && k.cy_px <= k.height_px, s, "camera.cy_px", "must lie inside the image");
  // The distortion must stay monotonic over the image corners or pixels fold over each other.
  {
    const double xn = std::max(k.cx_px, k.width_px - k.cx_px) / k.fx_px;
    const double yn = std::max(k.cy_px, k.height_px - k.cy_px) / k.fy_px;
    const double r2_max = 2.0 * (xn * xn + yn * yn);  // generous: undistorted radius can exceed distorted
    bool monotonic = true;
    for (int i = 0; i <= 100; ++i) {
      const double r2 = r2_max * i / 100.0;
      // d(r * (1 + k1 r^2 + k2 r^4)) / dr = 1 + 3 k1 r^2 + 5 k2 r^4
      monotonic = monotonic && (1.0 + 3.0 * k.k1 * r2 + 5.0 * k.k2 * r2 * r2 > 0.05);
    }
    require(monotonic, s, "camera.k1", "distortion (k1, k2) folds the image over itself");
  }
  require(ok(k.validate()), s, "camera", "invalid intrinsics");
  require(c.render_threads >= 1, s, "camera.render_threads", "must be >= 1");
  require(c.shading.pixel_noise_sigma >= 0.0, s, "camera.pixel_noise_sigma", "must be >= 0");
  require(c.shading.samples_per_axis >= 1 && c.shading.samples_per_axis <= kMaxPixelSamplesPerAxis, s,
          "camera.pixel_samples_per_axis", "must be in [1, " + std::to_string(kMaxPixelSamplesPerAxis) + "]");
  require(c.shading.normals == NormalMode::kFlat || c.shading.normals == NormalMode::kSmooth, s, "lighting.normals",
          "must be flat or smooth");
  require(c.grid.cells_per_side >= 2, s, "grid.cells_per_side", "must be >= 2");
  require(c.grid.cell_size_m > 0.0 && std::isfinite(c.grid.cell_size_m), s, "grid.cell_size", "must be positive");
  require(std::isfinite(c.grid.elevation_m), s, "grid.elevation", "must be finite");
  require(c.occupancy_margin >= 0.0, s, "grid.occupancy_margin", "must be >= 0");
  require(c.shading.ambient >= 0.0, s, "lighting.ambient", "must be >= 0");
  require(c.shading.lights.size() <= 8, s, "lighting.lights", "at most 8 lights");
  const AlbedoConfig& a = c.shading.albedo;
  require(a.constant >= 0.0 && a.constant <= 1.0, s, "albedo.constant", "must be in [0, 1]");
  require(a.texture_contrast >= 0.0 && a.texture_contrast <= 1.0, s, "albedo.texture_contrast", "must be in [0, 1]");
  require(a.texture_feature_size > 0.0, s, "albedo.texture_feature_size", "must be positive");
  require(c.robot_speed > 0.0 && std::isfinite(c.robot_speed), s, "robot.speed", "must be positive");
  require(c.pose_noise.position_sigma >= 0.0, s, "robot.position_noise_sigma", "must be >= 0");
  require(c.pose_noise.rotation_sigma_rad >= 0.0, s, "robot.rotation_noise_sigma_deg", "must be >= 0");
}

SceneConfig parse_scene_config(std::string_view toml_text, const std::string& source_name) {
  toml::table root;
  try {
    root = toml::parse(toml_text, source_name);
  } catch (const toml::parse_error& e) {
    std::ostringstream msg;
    msg << source_name << ": line " << e.source().begin.line << ": " << e.description();
    throw SimError(msg.str());
  }
  return from_table(root, source_name);
}

SceneConfig load_scene_config(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw SimError(path + ": cannot open scene file");
  std::ostringstream text;
  text << in.rdbuf();
  SceneConfig config = parse_scene_config(text.str(), path);
  // A relative mesh path is relative to the scene file, so scenes can ship next to their meshes.
  const std::filesystem::path mesh(config.mesh_path);
  if (mesh.is_relative()) config.mesh_path = (std::filesystem::path(path).parent_path() / mesh).string();
  return config;
}

}  // namespace vantage::sim
