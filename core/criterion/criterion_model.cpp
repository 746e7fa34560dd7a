#include "core/criterion/criterion_model.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

#include "core/criterion/block_kernel.hpp"
#include "core/criterion/fast_math.hpp"
#include "core/estimation/ekf.hpp"

namespace vantage {

namespace {

constexpr double kPi = 3.14159265358979323846;

// Orders slots [begin, end) of `order` (pool indices) into clusters: a median split on the axis of
// largest extent in (x, y, z, lambda n), at a multiple of kClusterSize, until a range fits one cluster.
// Ties break on the pool index, so the clusters do not depend on the order of the pool. Depth is
// log2(N / kClusterSize), about 11 for 131072 primitives.
void build_clusters(const PrimitivePoolView& pool, std::uint64_t* order, std::size_t begin, std::size_t end,
                    double normal_weight) {
  if (end - begin <= kClusterSize) return;
  double lo[6] = {1e300, 1e300, 1e300, 1e300, 1e300, 1e300};
  double hi[6] = {-1e300, -1e300, -1e300, -1e300, -1e300, -1e300};
  for (std::size_t s = begin; s < end; ++s) {
    const Primitive& p = pool[static_cast<PrimitiveIndex>(order[s])];
    const Eigen::Vector3d n = p.normal_world.cast<double>().normalized() * normal_weight;
    const double c[6] = {p.X_world.x(), p.X_world.y(), p.X_world.z(), n.x(), n.y(), n.z()};
    for (int k = 0; k < 6; ++k) {
      lo[k] = std::min(lo[k], c[k]);
      hi[k] = std::max(hi[k], c[k]);
    }
  }
  int axis = 0;
  for (int k = 1; k < 6; ++k) {
    if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
  }
  auto coordinate = [&pool, axis, normal_weight](std::uint64_t i) {
    const Primitive& p = pool[static_cast<PrimitiveIndex>(i)];
    return axis < 3 ? p.X_world(axis) : normal_weight * p.normal_world.cast<double>().normalized()(axis - 3);
  };
  const std::size_t mid = begin + ((end - begin) / 2 + kClusterSize - 1) / kClusterSize * kClusterSize;
  std::nth_element(order + begin, order + mid, order + end, [&coordinate](std::uint64_t a, std::uint64_t b) {
    const double ca = coordinate(a);
    const double cb = coordinate(b);
    return ca < cb || (ca == cb && a < b);
  });
  build_clusters(pool, order, begin, mid, normal_weight);
  build_clusters(pool, order, mid, end, normal_weight);
}

Status check_primitive(const Primitive& p) {
  if (!p.X_world.allFinite() || !p.normal_world.allFinite() || !std::isfinite(p.radius) ||
      !std::isfinite(p.saliency_h) || !p.Sigma_world.allFinite()) {
    return Status::kNonFiniteInput;
  }
  if (!is_spd(p.Sigma_world)) return Status::kNotSpd;
  if (!(p.normal_world.norm() > 1e-6f) || p.radius < 0.0f || p.saliency_h < 0.0f || p.saliency_h > 1.0f) {
    return Status::kInvalidArgument;
  }
  return Status::kOk;
}

}  // namespace

Eigen::Matrix3d compute_psi(const Eigen::Matrix3d& Sigma) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(Sigma);
  Eigen::Matrix3d psi;
  for (int k = 0; k < 3; ++k) {
    const int source = 2 - k;  // eigenvalues come ascending; Psi lists l1 >= l2 >= l3
    psi.col(k) = solver.eigenvalues()(source) * solver.eigenvectors().col(source);
  }
  return psi;
}

Status CriterionModelView::refresh(const PrimitivePoolView& pool) {
  // Pass 1: validate everything and find the variance scale and the bounding box; nothing written.
  std::size_t alive = 0;
  double scale = 0.0;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300);
  Eigen::Vector3d hi = Eigen::Vector3d::Constant(-1e300);
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (!pool.is_alive(i)) continue;
    const Primitive& p = pool[i];
    const Status status = check_primitive(p);
    if (!ok(status)) {
      rejected_index_ = i;
      return status;
    }
    ++alive;
    scale = std::max(scale, p.Sigma_world.trace() / 3.0);
    lo = lo.cwiseMin(p.X_world);
    hi = hi.cwiseMax(p.X_world);
  }
  if (alive > capacity_) {
    rejected_index_ = kInvalidPrimitive;
    return Status::kPoolFull;
  }
  rejected_index_ = kInvalidPrimitive;

  // Pass 2: order the primitives into compact clusters of similar normals. Normals weigh a quarter of
  // the model's extent per unit: on the bunny (70K, clusters of 64) that gave 19-degree cones of 3-unit
  // spheres and culled more than lighter weights (1/16: 29 degrees, 1.6 units) or heavier ones (1: 12
  // degrees, but 7-unit spheres). With clusters of 32: 14 degrees, 2.3 units.
  std::size_t n = 0;
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (pool.is_alive(i)) arrays_.sort_keys[n++] = i;
  }
  const double normal_weight = alive > 0 ? (hi - lo).maxCoeff() / 4.0 : 1.0;
  build_clusters(pool, arrays_.sort_keys, 0, n, normal_weight);

  // Pass 3: fill the slots.
  const double inv_scale = alive > 0 ? 1.0 / scale : 1.0;
  for (std::size_t s = 0; s < n; ++s) {
    const PrimitiveIndex i = static_cast<PrimitiveIndex>(arrays_.sort_keys[s] & 0xFFFFFFFFu);
    const Primitive& p = pool[i];
    const Eigen::Matrix3d S = p.Sigma_world * inv_scale;
    const Eigen::Vector3f normal = p.normal_world.normalized();
    const double h = p.saliency_h;
    const double area = kPi * static_cast<double>(p.radius) * p.radius;
    arrays_.x[s] = static_cast<float>(p.X_world.x());
    arrays_.y[s] = static_cast<float>(p.X_world.y());
    arrays_.z[s] = static_cast<float>(p.X_world.z());
    arrays_.nx[s] = normal.x();
    arrays_.ny[s] = normal.y();
    arrays_.nz[s] = normal.z();
    arrays_.s00[s] = static_cast<float>(S(0, 0));
    arrays_.s01[s] = static_cast<float>(0.5 * (S(0, 1) + S(1, 0)));
    arrays_.s02[s] = static_cast<float>(0.5 * (S(0, 2) + S(2, 0)));
    arrays_.s11[s] = static_cast<float>(S(1, 1));
    arrays_.s12[s] = static_cast<float>(0.5 * (S(1, 2) + S(2, 1)));
    arrays_.s22[s] = static_cast<float>(S(2, 2));
    // A zero-radius footprint has g = 0 and never contributes (radius > 0 is part of the view mask).
    // w = det Sigma (eq. 9), except for a primitive images do not consume (kUnconsumed): w = 0.
    arrays_.log2_wa[s] = (p.flags & primitive_flags::kUnconsumed) != 0
                             ? criterion_kernel::kZeroWeightLog2
                             : static_cast<float>(std::log2(S.determinant()) + (area > 0.0 ? h * std::log2(area) : 0.0));
    arrays_.h[s] = static_cast<float>(h);
    arrays_.radius[s] = p.radius;
    arrays_.index[s] = i;
  }
  // Padding up to a whole cluster: zero normal (never front-facing), zero radius, unit Sigma.
  const std::size_t padded = round_up_to_clusters(n);
  for (std::size_t s = n; s < padded; ++s) {
    arrays_.x[s] = n > 0 ? arrays_.x[n - 1] : 0.0f;
    arrays_.y[s] = n > 0 ? arrays_.y[n - 1] : 0.0f;
    arrays_.z[s] = n > 0 ? arrays_.z[n - 1] : 0.0f;
    arrays_.nx[s] = arrays_.ny[s] = arrays_.nz[s] = 0.0f;
    arrays_.s00[s] = arrays_.s11[s] = arrays_.s22[s] = 1.0f;
    arrays_.s01[s] = arrays_.s02[s] = arrays_.s12[s] = 0.0f;
    arrays_.log2_wa[s] = -200.0f;
    arrays_.h[s] = 0.0f;
    arrays_.radius[s] = 0.0f;
    arrays_.index[s] = kInvalidPrimitive;
  }

  // Pass 4: cluster bounds.
  for (std::size_t c = 0; c * kClusterSize < n; ++c) {
    const std::size_t begin = c * kClusterSize;
    const std::size_t end = std::min(n, begin + kClusterSize);
    Eigen::Vector3f centre = Eigen::Vector3f::Zero();
    Eigen::Vector3f normal_sum = Eigen::Vector3f::Zero();
    for (std::size_t s = begin; s < end; ++s) {
      centre += Eigen::Vector3f(arrays_.x[s], arrays_.y[s], arrays_.z[s]);
      normal_sum += Eigen::Vector3f(arrays_.nx[s], arrays_.ny[s], arrays_.nz[s]);
    }
    centre /= static_cast<float>(end - begin);
    float radius = 0.0f;
    for (std::size_t s = begin; s < end; ++s) {
      const float d = (Eigen::Vector3f(arrays_.x[s], arrays_.y[s], arrays_.z[s]) - centre).norm() + arrays_.radius[s];
      radius = std::max(radius, d);
    }
    ClusterBounds b;
    b.centre_x = centre.x();
    b.centre_y = centre.y();
    b.centre_z = centre.z();
    b.radius = radius * 1.0001f + 1e-6f;  // float rounding of the distances above
    const float mean_length = normal_sum.norm();
    if (mean_length > 1e-3f) {
      const Eigen::Vector3f axis = normal_sum / mean_length;
      float min_cos = 1.0f;
      for (std::size_t s = begin; s < end; ++s) {
        min_cos = std::min(min_cos, axis.dot(Eigen::Vector3f(arrays_.nx[s], arrays_.ny[s], arrays_.nz[s])));
      }
      min_cos -= 1e-4f;  // float rounding: keep the cone conservative
      if (min_cos > 0.0f) {
        b.axis_x = axis.x();
        b.axis_y = axis.y();
        b.axis_z = axis.z();
        b.cos_half_angle = min_cos;
        b.sin_half_angle = std::sqrt(std::max(0.0f, 1.0f - min_cos * min_cos));
      }
    }
    const ClusterArrays& a = arrays_.clusters;
    a.centre_x[c] = b.centre_x;
    a.centre_y[c] = b.centre_y;
    a.centre_z[c] = b.centre_z;
    a.radius[c] = b.radius;
    a.axis_x[c] = b.axis_x;
    a.axis_y[c] = b.axis_y;
    a.axis_z[c] = b.axis_z;
    a.sin_half_angle[c] = b.sin_half_angle;
    a.cos_half_angle[c] = b.cos_half_angle;
  }

  count_ = n;
  scale_ = alive > 0 ? scale : 1.0;
  pool_revision_ = pool.revision();
  refreshed_ = true;
  return Status::kOk;
}

ClusterBounds CriterionModelView::cluster(std::size_t c) const {
  const ClusterArrays& a = arrays_.clusters;
  ClusterBounds b;
  b.centre_x = a.centre_x[c];
  b.centre_y = a.centre_y[c];
  b.centre_z = a.centre_z[c];
  b.radius = a.radius[c];
  b.axis_x = a.axis_x[c];
  b.axis_y = a.axis_y[c];
  b.axis_z = a.axis_z[c];
  b.sin_half_angle = a.sin_half_angle[c];
  b.cos_half_angle = a.cos_half_angle[c];
  return b;
}

}  // namespace vantage
