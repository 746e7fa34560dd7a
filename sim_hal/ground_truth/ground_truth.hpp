#pragma once
// Ground truth for EVALUATION ONLY (never given to the planner). Definitions (sim_hal/README.md):
//  (a) samples: sample_count area-weighted surface points (sample_surface, fixed seed);
//  (b) visible samples: observable from at least one free grid cell's viewpoint (cell centre at the
//      grid elevation, looking at the grid centre, up = +z): in front of the camera, projecting at least
//      image_margin_px inside the image, not grazing (cos incidence >= min_cos_incidence) and
//      unoccluded (no hit between camera and X); visible area = total area * visible samples / samples.
//      The thresholds are the oracle's: a surface that no cell sees at more than grazing incidence
//      cannot be measured, like the paper's "nearly horizontal region on top" (sim_hal/README.md);
//  (c) coverage(d, sigma_target) = fraction of visible samples within distance d of the position of at
//      least one primitive with primitive_sigma < sigma_target;
//  (d) accuracy: each primitive's distance to the true surface (closest point, Embree point query),
//      RMS and 95th percentile (nearest-rank) over alive primitives;
//  (e) average sigma: mean of primitive_sigma over alive primitives.
//  (f) verified coverage(d, sigma_target, k): (c) counting only the precise primitives whose distance to
//      the true surface is at most k of their own standard deviations along that distance's direction
//      (sqrt(e^T Sigma e), e the unit vector to the closest surface point): what an over-confident
//      estimate claims but does not have is left out.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/model/primitive.hpp"
#include "core/model/primitive_pool.hpp"
#include "sim_hal/scene/embree_scene.hpp"
#include "sim_hal/scene/surface_sampler.hpp"
#include "sim_hal/world/occupancy.hpp"

namespace vantage::sim {

// sigma of a primitive: sqrt(trace(Sigma_world) / 3), the RMS per-axis standard deviation (units).
double primitive_sigma(const Primitive& primitive);

// The viewpoint the ground truth (and the planner's grid) uses for a cell: cell centre, looking at the
// grid centre at the grid elevation, image up toward +z.
Viewpoint grid_cell_viewpoint(const GridGeometry& grid, const GridCell& cell);

struct GroundTruthConfig {
  std::size_t sample_count = 50000;
  std::uint32_t seed = 7;
  double coverage_distance = 0.5;   // d, scene units
  double sigma_target = 0.008;      // the paper's precision target, units
  // (b) observability, the same thresholds as OracleConfig: a patch margin and no grazing views
  // (incidence beyond ~78 degrees). 0 and 0 give the geometric visibility (any front-facing view).
  double image_margin_px = kPatchSize / 2 + 1;
  double min_cos_incidence = 0.2;
  int threads = 2;
};

struct Evaluation {
  std::size_t primitive_count = 0;
  double coverage = 0.0;            // (c), in [0, 1]
  double rms_error = 0.0;           // (d), units
  double p95_error = 0.0;           // (d), units
  double max_error = 0.0;           // (d), units
  double average_sigma = 0.0;       // (e), units
};

class GroundTruth {
 public:
  // Samples the surface and computes the visible set (the slow part, once per scene). Throws SimError
  // for a bad configuration.
  GroundTruth(const EmbreeScene& scene, const OccupancyGrid& occupancy, const PinholeIntrinsics& intrinsics,
              const GroundTruthConfig& config);

  const std::vector<SurfaceSample>& samples() const { return samples_; }
  // visible()[i] != 0 when samples()[i] is visible (observable, see (b)) from at least one free cell.
  const std::vector<std::uint8_t>& visible() const { return visible_; }
  std::size_t visible_count() const { return visible_count_; }
  double surface_area() const { return surface_area_; }
  double visible_area() const;

  // True when the point with outward normal is seen from view: in front, inside the image,
  // front-facing and unoccluded.
  // margin_px shrinks the image on every side; min_cos_incidence > 0 also rejects grazing views (the
  // ground truth uses 0: any front-facing view counts).
  static bool visible_from(const EmbreeScene& scene, const PinholeIntrinsics& intrinsics, const Viewpoint& view,
                           const Eigen::Vector3d& point, const Eigen::Vector3d& normal, double margin_px = 0.0,
                           double min_cos_incidence = 0.0);

  double coverage(const PrimitivePoolView& pool, double distance, double sigma_target) const;
  // (f); precise_count / verified_count (when not null): the alive primitives with sigma < sigma_target,
  // and those of them within max_sigmas of the surface.
  double verified_coverage(const PrimitivePoolView& pool, double distance, double sigma_target, double max_sigmas,
                           std::size_t* precise_count = nullptr, std::size_t* verified_count = nullptr) const;
  // Fills distances (one per alive primitive, in index order) when not null.
  void accuracy(const PrimitivePoolView& pool, double* rms, double* p95, double* max,
                std::vector<double>* distances = nullptr) const;
  static double average_sigma(const PrimitivePoolView& pool);
  // All of the above with the configured d and sigma target.
  Evaluation evaluate(const PrimitivePoolView& pool) const;

 private:
  // The alive primitives with a finite position and sigma < sigma_target, in index order ((c) and (f)).
  static std::vector<PrimitiveIndex> precise_primitives(const PrimitivePoolView& pool, double sigma_target);
  // The share of visible samples within distance of one of the points (the grid search of (c)).
  double covered_fraction(const std::vector<Eigen::Vector3d>& points, double distance) const;

  const EmbreeScene& scene_;
  GroundTruthConfig config_;
  std::vector<SurfaceSample> samples_;
  std::vector<std::uint8_t> visible_;
  std::size_t visible_count_ = 0;
  double surface_area_ = 0.0;
};

}  // namespace vantage::sim
