#include <catch2/catch.hpp>
#include <cmath>
#include <vector>

#include "core/geometry/projection.hpp"
#include "sim_hal/raycast_camera.hpp"
#include "sim_hal/sim_clock.hpp"
#include "test_meshes.hpp"

using namespace vantage;
using namespace vantage::sim;

namespace {

PinholeIntrinsics small_intrinsics() {
  PinholeIntrinsics k;
  k.width_px = 160;
  k.height_px = 120;
  k.fx_px = k.fy_px = 140.0;
  k.cx_px = 79.5;
  k.cy_px = 59.5;
  return k;
}

Viewpoint looking_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  Viewpoint v;
  REQUIRE(ok(look_at(eye, target, Eigen::Vector3d::UnitZ(), &v)));
  return v;
}

struct FixedPose final : SimPoseSource {
  Viewpoint pose;
  Viewpoint camera_pose() const override { return pose; }
};

}  // namespace

TEST_CASE("depth of a tilted plane matches the analytic camera z within 1e-4", "[sim_hal][camera]") {
  // Plane through p0 with normal n, as a large quad.
  const Eigen::Vector3d p0(0.5, -0.2, 0.3);
  const Eigen::Vector3d n = Eigen::Vector3d(1.0, 0.4, 0.3).normalized();
  const Eigen::Vector3d t1 = n.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d t2 = n.cross(t1);
  TriangleMesh plane;
  for (const auto& c : {-1.0, 1.0}) {
    for (const auto& d : {-1.0, 1.0}) plane.vertices.push_back((p0 + 50.0 * (c * t1 + d * t2)).cast<float>());
  }
  plane.triangles = {{0, 1, 3}, {0, 3, 2}};
  const EmbreeScene scene{plane};
  for (double k1 : {0.0, -0.15}) {
    RaycastCameraConfig config;
    config.intrinsics = small_intrinsics();
    config.intrinsics.k1 = k1;
    config.threads = 2;
    const RaycastCamera camera(scene, config, nullptr);
    const Viewpoint view = looking_at(Eigen::Vector3d(12.0, 3.0, 2.0), p0);
    std::vector<std::uint8_t> pixels(160 * 120);
    DepthImage depth;
    REQUIRE(ok(camera.render(view, MutableGrayImageView{pixels.data(), 160, 120, 160}, &depth)));
    int checked = 0;
    for (int v = 0; v < 120; ++v) {
      for (int u = 0; u < 160; ++u) {
        const Eigen::Vector3d ray = back_project_ray_world(Eigen::Vector2d(u, v), view, config.intrinsics);
        const double range = n.dot(p0 - view.position_world) / n.dot(ray);
        const double camera_z = range * (view.R_world_cam.transpose() * ray).z();
        REQUIRE(depth.hit(u, v));
        CHECK(std::abs(depth.at(u, v) - camera_z) < 1e-4);
        // The ray model agrees with the core's projection (distortion included).
        Eigen::Vector2d uv;
        REQUIRE(ok(project(view.position_world + range * ray, view, config.intrinsics, &uv)));
        CHECK((uv - Eigen::Vector2d(u, v)).norm() < 1e-3);
        ++checked;
      }
    }
    CHECK(checked == 160 * 120);
  }
}

TEST_CASE("depth of a finely tessellated sphere matches the analytic sphere within 1e-4", "[sim_hal][camera]") {
  // Radius 0.5 with 512 segments: the facets deviate from the sphere by under 6e-5.
  const double radius = 0.5;
  const Eigen::Vector3d centre(0.1, -0.05, 0.025);
  const EmbreeScene scene{test::make_uv_sphere(centre.cast<float>(), static_cast<float>(radius), 512)};
  RaycastCameraConfig config;
  config.intrinsics = small_intrinsics();
  const RaycastCamera camera(scene, config, nullptr);
  const Viewpoint view = looking_at(Eigen::Vector3d(1.75, 0.5, 0.5), centre);
  std::vector<std::uint8_t> pixels(160 * 120);
  DepthImage depth;
  REQUIRE(ok(camera.render(view, MutableGrayImageView{pixels.data(), 160, 120, 160}, &depth)));
  int inside = 0;
  for (int v = 0; v < 120; ++v) {
    for (int u = 0; u < 160; ++u) {
      const Eigen::Vector3d d = back_project_ray_world(Eigen::Vector2d(u, v), view, config.intrinsics);
      const Eigen::Vector3d oc = view.position_world - centre;
      const double b = oc.dot(d);
      const double disc = b * b - (oc.squaredNorm() - radius * radius);
      if (disc < 0.05 * radius * radius) {
        // Misses (and grazing rays, where the facets' silhouette differs from the sphere's) are skipped,
        // but a clear miss must be a miss.
        if (disc < -0.05 * radius * radius) CHECK(!depth.hit(u, v));
        continue;
      }
      const double range = -b - std::sqrt(disc);
      const double camera_z = range * (view.R_world_cam.transpose() * d).z();
      REQUIRE(depth.hit(u, v));
      CHECK(std::abs(depth.at(u, v) - camera_z) < 1e-4);
      ++inside;
    }
  }
  CHECK(inside > 1000);
}

TEST_CASE("rendering is deterministic for a seed and independent of the thread count", "[sim_hal][camera]") {
  const EmbreeScene scene{test::make_uv_sphere(Eigen::Vector3f::Zero(), 1.0f, 64)};
  RaycastCameraConfig config;
  config.intrinsics = small_intrinsics();
  config.shading.lights = {DirectionalLight{Eigen::Vector3d(1, 0, 1).normalized(), 0.7}};
  config.shading.pixel_noise_sigma = 3.0;
  config.seed = 5;
  RaycastCamera one(scene, config, nullptr);
  one.set_threads(1);
  RaycastCamera two(scene, config, nullptr);
  two.set_threads(2);
  config.seed = 6;
  const RaycastCamera other_seed(scene, config, nullptr);
  const Viewpoint view = looking_at(Eigen::Vector3d(4.0, 0.0, 0.5), Eigen::Vector3d::Zero());
  std::vector<std::uint8_t> a(160 * 120), b(160 * 120), c(160 * 120), d(160 * 120);
  REQUIRE(ok(one.render(view, MutableGrayImageView{a.data(), 160, 120, 160}, nullptr, 3)));
  REQUIRE(ok(two.render(view, MutableGrayImageView{b.data(), 160, 120, 160}, nullptr, 3)));
  REQUIRE(ok(other_seed.render(view, MutableGrayImageView{c.data(), 160, 120, 160}, nullptr, 3)));
  REQUIRE(ok(two.render(view, MutableGrayImageView{d.data(), 160, 120, 160}, nullptr, 4)));
  CHECK(a == b);
  CHECK(a != c);
  CHECK(a != d);  // another frame draws other noise
}

TEST_CASE("shading: texture varies the albedo and constant albedo is lighting only", "[sim_hal][camera]") {
  const EmbreeScene scene{test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(0.1f, 5.0f, 5.0f))};
  RaycastCameraConfig config;
  config.intrinsics = small_intrinsics();
  config.shading.lights = {DirectionalLight{Eigen::Vector3d::UnitX(), 0.6}};
  config.shading.ambient = 0.2;
  config.shading.albedo.mode = AlbedoMode::kConstant;
  config.shading.albedo.constant = 0.5;
  const Viewpoint view = looking_at(Eigen::Vector3d(6.0, 0.0, 0.0), Eigen::Vector3d::Zero());
  std::vector<std::uint8_t> pixels(160 * 120);
  {
    const RaycastCamera camera(scene, config, nullptr);
    REQUIRE(ok(camera.render(view, MutableGrayImageView{pixels.data(), 160, 120, 160}, nullptr)));
    // The face x = 0.1 faces the light head on: 255 * 0.5 * (0.2 + 0.6) = 102.
    CHECK(int{pixels[60 * 160 + 80]} == 102);
    CHECK(int{pixels[0]} == 102);
  }
  config.shading.albedo.mode = AlbedoMode::kTexture;
  const RaycastCamera camera(scene, config, nullptr);
  REQUIRE(ok(camera.render(view, MutableGrayImageView{pixels.data(), 160, 120, 160}, nullptr)));
  double mean = 0.0, mean2 = 0.0;
  for (std::uint8_t p : pixels) {
    mean += p;
    mean2 += static_cast<double>(p) * p;
  }
  mean /= pixels.size();
  const double stddev = std::sqrt(mean2 / pixels.size() - mean * mean);
  CHECK(stddev > 8.0);  // texture for the matcher
  CHECK(mean == Approx(102.0).margin(20.0));
}

TEST_CASE("grab renders at the pose source's pose with clock timestamps and refuses small buffers", "[sim_hal][camera]") {
  const EmbreeScene scene{test::make_uv_sphere(Eigen::Vector3f::Zero(), 1.0f, 32)};
  RaycastCameraConfig config;
  config.intrinsics = small_intrinsics();
  FixedPose pose;
  pose.pose = looking_at(Eigen::Vector3d(4.0, 0.0, 0.0), Eigen::Vector3d::Zero());
  SimClock clock;
  clock.advance(1.25);
  RaycastCamera camera(scene, config, &pose, &clock);
  std::vector<std::uint8_t> buffer(160 * 120), direct(160 * 120);
  MutableGrayImageView out{buffer.data(), 160, 120, 160};
  hal::FrameInfo info;
  REQUIRE(camera.grab(out, info, 0) == hal::CaptureStatus::kOk);
  CHECK(info.timestamp_ns == 1250000000);
  CHECK(info.sequence == 0);
  REQUIRE(ok(camera.render(pose.pose, MutableGrayImageView{direct.data(), 160, 120, 160}, nullptr, 0)));
  CHECK(buffer == direct);
  REQUIRE(camera.grab(out, info, 0) == hal::CaptureStatus::kOk);
  CHECK(info.sequence == 1);
  MutableGrayImageView small{buffer.data(), 80, 60, 80};
  CHECK(camera.grab(small, info, 0) == hal::CaptureStatus::kBufferTooSmall);
  RaycastCamera no_pose(scene, config, nullptr);
  CHECK(no_pose.grab(out, info, 0) == hal::CaptureStatus::kNotStarted);
  // A non-rotation viewpoint is refused.
  Viewpoint bad = pose.pose;
  bad.R_world_cam *= 2.0;
  CHECK(camera.render(bad, out, nullptr) == Status::kInvalidArgument);
}
