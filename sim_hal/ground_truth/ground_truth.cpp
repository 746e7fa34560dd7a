#include "sim_hal/ground_truth/ground_truth.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>

#include "core/geometry/projection.hpp"
#include "sim_hal/sim_error.hpp"

namespace vantage::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kAzimuthBins = 36;

// Runs body(i) for i in [0, n) on `threads` threads (interleaved blocks of 64).
template <typename Body>
void parallel_for(std::size_t n, int threads, const Body& body) {
  const int count = std::max(1, threads);
  std::atomic<std::size_t> next{0};
  auto worker = [&] {
    for (;;) {
      const std::size_t begin = next.fetch_add(64);
      if (begin >= n) return;
      const std::size_t end = std::min(n, begin + 64);
      for (std::size_t i = begin; i < end; ++i) body(i);
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < count; ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
}

int azimuth_bin(double azimuth) {
  int bin = static_cast<int>(std::floor((azimuth + kPi) / (2.0 * kPi) * kAzimuthBins));
  return ((bin % kAzimuthBins) + kAzimuthBins) % kAzimuthBins;
}

// Uniform grid over a box holding point indices in CSR form, for radius queries with radius <= cell.
class PointGrid {
 public:
  PointGrid(const Eigen::AlignedBox3d& box, double cell, const std::vector<Eigen::Vector3d>& points)
      : origin_(box.min()), inv_cell_(1.0 / cell), points_(points) {
    const Eigen::Vector3d extent = box.sizes();
    for (int a = 0; a < 3; ++a) {
      dims_[a] = std::max<std::int64_t>(1, std::min<std::int64_t>(512, static_cast<std::int64_t>(std::ceil(extent[a] * inv_cell_))));
    }
    // Coarser cells when the box is large for d: the query then scans more points per cell but stays right.
    for (int a = 0; a < 3; ++a) cell_size_[a] = std::max(cell, extent[a] / static_cast<double>(dims_[a]));
    const std::size_t cells = static_cast<std::size_t>(dims_[0] * dims_[1] * dims_[2]);
    start_.assign(cells + 1, 0);
    std::vector<std::int64_t> key(points.size(), -1);
    for (std::size_t i = 0; i < points.size(); ++i) {
      key[i] = key_of(points[i]);
      if (key[i] >= 0) ++start_[static_cast<std::size_t>(key[i]) + 1];
    }
    for (std::size_t c = 0; c < cells; ++c) start_[c + 1] += start_[c];
    items_.resize(start_[cells]);
    std::vector<std::size_t> fill(start_.begin(), start_.end() - 1);
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (key[i] >= 0) items_[fill[static_cast<std::size_t>(key[i])]++] = static_cast<std::uint32_t>(i);
    }
  }

  bool any_within(const Eigen::Vector3d& q, double radius) const {
    std::int64_t lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor((q[a] - radius - origin_[a]) / cell_size_[a])));
      hi[a] = std::min<std::int64_t>(dims_[a] - 1, static_cast<std::int64_t>(std::floor((q[a] + radius - origin_[a]) / cell_size_[a])));
      if (lo[a] > hi[a]) return false;
    }
    const double r2 = radius * radius;
    for (std::int64_t z = lo[2]; z <= hi[2]; ++z) {
      for (std::int64_t y = lo[1]; y <= hi[1]; ++y) {
        for (std::int64_t x = lo[0]; x <= hi[0]; ++x) {
          const std::size_t c = static_cast<std::size_t>((z * dims_[1] + y) * dims_[0] + x);
          for (std::size_t k = start_[c]; k < start_[c + 1]; ++k) {
            if ((points_[items_[k]] - q).squaredNorm() <= r2) return true;
          }
        }
      }
    }
    return false;
  }

 private:
  std::int64_t key_of(const Eigen::Vector3d& p) const {
    std::int64_t idx[3];
    for (int a = 0; a < 3; ++a) {
      const double f = std::floor((p[a] - origin_[a]) / cell_size_[a]);
      if (!(f >= 0.0) || f >= static_cast<double>(dims_[a])) return -1;
      idx[a] = static_cast<std::int64_t>(f);
    }
    return (idx[2] * dims_[1] + idx[1]) * dims_[0] + idx[0];
  }

  Eigen::Vector3d origin_;
  double inv_cell_;
  Eigen::Vector3d cell_size_;
  std::int64_t dims_[3];
  const std::vector<Eigen::Vector3d>& points_;
  std::vector<std::size_t> start_;
  std::vector<std::uint32_t> items_;
};

}  // namespace

double primitive_sigma(const Primitive& primitive) {
  return std::sqrt(std::max(0.0, primitive.Sigma_world.trace()) / 3.0);
}

Viewpoint grid_cell_viewpoint(const GridGeometry& grid, const GridCell& cell) {
  Viewpoint view;
  const Eigen::Vector3d centre(grid.center_xy.x(), grid.center_xy.y(), grid.elevation_m);
  const Eigen::Vector3d eye = grid.cell_center_world(cell);
  if (!ok(look_at(eye, centre, Eigen::Vector3d::UnitZ(), &view))) {
    // Only the grid centre itself has no direction to look; it is never a cell centre for even M, and
    // for odd M the centre cell is under the object. Look along +x there.
    view.position_world = eye;
    view.R_world_cam << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  }
  return view;
}

bool GroundTruth::visible_from(const EmbreeScene& scene, const PinholeIntrinsics& intrinsics, const Viewpoint& view,
                               const Eigen::Vector3d& point, const Eigen::Vector3d& normal, double margin_px,
                               double min_cos_incidence) {
  const Eigen::Vector3d to_camera = view.position_world - point;
  const double distance = to_camera.norm();
  if (!(distance > 0.0) || normal.dot(to_camera) <= min_cos_incidence * distance) return false;
  Eigen::Vector2d uv;
  if (!ok(project(point, view, intrinsics, &uv)) || !in_image(uv, intrinsics, margin_px)) return false;
  return !scene.occluded(view.position_world, point, std::min(1e-3, 0.25 * distance));
}

GroundTruth::GroundTruth(const EmbreeScene& scene, const OccupancyGrid& occupancy, const PinholeIntrinsics& intrinsics,
                         const GroundTruthConfig& config)
    : scene_(scene), config_(config) {
  if (config.sample_count == 0) throw SimError("ground truth: sample_count must be positive");
  if (!(config.coverage_distance > 0.0) || !(config.sigma_target > 0.0)) {
    throw SimError("ground truth: coverage_distance and sigma_target must be positive");
  }
  if (!ok(intrinsics.validate())) throw SimError("ground truth: invalid intrinsics");
  if (!(config.image_margin_px >= 0.0) || !(config.min_cos_incidence >= 0.0 && config.min_cos_incidence < 1.0)) {
    throw SimError("ground truth: image_margin_px must be >= 0 and min_cos_incidence in [0, 1)");
  }
  surface_area_ = scene.mesh().surface_area();
  samples_ = sample_surface(scene.mesh(), config.sample_count, config.seed);
  visible_.assign(samples_.size(), 0);

  // Free cells' viewpoints, bucketed by the azimuth of the cell seen from the grid centre, so a sample
  // tries the cells its normal faces first and most visible samples stop after a few rays.
  const GridGeometry& grid = occupancy.geometry();
  std::vector<Viewpoint> views;
  std::vector<std::vector<std::uint32_t>> bins(kAzimuthBins);
  for (std::int32_t i = 0; i < grid.cell_count(); ++i) {
    const GridCell cell = grid.cell_at(i);
    if (occupancy.occupied(cell)) continue;
    const Viewpoint v = grid_cell_viewpoint(grid, cell);
    const Eigen::Vector2d rel = v.position_world.head<2>() - grid.center_xy;
    bins[azimuth_bin(std::atan2(rel.y(), rel.x()))].push_back(static_cast<std::uint32_t>(views.size()));
    views.push_back(v);
  }

  parallel_for(samples_.size(), config.threads, [&](std::size_t i) {
    const SurfaceSample& s = samples_[i];
    const Eigen::Vector2d horizontal = s.normal.head<2>();
    const int first = horizontal.squaredNorm() > 1e-12 ? azimuth_bin(std::atan2(horizontal.y(), horizontal.x())) : 0;
    for (int step = 0; step < kAzimuthBins; ++step) {
      // first, first+1, first-1, first+2, ...
      const int offset = (step + 1) / 2 * ((step % 2) != 0 ? 1 : -1);
      const auto& bin = bins[static_cast<std::size_t>(((first + offset) % kAzimuthBins + kAzimuthBins) % kAzimuthBins)];
      for (std::uint32_t v : bin) {
        if (visible_from(scene_, intrinsics, views[v], s.position, s.normal, config.image_margin_px,
                         config.min_cos_incidence)) {
          visible_[i] = 1;
          return;
        }
      }
    }
  });
  visible_count_ = static_cast<std::size_t>(std::count(visible_.begin(), visible_.end(), 1));
}

double GroundTruth::visible_area() const {
  return samples_.empty() ? 0.0 : surface_area_ * static_cast<double>(visible_count_) / samples_.size();
}

std::vector<PrimitiveIndex> GroundTruth::precise_primitives(const PrimitivePoolView& pool, double sigma_target) {
  std::vector<PrimitiveIndex> precise;
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (pool.is_alive(i) && primitive_sigma(pool[i]) < sigma_target && pool[i].X_world.allFinite()) {
      precise.push_back(i);
    }
  }
  return precise;
}

double GroundTruth::coverage(const PrimitivePoolView& pool, double distance, double sigma_target) const {
  if (visible_count_ == 0 || !(distance > 0.0)) return 0.0;
  std::vector<Eigen::Vector3d> points;
  for (const PrimitiveIndex i : precise_primitives(pool, sigma_target)) points.push_back(pool[i].X_world);
  return covered_fraction(points, distance);
}

double GroundTruth::verified_coverage(const PrimitivePoolView& pool, double distance, double sigma_target,
                                      double max_sigmas, std::size_t* precise_count,
                                      std::size_t* verified_count) const {
  const std::vector<PrimitiveIndex> precise = precise_primitives(pool, sigma_target);
  std::vector<std::uint8_t> within(precise.size(), 0);
  parallel_for(precise.size(), config_.threads, [&](std::size_t k) {
    const Primitive& p = pool[precise[k]];
    const ClosestPoint c = scene_.closest_point(p.X_world, std::numeric_limits<double>::infinity());
    if (!c.found) return;
    if (c.distance == 0.0) {
      within[k] = 1;
      return;
    }
    // The error's own direction: its variance there is what the estimate claims about this error.
    const Eigen::Vector3d e = (p.X_world - c.point) / c.distance;
    const double variance = e.dot(p.Sigma_world * e);
    within[k] = variance > 0.0 && c.distance <= max_sigmas * std::sqrt(variance) ? 1 : 0;
  });
  std::vector<Eigen::Vector3d> verified;
  for (std::size_t k = 0; k < precise.size(); ++k) {
    if (within[k] != 0) verified.push_back(pool[precise[k]].X_world);
  }
  if (precise_count != nullptr) *precise_count = precise.size();
  if (verified_count != nullptr) *verified_count = verified.size();
  return covered_fraction(verified, distance);
}

double GroundTruth::covered_fraction(const std::vector<Eigen::Vector3d>& points, double distance) const {
  if (points.empty() || visible_count_ == 0 || !(distance > 0.0)) return 0.0;
  Eigen::AlignedBox3d box = scene_.mesh().bounds();
  box.extend(box.min() - Eigen::Vector3d::Constant(distance));
  box.extend(box.max() + Eigen::Vector3d::Constant(distance));
  const PointGrid grid(box, distance, points);
  std::atomic<std::size_t> covered{0};
  parallel_for(samples_.size(), config_.threads, [&](std::size_t i) {
    if (visible_[i] != 0 && grid.any_within(samples_[i].position, distance)) covered.fetch_add(1, std::memory_order_relaxed);
  });
  return static_cast<double>(covered.load()) / static_cast<double>(visible_count_);
}

void GroundTruth::accuracy(const PrimitivePoolView& pool, double* rms, double* p95, double* max,
                           std::vector<double>* distances) const {
  std::vector<PrimitiveIndex> alive;
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (pool.is_alive(i)) alive.push_back(i);
  }
  std::vector<double> d(alive.size(), 0.0);
  parallel_for(alive.size(), config_.threads, [&](std::size_t k) {
    const ClosestPoint c = scene_.closest_point(pool[alive[k]].X_world, std::numeric_limits<double>::infinity());
    d[k] = c.found ? c.distance : std::numeric_limits<double>::infinity();
  });
  double sum2 = 0.0, mx = 0.0;
  for (double v : d) {
    sum2 += v * v;
    mx = std::max(mx, v);
  }
  if (rms != nullptr) *rms = d.empty() ? 0.0 : std::sqrt(sum2 / d.size());
  if (max != nullptr) *max = mx;
  if (p95 != nullptr) {
    if (d.empty()) {
      *p95 = 0.0;
    } else {
      std::vector<double> sorted = d;
      // Nearest rank: the smallest value with at least 95% of the values at or below it.
      const std::size_t rank = static_cast<std::size_t>(std::ceil(0.95 * sorted.size()));
      std::nth_element(sorted.begin(), sorted.begin() + (rank - 1), sorted.end());
      *p95 = sorted[rank - 1];
    }
  }
  if (distances != nullptr) *distances = std::move(d);
}

double GroundTruth::average_sigma(const PrimitivePoolView& pool) {
  double sum = 0.0;
  std::size_t n = 0;
  for (PrimitiveIndex i = 0; i < pool.index_bound(); ++i) {
    if (!pool.is_alive(i)) continue;
    sum += primitive_sigma(pool[i]);
    ++n;
  }
  return n == 0 ? 0.0 : sum / static_cast<double>(n);
}

Evaluation GroundTruth::evaluate(const PrimitivePoolView& pool) const {
  Evaluation e;
  e.primitive_count = pool.size();
  e.coverage = coverage(pool, config_.coverage_distance, config_.sigma_target);
  accuracy(pool, &e.rms_error, &e.p95_error, &e.max_error);
  e.average_sigma = average_sigma(pool);
  return e;
}

}  // namespace vantage::sim
