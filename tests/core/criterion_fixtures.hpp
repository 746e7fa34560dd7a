#pragma once
// Shared fixtures of the criterion and view-grid suites: small models built in static storage.
#include <cmath>
#include <random>

#include <Eigen/Core>

#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/model/primitive.hpp"
#include "core/model/primitive_pool.hpp"

namespace vantage::test {

inline Primitive make_primitive(const Eigen::Vector3d& X, const Eigen::Vector3f& normal, float radius,
                                const Eigen::Matrix3d& Sigma, float h) {
  Primitive p;
  p.X_world = X;
  p.normal_world = normal.normalized();
  p.radius = radius;
  p.Sigma_world = Sigma;
  p.saliency_h = h;
  return p;
}

// A random SPD covariance with standard deviations in [sigma_min, sigma_max] along random axes.
inline Eigen::Matrix3d random_covariance(std::mt19937& rng, double sigma_min, double sigma_max) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Matrix3d A;
  for (int i = 0; i < 9; ++i) A(i / 3, i % 3) = n(rng);
  Eigen::HouseholderQR<Eigen::Matrix3d> qr(A);
  const Eigen::Matrix3d Q = qr.householderQ();
  Eigen::Vector3d sigma;
  for (int i = 0; i < 3; ++i) sigma(i) = sigma_min + (sigma_max - sigma_min) * u(rng);
  return Q * sigma.array().square().matrix().asDiagonal() * Q.transpose();
}

// count primitives on a sphere (Fibonacci lattice) with outward normals and random covariances.
template <typename Pool>
void fill_sphere(Pool& pool, int count, double radius, const Eigen::Vector3d& centre, std::uint32_t seed,
                 float h = 0.5f) {
  std::mt19937 rng(seed);
  const double golden = 3.14159265358979323846 * (3.0 - std::sqrt(5.0));
  const float footprint = static_cast<float>(radius * std::sqrt(4.0 / count));
  for (int i = 0; i < count; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / count;
    const double r = std::sqrt(1.0 - z * z);
    const Eigen::Vector3d n(r * std::cos(golden * i), r * std::sin(golden * i), z);
    PrimitiveIndex index;
    const Status status = pool.insert(
        make_primitive(centre + radius * n, n.cast<float>(), footprint, random_covariance(rng, 0.01, 0.2), h), &index);
    (void)status;
  }
}

inline PinholeIntrinsics test_intrinsics() { return PinholeIntrinsics::default_vga(); }

inline Viewpoint view_from(const Eigen::Vector3d& position, const Eigen::Vector3d& target = Eigen::Vector3d::Zero()) {
  Viewpoint v;
  Status s = look_at(position, target, Eigen::Vector3d::UnitZ(), &v);
  if (!ok(s)) s = look_at(position, target, Eigen::Vector3d::UnitY(), &v);
  return v;
}

}  // namespace vantage::test
