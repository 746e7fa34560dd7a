#pragma once
// Synthetic images for the front end's core tests: a textured plane rendered analytically (ray-plane
// intersection, smooth value-noise albedo), small enough for Debug, ASan and qemu.
#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "core/frontend/image_front_end.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/projection.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/image/gray_image.hpp"

namespace vantage::test {

// A small camera with the paper's 45 degree vertical field of view.
inline PinholeIntrinsics small_intrinsics(std::int32_t width = 160, std::int32_t height = 120) {
  PinholeIntrinsics k;
  k.width_px = width;
  k.height_px = height;
  k.fy_px = 0.5 * height / std::tan(0.5 * 45.0 * 3.14159265358979323846 / 180.0);
  k.fx_px = k.fy_px;
  k.cx_px = 0.5 * (width - 1);
  k.cy_px = 0.5 * (height - 1);
  return k;
}

// Smooth, non-periodic value noise in [0, 1] with features about `cell` units across.
inline double value_noise(double a, double b, double cell) {
  auto lattice = [](std::int64_t i, std::int64_t j) {
    std::uint64_t h = static_cast<std::uint64_t>(i) * 0x9E3779B97F4A7C15ull ^ static_cast<std::uint64_t>(j) * 0xC2B2AE3D27D4EB4Full;
    h ^= h >> 29;
    h *= 0xBF58476D1CE4E5B9ull;
    h ^= h >> 32;
    return static_cast<double>(h & 0xFFFF) / 65535.0;
  };
  const double x = a / cell;
  const double y = b / cell;
  const double fx = std::floor(x);
  const double fy = std::floor(y);
  const auto i = static_cast<std::int64_t>(fx);
  const auto j = static_cast<std::int64_t>(fy);
  auto smooth = [](double t) { return t * t * (3.0 - 2.0 * t); };
  const double tx = smooth(x - fx);
  const double ty = smooth(y - fy);
  const double top = lattice(i, j) * (1 - tx) + lattice(i + 1, j) * tx;
  const double bottom = lattice(i, j + 1) * (1 - tx) + lattice(i + 1, j + 1) * tx;
  return top * (1 - ty) + bottom * ty;
}

// The plane n . X = offset, textured in its own 2D coordinates (e1, e2).
struct TexturedPlane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitX();
  double offset = 0.0;
  double feature_size = 0.5;  // scene units

  void basis(Eigen::Vector3d* e1, Eigen::Vector3d* e2) const {
    const Eigen::Vector3d helper = std::abs(normal.z()) < 0.9 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitX();
    *e1 = normal.cross(helper).normalized();
    *e2 = normal.cross(*e1);
  }
  double albedo_2d(double a, double b) const {
    return 0.6 * value_noise(a, b, feature_size) + 0.4 * value_noise(a + 17.3, b - 5.1, 0.5 * feature_size);
  }
  // Where the ray through uv meets the plane; false when it does not (in front of the camera).
  bool intersect(const Eigen::Vector2d& uv, const Viewpoint& view, const PinholeIntrinsics& k, Eigen::Vector3d* X) const {
    const Eigen::Vector3d ray = back_project_ray_world(uv, view, k);
    const double denominator = normal.dot(ray);
    if (std::abs(denominator) < 1e-12) return false;
    const double t = (offset - normal.dot(view.position_world)) / denominator;
    if (!(t > 0.0)) return false;
    *X = view.position_world + t * ray;
    return true;
  }
};

// Renders the plane (no lens distortion) with 2x2 supersampling, gray 30..230; background 0. Plain
// scalar arithmetic: the core tests also run in Debug and under qemu.
inline void render_plane(const TexturedPlane& plane, const Viewpoint& view, const PinholeIntrinsics& k,
                         std::vector<std::uint8_t>* pixels) {
  pixels->assign(static_cast<std::size_t>(k.width_px) * k.height_px, 0);
  Eigen::Vector3d e1;
  Eigen::Vector3d e2;
  plane.basis(&e1, &e2);
  const Eigen::Matrix3d& R = view.R_world_cam;
  const Eigen::Vector3d& C = view.position_world;
  const double n_c = plane.normal.dot(C);
  // Ray (before normalization) = R * (xn, yn, 1) = r0 + xn * rx + yn * ry.
  const double r0[3] = {R(0, 2), R(1, 2), R(2, 2)};
  const double rx[3] = {R(0, 0), R(1, 0), R(2, 0)};
  const double ry[3] = {R(0, 1), R(1, 1), R(2, 1)};
  const double n[3] = {plane.normal.x(), plane.normal.y(), plane.normal.z()};
  const double a_c = e1.dot(C);
  const double b_c = e2.dot(C);
  for (std::int32_t y = 0; y < k.height_px; ++y) {
    for (std::int32_t x = 0; x < k.width_px; ++x) {
      double sum = 0.0;
      int hits = 0;
      for (int sy = 0; sy < 2; ++sy) {
        for (int sx = 0; sx < 2; ++sx) {
          const double xn = (x - 0.25 + 0.5 * sx - k.cx_px) / k.fx_px;
          const double yn = (y - 0.25 + 0.5 * sy - k.cy_px) / k.fy_px;
          double d[3];
          for (int i = 0; i < 3; ++i) d[i] = r0[i] + xn * rx[i] + yn * ry[i];
          const double denominator = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
          if (std::abs(denominator) < 1e-12) continue;
          const double t = (plane.offset - n_c) / denominator;
          if (!(t > 0.0)) continue;
          const double a = a_c + t * (e1.x() * d[0] + e1.y() * d[1] + e1.z() * d[2]);
          const double b = b_c + t * (e2.x() * d[0] + e2.y() * d[1] + e2.z() * d[2]);
          sum += plane.albedo_2d(a, b);
          ++hits;
        }
      }
      const double gray = hits > 0 ? 30.0 + 200.0 * sum / 4.0 : 0.0;
      (*pixels)[static_cast<std::size_t>(y) * k.width_px + x] = static_cast<std::uint8_t>(std::lround(gray));
    }
  }
}

inline GrayImageView view_of(const std::vector<std::uint8_t>& pixels, const PinholeIntrinsics& k) {
  return GrayImageView{pixels.data(), k.width_px, k.height_px, k.width_px};
}

inline Viewpoint looking_at_origin(const Eigen::Vector3d& position) {
  Viewpoint view;
  (void)look_at(position, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &view);
  return view;
}

// The textured plane x = 0 in the small camera, as most front-end tests image it.
struct PlaneScene {
  PinholeIntrinsics k = small_intrinsics();
  TexturedPlane plane;
  std::vector<std::uint8_t> render(const Viewpoint& view) const {
    std::vector<std::uint8_t> pixels;
    render_plane(plane, view, k, &pixels);
    return pixels;
  }
};

// configure() with config, then initialize() from the plane's images at first and second (the pool
// cleared first); the first failing status, with the spawn counts in *report.
inline Status initialize_on_plane(ImageFrontEnd& front_end, PrimitivePoolView& pool, const PlaneScene& scene,
                                  const Viewpoint& first, const Viewpoint& second, const FrontEndConfig& config,
                                  UpdateReport* report) {
  pool.clear();
  const Status configured = front_end.configure(scene.k, config);
  if (!ok(configured)) return configured;
  const auto a = scene.render(first);
  const auto b = scene.render(second);
  return front_end.initialize(view_of(a, scene.k), first, view_of(b, scene.k), second, pool, report);
}

}  // namespace vantage::test
