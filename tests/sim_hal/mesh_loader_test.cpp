#include <catch2/catch.hpp>

#include "sim_hal/ground_truth/ground_truth.hpp"
#include "sim_hal/raycast_camera.hpp"
#include "sim_hal/scene/mesh_loader.hpp"
#include "sim_hal/scene/scene_config.hpp"
#include "sim_hal/scene/surface_sampler.hpp"
#include "sim_hal/sim_error.hpp"
#include "test_meshes.hpp"

using Catch::Matchers::Contains;
using namespace vantage;
using namespace vantage::sim;

namespace {

std::string error_of(const std::string& path) {
  try {
    (void)load_mesh(path);
  } catch (const SimError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("load_mesh reads OBJ PLY and OFF triangles and joins vertices", "[sim_hal][mesh]") {
  const std::string obj = test::write_scratch_file("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
  const TriangleMesh quad = load_mesh(obj);
  CHECK(quad.triangles.size() == 2);
  CHECK(quad.vertices.size() == 4);
  CHECK(quad.surface_area() == Approx(1.0));

  const std::string off = test::write_scratch_file("tri.off", "OFF\n3 1 0\n0 0 0\n2 0 0\n0 2 0\n3 0 1 2\n");
  CHECK(load_mesh(off).surface_area() == Approx(2.0));

  const std::string ply = test::write_scratch_file(
      "tri.ply",
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n0 3 0\n0 0 1\n3 0 1 2\n");
  CHECK(load_mesh(ply).surface_area() == Approx(1.5));
}

TEST_CASE("load_mesh names the file and the problem for bad input", "[sim_hal][mesh]") {
  CHECK_THAT(error_of("/nonexistent/bunny.obj"), Contains("/nonexistent/bunny.obj") && Contains("no such file"));
  const std::string empty = test::write_scratch_file("empty.obj", "");
  CHECK_THAT(error_of(empty), Contains(empty) && Contains("empty"));
  const std::string points = test::write_scratch_file("points.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\n");
  CHECK_THAT(error_of(points), Contains(points));
  const std::string corrupt = test::write_scratch_file("corrupt.ply", "ply\nformat ascii 1.0\nelement vertex 3\ngarbage\n");
  CHECK_THAT(error_of(corrupt), Contains(corrupt));
  // Inputs that hang or crash assimp 5.2 itself: caught by the structure checks.
  const std::string off_bad = test::write_scratch_file("bad.off", "OFF\n3 1 0\n0 0 0\n");
  CHECK_THAT(error_of(off_bad), Contains(off_bad) && Contains("truncated"));
  const std::string off_index = test::write_scratch_file("index.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  CHECK_THAT(error_of(off_index), Contains("out of range"));
  const std::string no_end = test::write_scratch_file(
      "noend.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n");
  CHECK_THAT(error_of(no_end), Contains("end_header"));
  const std::string binary = test::write_scratch_file(
      "short.ply",
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\nab");
  CHECK_THAT(error_of(binary), Contains("truncated"));
  for (const std::string& e : {error_of(empty), error_of(points), error_of(corrupt)}) {
    CHECK(e.find('\n') == std::string::npos);  // one line
  }
}

TEST_CASE("rotate_to_z_up turns a y-up file's up axis into world z", "[sim_hal][mesh]") {
  TriangleMesh m;
  m.vertices = {Eigen::Vector3f(0, 1, 0), Eigen::Vector3f(1, 0, 0), Eigen::Vector3f(0, 0, 1)};
  m.triangles = {{0, 1, 2}};
  const Eigen::Vector3d n_before = m.triangle_normal(0);
  rotate_to_z_up(m, UpAxis::kY);
  CHECK(m.vertices[0].isApprox(Eigen::Vector3f(0, 0, 1)));
  CHECK(m.vertices[2].isApprox(Eigen::Vector3f(0, -1, 0)));
  // A rotation: the normal turns with the mesh and keeps its length (no mirror).
  const Eigen::Vector3d n_after = m.triangle_normal(0);
  CHECK(n_after.isApprox(Eigen::Vector3d(n_before.x(), -n_before.z(), n_before.y()), 1e-6));
}

TEST_CASE("sample_surface is area weighted and deterministic", "[sim_hal][mesh]") {
  // Two triangles of area 1 and 3: about a quarter of the samples fall on the first.
  TriangleMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0}, {10, 0, 0}, {13, 0, 0}, {10, 2, 0}};
  m.triangles = {{0, 1, 2}, {3, 4, 5}};
  const auto a = sample_surface(m, 20000, 3);
  const auto b = sample_surface(m, 20000, 3);
  REQUIRE(a.size() == 20000);
  std::size_t first = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    CHECK(a[i].position == b[i].position);
    if (a[i].triangle == 0) ++first;
    CHECK(a[i].normal.isApprox(Eigen::Vector3d::UnitZ()));
  }
  CHECK(static_cast<double>(first) / a.size() == Approx(0.25).margin(0.015));
  CHECK(sample_surface(m, 10, 4)[0].position != a[0].position);
}

TEST_CASE("the normalized bunny is centred and z-up and fills about half the image at distance 40", "[sim_hal][mesh][bunny]") {
  TriangleMesh bunny = load_mesh(kDefaultMeshPath);
  CHECK(bunny.triangles.size() == 69666);
  const NormalizationConfig config;  // paper defaults: y-up file, distance 40, half the image
  const NormalizationResult result = normalize_for_paper_setup(bunny, config);
  CHECK(bunny.bounds().center().norm() < 1e-3);
  CHECK(result.mean_area_fraction == Approx(0.5).margin(0.02));

  // Measure at full resolution with the real camera: the silhouette's share of the image, mean over
  // four horizontal views at distance 40.
  const EmbreeScene scene{TriangleMesh(bunny)};
  RaycastCameraConfig camera_config;
  camera_config.shading.samples_per_axis = 1;  // only the depth (pixel centres) is used
  const RaycastCamera camera(scene, camera_config, nullptr);
  std::vector<std::uint8_t> pixels(640 * 480);
  DepthImage depth;
  double sum = 0.0;
  for (int a = 0; a < 4; ++a) {
    const double azimuth = 2.0 * test::kPi * (a + 0.5) / 4.0;
    Viewpoint view;
    REQUIRE(ok(look_at(Eigen::Vector3d(40.0 * std::cos(azimuth), 40.0 * std::sin(azimuth), 0.0), Eigen::Vector3d::Zero(),
                       Eigen::Vector3d::UnitZ(), &view)));
    REQUIRE(ok(camera.render(view, MutableGrayImageView{pixels.data(), 640, 480, 640}, &depth)));
    std::size_t hits = 0;
    for (float z : depth.camera_z) hits += std::isfinite(z) ? 1 : 0;
    sum += static_cast<double>(hits) / depth.camera_z.size();
  }
  CHECK(sum / 4.0 == Approx(0.5).margin(0.06));
  // z-up: the bunny is taller than it is deep from front to back only if the up axis was applied; the
  // glmark2 bunny's y extent (its height) becomes z.
  const TriangleMesh raw = load_mesh(kDefaultMeshPath);
  const Eigen::Vector3d raw_size = raw.bounds().sizes();
  const Eigen::Vector3d size = bunny.bounds().sizes();
  CHECK(size.z() / size.x() == Approx(raw_size.y() / raw_size.x()).epsilon(1e-3));

  // Visible-set sanity on the paper's grid: samples on the bunny's flat base (facing straight down, at
  // its lowest level) are seen from no free cell; most of the surface is. (Faces tilted 25 degrees from
  // straight down ARE seen from far cells: the scene has no ground plane.)
  const OccupancyGrid occupancy(scene.mesh(), GridGeometry{}, 1.0);
  GroundTruthConfig gt;
  gt.sample_count = 3000;
  const GroundTruth truth(scene, occupancy, PinholeIntrinsics::default_vga(), gt);
  const double z_min = bunny.bounds().min().z();
  std::size_t base = 0;
  for (std::size_t i = 0; i < truth.samples().size(); ++i) {
    const SurfaceSample& s = truth.samples()[i];
    if (s.normal.z() < -0.99 && s.position.z() < z_min + 0.02 * size.z()) {
      ++base;
      CHECK(truth.visible()[i] == 0);
    }
  }
  CHECK(base > 0);
  const double visible_fraction = static_cast<double>(truth.visible_count()) / truth.samples().size();
  CHECK(visible_fraction > 0.75);
  CHECK(visible_fraction < 0.97);
}
