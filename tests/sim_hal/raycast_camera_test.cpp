#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/geometry/projection.hpp"
#include "sim_hal/raycast_camera.hpp"
#include "sim_hal/sim_clock.hpp"
#include "sim_hal/sim_error.hpp"
#include "test_meshes.hpp"

using namespace vantage;
using namespace vantage::sim;

namespace {

using test::looking_at;
using test::small_intrinsics;

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

namespace {

// Mean of n x n point renders whose pixel centres sit at the sub-sample positions: shifting the principal
// point by -d moves every pixel's ray to the one through (u + d.x, v + d.y) of the unshifted camera, with
// or without distortion (which acts on the normalized coordinates).
std::vector<double> mean_of_point_renders(const EmbreeScene& scene, RaycastCameraConfig config, const Viewpoint& view,
                                          int n) {
  const PinholeIntrinsics k = config.intrinsics;
  std::vector<double> mean(static_cast<std::size_t>(k.width_px) * k.height_px, 0.0);
  std::vector<std::uint8_t> pixels(mean.size());
  config.shading.samples_per_axis = 1;
  for (int sy = 0; sy < n; ++sy) {
    for (int sx = 0; sx < n; ++sx) {
      config.intrinsics.cx_px = k.cx_px - ((sx + 0.5) / n - 0.5);
      config.intrinsics.cy_px = k.cy_px - ((sy + 0.5) / n - 0.5);
      const RaycastCamera camera(scene, config, nullptr);
      REQUIRE(ok(camera.render(view, MutableGrayImageView{pixels.data(), k.width_px, k.height_px, k.width_px}, nullptr)));
      for (std::size_t i = 0; i < mean.size(); ++i) mean[i] += pixels[i] / static_cast<double>(n * n);
    }
  }
  return mean;
}

RaycastCameraConfig lit_textured_config() {
  RaycastCameraConfig config;
  config.intrinsics = small_intrinsics();
  config.shading.lights = {DirectionalLight{Eigen::Vector3d(1, -1, 1).normalized(), 0.6},
                           DirectionalLight{Eigen::Vector3d(-1, 1, 0.5).normalized(), 0.3}};
  config.shading.ambient = 0.2;
  config.shading.albedo.texture_feature_size = 0.04;  // about two pixels: it varies inside a pixel
  return config;
}

}  // namespace

TEST_CASE("an n x n pixel is the mean of the n^2 point renders at its sub-sample positions", "[sim_hal][camera]") {
  // A coarse sphere (facets several pixels wide, silhouette) with a fine texture: neighbouring sub-samples differ.
  const EmbreeScene scene{test::make_uv_sphere(Eigen::Vector3f::Zero(), 1.0f, 24)};
  const Viewpoint view = looking_at(Eigen::Vector3d(3.2, 0.8, 0.9), Eigen::Vector3d::Zero());
  for (const double k1 : {0.0, -0.15}) {
    for (const int n : {2, 3}) {
      for (const NormalMode normals : {NormalMode::kFlat, NormalMode::kSmooth}) {
        CAPTURE(k1, n, to_string(normals));
        RaycastCameraConfig config = lit_textured_config();
        config.intrinsics.k1 = k1;
        config.shading.normals = normals;
        const std::vector<double> expected = mean_of_point_renders(scene, config, view, n);
        config.shading.samples_per_axis = n;
        const RaycastCamera camera(scene, config, nullptr);
        std::vector<std::uint8_t> pixels(expected.size());
        REQUIRE(ok(camera.render(view, MutableGrayImageView{pixels.data(), 160, 120, 160}, nullptr)));
        // The mean of rounded renders and the rounded mean differ by at most 1; a ray exactly on a
        // triangle edge or the silhouette may land on the other side after interpolation's float rounding.
        int off = 0;
        double differing_from_centre = 0.0;
        std::vector<std::uint8_t> centre(expected.size());
        config.shading.samples_per_axis = 1;
        const RaycastCamera point(scene, config, nullptr);
        REQUIRE(ok(point.render(view, MutableGrayImageView{centre.data(), 160, 120, 160}, nullptr)));
        for (std::size_t i = 0; i < pixels.size(); ++i) {
          if (std::abs(static_cast<double>(pixels[i]) - expected[i]) > 1.0) ++off;
          if (std::abs(static_cast<double>(pixels[i]) - expected[i]) <= 1.0 && std::abs(static_cast<double>(pixels[i]) - static_cast<double>(centre[i])) > 1.0) {
            ++differing_from_centre;
          }
        }
        CHECK(off <= 3);
        // Not a trivial pass: on many pixels the area mean is not the centre sample.
        CHECK(differing_from_centre > 500);
      }
    }
  }
}

TEST_CASE("an n x n render keeps the pixel-centre depth", "[sim_hal][camera]") {
  const EmbreeScene scene{test::make_uv_sphere(Eigen::Vector3f::Zero(), 1.0f, 24)};
  const Viewpoint view = looking_at(Eigen::Vector3d(3.2, 0.8, 0.9), Eigen::Vector3d::Zero());
  RaycastCameraConfig config = lit_textured_config();
  std::vector<std::uint8_t> pixels(160 * 120);
  DepthImage centre_depth;
  REQUIRE(ok(RaycastCamera(scene, config, nullptr).render(view, MutableGrayImageView{pixels.data(), 160, 120, 160},
                                                          &centre_depth)));
  for (const int n : {2, 3, 4}) {
    config.shading.samples_per_axis = n;
    DepthImage depth;
    REQUIRE(ok(RaycastCamera(scene, config, nullptr).render(view, MutableGrayImageView{pixels.data(), 160, 120, 160},
                                                            &depth)));
    CHECK(depth.camera_z == centre_depth.camera_z);
  }
}

TEST_CASE("smooth normals shade a coarse sphere continuously and flat normals in steps", "[sim_hal][camera]") {
  // 24 segments: facets of 15 degrees, many pixels wide. Constant albedo: the gray is the lighting only.
  const Eigen::Vector3d centre(0.0, 0.0, 0.0);
  const EmbreeScene scene{test::make_uv_sphere(centre.cast<float>(), 1.0f, 24)};
  RaycastCameraConfig config;
  config.intrinsics = small_intrinsics();
  config.shading.lights = {DirectionalLight{Eigen::Vector3d(1, -0.5, 0.8).normalized(), 0.7}};
  config.shading.ambient = 0.1;
  config.shading.albedo.mode = AlbedoMode::kConstant;
  config.shading.albedo.constant = 1.0;
  const Viewpoint view = looking_at(Eigen::Vector3d(3.0, 0.0, 0.4), centre);
  // max_step: the largest difference between a neighbouring-pixel step of the render and that of the
  // analytic sphere's shading (a facet edge is a step the sphere does not have); max_error: the render
  // against the analytic shading.
  auto measure = [&](NormalMode normals, double* max_step, double* max_error) {
    config.shading.normals = normals;
    const RaycastCamera camera(scene, config, nullptr);
    std::vector<std::uint8_t> pixels(160 * 120);
    DepthImage depth;
    REQUIRE(ok(camera.render(view, MutableGrayImageView{pixels.data(), 160, 120, 160}, &depth)));
    const Eigen::Vector3d light = config.shading.lights[0].direction_world.normalized();
    // Analytic shading of the sphere at the pixel's hit; NaN where the ray is grazing or misses.
    std::vector<double> analytic(160 * 120, std::nan(""));
    for (int v = 0; v < 120; ++v) {
      for (int u = 0; u < 160; ++u) {
        const Eigen::Vector3d ray = back_project_ray_world(Eigen::Vector2d(u, v), view, config.intrinsics);
        const Eigen::Vector3d oc = view.position_world - centre;
        const double b = oc.dot(ray);
        const double disc = b * b - (oc.squaredNorm() - 1.0);
        if (disc <= 0.0 || !depth.hit(u, v)) continue;
        // The sphere's normal at the facet point the ray hit (the facets are the geometry being shaded).
        const Eigen::Vector3d X = view.position_world + depth.at(u, v) / (view.R_world_cam.transpose() * ray).z() * ray;
        const Eigen::Vector3d n_true = (X - centre).normalized();
        if (-n_true.dot(ray) < 0.3) continue;  // grazing: the facets' silhouette differs from the sphere's
        analytic[v * 160 + u] = 255.0 * (0.1 + 0.7 * std::max(0.0, n_true.dot(light)));
      }
    }
    *max_step = 0.0;
    *max_error = 0.0;
    int interior = 0;
    for (int v = 0; v + 1 < 120; ++v) {
      for (int u = 0; u + 1 < 160; ++u) {
        const int i = v * 160 + u;
        if (std::isnan(analytic[i])) continue;
        ++interior;
        *max_error = std::max(*max_error, std::abs(static_cast<double>(pixels[i]) - analytic[i]));
        for (const int j : {i + 1, i + 160}) {
          if (std::isnan(analytic[j])) continue;
          const double rendered_step = static_cast<double>(pixels[j]) - static_cast<double>(pixels[i]);
          *max_step = std::max(*max_step, std::abs(rendered_step - (analytic[j] - analytic[i])));
        }
      }
    }
    CHECK(interior > 2000);
  };
  double flat_step = 0.0, flat_error = 0.0, smooth_step = 0.0, smooth_error = 0.0;
  measure(NormalMode::kFlat, &flat_step, &flat_error);
  measure(NormalMode::kSmooth, &smooth_step, &smooth_error);
  CAPTURE(flat_step, flat_error, smooth_step, smooth_error);
  CHECK(flat_step > 10.0);    // a step at every facet edge
  CHECK(smooth_step < 4.0);   // no steps beyond the sphere's own shading change (and rounding)
  CHECK(smooth_error < 6.0);  // and it follows the true sphere closely
  CHECK(flat_error > 10.0);
}

TEST_CASE("smooth corner normals keep a box's faces flat and follow a sphere", "[sim_hal][camera]") {
  const TriangleMesh box = test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(1.0f, 2.0f, 3.0f));
  const std::vector<Eigen::Vector3f> box_normals = smooth_corner_normals(box, kSmoothCreaseAngleRad);
  REQUIRE(box_normals.size() == 3 * box.triangles.size());
  for (std::size_t t = 0; t < box.triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) CHECK((box_normals[3 * t + c].cast<double>() - box.triangle_normal(t)).norm() < 1e-6);
  }
  const TriangleMesh sphere = test::make_uv_sphere(Eigen::Vector3f::Zero(), 2.0f, 48);
  const std::vector<Eigen::Vector3f> sphere_normals = smooth_corner_normals(sphere, kSmoothCreaseAngleRad);
  double worst = 0.0;
  for (std::size_t t = 0; t < sphere.triangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector3f radial = sphere.vertices[sphere.triangles[t][c]].normalized();
      // The test sphere's poles are a fan of separate vertices, each with two triangles only.
      if (std::abs(radial.z()) > 0.95f) continue;
      worst = std::max(worst, static_cast<double>((sphere_normals[3 * t + c] - radial).norm()));
    }
  }
  CHECK(worst < 0.02);
}

TEST_CASE("the camera refuses a pixel sample count outside [1, 8]", "[sim_hal][camera]") {
  const EmbreeScene scene{test::make_uv_sphere(Eigen::Vector3f::Zero(), 1.0f, 16)};
  RaycastCameraConfig config;
  config.intrinsics = small_intrinsics();
  for (const int n : {0, -1, 9}) {
    config.shading.samples_per_axis = n;
    CHECK_THROWS_AS(RaycastCamera(scene, config, nullptr), SimError);
  }
  config.shading.samples_per_axis = 8;
  CHECK_NOTHROW(RaycastCamera(scene, config, nullptr));
}
