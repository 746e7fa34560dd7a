#pragma once
// Small analytic meshes, the small camera they are seen with and its views, and scratch files for the
// sim_hal tests.
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

#include <catch2/catch.hpp>

#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "sim_hal/scene/triangle_mesh.hpp"

namespace vantage::sim::test {

inline constexpr double kPi = 3.14159265358979323846;

// A 160 x 120 camera with a 140 px focal length: quick renders and ray casts.
inline PinholeIntrinsics small_intrinsics() {
  PinholeIntrinsics k;
  k.width_px = 160;
  k.height_px = 120;
  k.fx_px = k.fy_px = 140.0;
  k.cx_px = 79.5;
  k.cy_px = 59.5;
  return k;
}

// A camera at eye looking at target (the origin by default), +z up.
inline Viewpoint looking_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target = Eigen::Vector3d::Zero()) {
  Viewpoint v;
  REQUIRE(ok(look_at(eye, target, Eigen::Vector3d::UnitZ(), &v)));
  return v;
}

// Axis-aligned box centred at centre with the given half sizes, outward winding.
inline TriangleMesh make_box(const Eigen::Vector3f& centre, const Eigen::Vector3f& half) {
  TriangleMesh m;
  for (int i = 0; i < 8; ++i) {
    m.vertices.emplace_back(centre.x() + ((i & 1) ? half.x() : -half.x()), centre.y() + ((i & 2) ? half.y() : -half.y()),
                            centre.z() + ((i & 4) ? half.z() : -half.z()));
  }
  // Faces as quads (a, b, c, d) counter-clockwise seen from outside.
  const std::uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
  }
  return m;
}

// Latitude-longitude sphere with `segments` around and segments / 2 from pole to pole.
inline TriangleMesh make_uv_sphere(const Eigen::Vector3f& centre, float radius, int segments) {
  TriangleMesh m;
  const int rings = segments / 2;
  for (int r = 0; r <= rings; ++r) {
    const double theta = kPi * r / rings;
    for (int s = 0; s < segments; ++s) {
      const double phi = 2.0 * kPi * s / segments;
      m.vertices.emplace_back(centre.x() + radius * static_cast<float>(std::sin(theta) * std::cos(phi)),
                              centre.y() + radius * static_cast<float>(std::sin(theta) * std::sin(phi)),
                              centre.z() + radius * static_cast<float>(std::cos(theta)));
    }
  }
  auto at = [segments](int r, int s) { return static_cast<std::uint32_t>(r * segments + (s % segments)); };
  for (int r = 0; r < rings; ++r) {
    for (int s = 0; s < segments; ++s) {
      if (r > 0) m.triangles.push_back({at(r, s), at(r + 1, s), at(r, s + 1)});
      if (r + 1 < rings) m.triangles.push_back({at(r, s + 1), at(r + 1, s), at(r + 1, s + 1)});
    }
  }
  return m;
}

// A file under a per-process scratch directory, written with the given content.
inline std::string write_scratch_file(const std::string& name, const std::string& content) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("vantage_sim_hal_tests_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::filesystem::path path = dir / name;
  std::ofstream(path, std::ios::binary) << content;
  return path.string();
}

}  // namespace vantage::sim::test
