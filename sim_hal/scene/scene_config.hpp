#pragma once
// Everything a simulated experiment needs, with defaults that reproduce the paper's bunny experiment
// (section VI) without any file. A TOML scene file (sim_hal/scenes/bunny.toml documents every field)
// overrides any subset of fields.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/grid/grid_geometry.hpp"
#include "sim_hal/scene/mesh_loader.hpp"

namespace vantage::sim {

inline constexpr const char* kDefaultMeshPath = "/usr/share/glmark2/models/bunny.obj";

// A directional light: direction_world points from the surface TOWARD the light (unit length after
// parsing), intensity multiplies the Lambertian term max(0, n . direction).
struct DirectionalLight {
  Eigen::Vector3d direction_world = Eigen::Vector3d::UnitZ();
  double intensity = 1.0;
};

enum class AlbedoMode { kTexture, kConstant };
const char* to_string(AlbedoMode mode);

struct AlbedoConfig {
  // kTexture: procedural 3D value-noise texture (solid texture, so matching finds texture everywhere).
  // kConstant: one albedo everywhere, lighting only (the paper's rendering).
  AlbedoMode mode = AlbedoMode::kTexture;
  double constant = 0.8;            // albedo in [0, 1] for kConstant, and the texture's mean
  double texture_contrast = 0.35;   // kTexture: albedo = constant + contrast * (noise in [-1, 1]), clamped
  double texture_feature_size = 0.6;  // kTexture: scene units of the finest noise octave's lattice
};

// Which normal the Lambertian term uses: the hit triangle's own (flat facets) or the corner normals
// interpolated with the hit's barycentrics (EmbreeScene::corner_normals, a smooth surface).
enum class NormalMode { kFlat, kSmooth };
const char* to_string(NormalMode mode);

inline constexpr int kMaxPixelSamplesPerAxis = 8;

struct ShadingConfig {
  std::vector<DirectionalLight> lights;  // in the world frame
  // Pixel-area integration: a pixel's gray is the mean over samples_per_axis^2 rays on a regular grid
  // inside the pixel's square (a box filter, 100% fill factor), as a sensor integrates irradiance over
  // its area; 1 is one ray through the pixel centre. In [1, kMaxPixelSamplesPerAxis]. The defaults
  // (1, flat) were chosen by measurement: 2 x 2 smooth costs 3.8x the render time and made no figure
  // of the front end or the mission better (sim_hal/README.md, "Pixel-area integration").
  int samples_per_axis = 1;
  NormalMode normals = NormalMode::kFlat;
  double ambient = 0.25;                 // added to the Lambertian sum
  AlbedoConfig albedo;
  double pixel_noise_sigma = 0.0;        // gray levels, Gaussian, added before rounding
  std::uint8_t background_gray = 0;      // pixels whose ray misses the object
};

struct PoseNoiseConfig {
  double position_sigma = 0.0;      // scene units, per axis, on the REPORTED pose only
  double rotation_sigma_rad = 0.0;  // small-angle rotation noise per axis on the reported pose
};

struct SceneConfig {
  std::string source = "<defaults>";    // the file it was read from, for messages
  std::string mesh_path = kDefaultMeshPath;
  UpAxis up_axis = UpAxis::kY;          // the glmark2 bunny is y-up
  double scale = 0.0;                   // 0: fit to target_area_fraction; > 0: fixed file->scene scale
  double target_area_fraction = 0.5;
  double viewing_distance = 40.0;
  PinholeIntrinsics intrinsics = PinholeIntrinsics::default_vga();
  GridGeometry grid;                    // M = 60, 2 units per cell, elevation 0, centred at the origin
  double occupancy_margin = 1.0;        // scene units added around the object's footprint
  ShadingConfig shading;
  PoseNoiseConfig pose_noise;
  double robot_speed = 10.0;            // scene units per second
  int render_threads = 2;
  std::uint32_t seed = 1;

  // The paper's defaults (two world lights plus ambient, textured albedo, no noise).
  static SceneConfig paper_defaults();
};

// Reads a TOML scene file over the defaults. Throws SimError "<file>: <field>: <problem>" for a missing
// or unparsable file, an unknown field, a wrongly typed or out-of-range value, or impossible intrinsics.
SceneConfig load_scene_config(const std::string& path);
// The same on text in memory; source_name is used in messages.
SceneConfig parse_scene_config(std::string_view toml_text, const std::string& source_name);
// Throws SimError naming the field when a value is out of range (used by both parsers; callers that
// build a SceneConfig in code may call it too).
void validate_scene_config(const SceneConfig& config);

}  // namespace vantage::sim
