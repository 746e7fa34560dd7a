#pragma once
// PrecisionLevel(M) of Fig. 3: the average 3D standard deviation over the model's primitives.
// A primitive's sigma is sqrt(trace(Sigma) / 3), the root mean square of its per-axis standard
// deviations (scene units). The paper's goal "average 3D uncertainty sigma < 0.008 units across all
// primitives" is average_sigma() < rho. sim_hal's ground-truth report should use the same
// primitive_sigma() so the planner's stop and the reported figure agree.
#include <cmath>
#include <cstddef>

#include <Eigen/Core>

#include "core/model/primitive_pool.hpp"

namespace vantage {

inline double primitive_sigma(const Eigen::Matrix3d& Sigma_world) {
  const double mean_variance = Sigma_world.trace() / 3.0;
  return mean_variance > 0.0 ? std::sqrt(mean_variance) : 0.0;
}

// Mean of primitive_sigma over alive primitives; 0 for an empty pool (count_out gets 0).
inline double average_sigma(const PrimitivePoolView& pool, std::size_t* count_out = nullptr) {
  double sum = 0.0;
  std::size_t count = 0;
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (!pool.is_alive(i)) continue;
    sum += primitive_sigma(pool[i].Sigma_world);
    ++count;
  }
  if (count_out != nullptr) *count_out = count;
  return count > 0 ? sum / static_cast<double>(count) : 0.0;
}

}  // namespace vantage
