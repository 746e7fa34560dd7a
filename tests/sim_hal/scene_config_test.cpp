#include <catch2/catch.hpp>

#include "sim_hal/scene/scene_config.hpp"
#include "sim_hal/sim_error.hpp"
#include "sim_hal/world/sim_world.hpp"
#include "test_meshes.hpp"

using Catch::Matchers::Contains;
using namespace vantage;
using namespace vantage::sim;

namespace {

std::string parse_error(const std::string& text) {
  try {
    (void)parse_scene_config(text, "scene.toml");
  } catch (const SimError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("the defaults are the paper's setup", "[sim_hal][config]") {
  const SceneConfig c = SceneConfig::paper_defaults();
  CHECK(c.mesh_path == kDefaultMeshPath);
  CHECK(c.grid.cells_per_side == 60);
  CHECK(c.grid.cell_size_m == 2.0);
  CHECK(c.grid.elevation_m == 0.0);
  CHECK(c.viewing_distance == 40.0);
  CHECK(c.intrinsics.width_px == 640);
  CHECK(c.intrinsics.height_px == 480);
  CHECK_NOTHROW(validate_scene_config(c));
  // An empty file changes nothing.
  const SceneConfig empty = parse_scene_config("", "empty.toml");
  CHECK(empty.mesh_path == c.mesh_path);
  CHECK(empty.shading.lights.size() == c.shading.lights.size());
}

TEST_CASE("the example scene file parses and reproduces the defaults", "[sim_hal][config]") {
  const SceneConfig file = load_scene_config(VANTAGE_SOURCE_DIR "/sim_hal/scenes/bunny.toml");
  const SceneConfig d = SceneConfig::paper_defaults();
  CHECK(file.mesh_path == d.mesh_path);
  CHECK(file.up_axis == d.up_axis);
  CHECK(file.intrinsics.fx_px == Approx(d.intrinsics.fx_px));
  CHECK(file.intrinsics.cx_px == Approx(d.intrinsics.cx_px));
  CHECK(file.grid.cells_per_side == d.grid.cells_per_side);
  CHECK(file.grid.cell_size_m == d.grid.cell_size_m);
  REQUIRE(file.shading.lights.size() == d.shading.lights.size());
  for (std::size_t i = 0; i < d.shading.lights.size(); ++i) {
    CHECK(file.shading.lights[i].direction_world.isApprox(d.shading.lights[i].direction_world, 1e-9));
    CHECK(file.shading.lights[i].intensity == d.shading.lights[i].intensity);
  }
  CHECK(file.shading.ambient == d.shading.ambient);
  CHECK(file.shading.albedo.mode == d.shading.albedo.mode);
  CHECK(file.shading.samples_per_axis == d.shading.samples_per_axis);
  CHECK(file.shading.normals == d.shading.normals);
  CHECK(file.robot_speed == d.robot_speed);
  CHECK(file.seed == d.seed);
}

TEST_CASE("scene fields override the defaults", "[sim_hal][config]") {
  const SceneConfig c = parse_scene_config(
      "seed = 9\n[camera]\nwidth_px = 320\nheight_px = 240\nk1 = -0.1\npixel_noise_sigma = 1.5\n"
      "[albedo]\nmode = \"constant\"\n[[lighting.lights]]\ndirection = [0, 0, 2]\nintensity = 0.7\n"
      "[robot]\nspeed = 4\n",
      "s.toml");
  CHECK(c.seed == 9);
  CHECK(c.intrinsics.width_px == 320);
  CHECK(c.intrinsics.cx_px == Approx(159.5));
  CHECK(c.intrinsics.k1 == -0.1);
  CHECK(c.shading.pixel_noise_sigma == 1.5);
  CHECK(c.shading.albedo.mode == AlbedoMode::kConstant);
  REQUIRE(c.shading.lights.size() == 1);
  CHECK(c.shading.lights[0].direction_world.isApprox(Eigen::Vector3d::UnitZ()));
  CHECK(c.robot_speed == 4.0);  // an integer is accepted for a number
}

TEST_CASE("scene-file errors name the file and the field", "[sim_hal][config]") {
  CHECK_THAT(parse_error("[camera]\nwidht_px = 640\n"), Contains("scene.toml") && Contains("camera.widht_px") &&
                                                            Contains("unknown field"));
  CHECK_THAT(parse_error("colour = 3\n"), Contains("colour") && Contains("unknown"));
  CHECK_THAT(parse_error("[robot]\nspeed = \"fast\"\n"), Contains("robot.speed") && Contains("number"));
  CHECK_THAT(parse_error("[camera]\nwidth_px = 640.5\n"), Contains("camera.width_px") && Contains("integer"));
  CHECK_THAT(parse_error("[mesh]\nup_axis = \"w\"\n"), Contains("mesh.up_axis"));
  CHECK_THAT(parse_error("[[lighting.lights]]\ndirection = [0, 0]\n"), Contains("lighting.lights[0].direction"));
  CHECK_THAT(parse_error("[[lighting.lights]]\ndirection = [0, 0, 1]\nintensty = 1\n"),
             Contains("lighting.lights[0].intensty"));
  CHECK_THAT(parse_error("[grid]\ncell_size = -2\n"), Contains("grid.cell_size"));
  CHECK_THAT(parse_error("[camera\n"), Contains("scene.toml") && Contains("line 1"));
  CHECK_THAT(parse_error("camera = 3\n"), Contains("camera") && Contains("table"));
}

TEST_CASE("pixel sampling and normals are read and validated with the file and key named", "[sim_hal][config]") {
  const SceneConfig c = parse_scene_config("[camera]\npixel_samples_per_axis = 3\n[lighting]\nnormals = \"flat\"\n",
                                           "scene.toml");
  CHECK(c.shading.samples_per_axis == 3);
  CHECK(c.shading.normals == NormalMode::kFlat);
  CHECK(parse_scene_config("[lighting]\nnormals = \"smooth\"\n", "s.toml").shading.normals == NormalMode::kSmooth);
  for (const char* bad : {"0", "9", "-2"}) {
    CHECK_THAT(parse_error(std::string("[camera]\npixel_samples_per_axis = ") + bad + "\n"),
               Contains("scene.toml: camera.pixel_samples_per_axis: must be in [1, 8]"));
  }
  CHECK_THAT(parse_error("[camera]\npixel_samples_per_axis = 2.5\n"),
             Contains("camera.pixel_samples_per_axis") && Contains("integer"));
  CHECK_THAT(parse_error("[lighting]\nnormals = \"phong\"\n"),
             Contains("scene.toml: lighting.normals") && Contains("phong"));
  CHECK_THAT(parse_error("[lighting]\nnormals = 1\n"), Contains("lighting.normals") && Contains("string"));
  // A configuration built in code is checked too.
  SceneConfig in_code = SceneConfig::paper_defaults();
  in_code.source = "code";
  in_code.shading.samples_per_axis = 0;
  try {
    validate_scene_config(in_code);
    FAIL("samples_per_axis 0 accepted");
  } catch (const SimError& e) {
    CHECK_THAT(std::string(e.what()), Contains("code: camera.pixel_samples_per_axis"));
  }
  // Every message is one line.
  CHECK(parse_error("[camera]\npixel_samples_per_axis = 9\n").find('\n') == std::string::npos);
}

TEST_CASE("impossible intrinsics are refused with the field named", "[sim_hal][config]") {
  CHECK_THAT(parse_error("[camera]\nfx_px = -500.0\n"), Contains("camera.fx_px"));
  CHECK_THAT(parse_error("[camera]\ncx_px = 900.0\n"), Contains("camera.cx_px"));
  CHECK_THAT(parse_error("[camera]\nwidth_px = 0\n"), Contains("camera.width_px"));
  CHECK_THAT(parse_error("[camera]\nvertical_fov_deg = 190.0\n"), Contains("camera.vertical_fov_deg"));
  CHECK_THAT(parse_error("[camera]\nk1 = -2.0\n"), Contains("camera.k1"));
  CHECK_THAT(parse_error("[camera]\nvertical_fov_deg = 50.0\nfx_px = 500.0\n"), Contains("vertical_fov_deg"));
}

TEST_CASE("a missing or empty mesh fails the world with the file named", "[sim_hal][config]") {
  SceneConfig c = SceneConfig::paper_defaults();
  c.mesh_path = "/nonexistent/object.ply";
  try {
    SimWorld world(c);
    FAIL("SimWorld accepted a missing mesh");
  } catch (const SimError& e) {
    CHECK_THAT(std::string(e.what()), Contains("/nonexistent/object.ply"));
  }
  c.mesh_path = test::write_scratch_file("empty_mesh.off", "");
  try {
    SimWorld world(c);
    FAIL("SimWorld accepted an empty mesh");
  } catch (const SimError& e) {
    CHECK_THAT(std::string(e.what()), Contains("empty_mesh.off") && Contains("empty"));
  }
  CHECK_THROWS_AS(load_scene_config("/nonexistent/scene.toml"), SimError);
}

TEST_CASE("a relative mesh path in a scene file is relative to the file", "[sim_hal][config]") {
  const std::string scene = test::write_scratch_file("rel.toml", "[mesh]\npath = \"box.obj\"\n");
  const SceneConfig c = load_scene_config(scene);
  CHECK(c.mesh_path == (std::filesystem::path(scene).parent_path() / "box.obj").string());
}
