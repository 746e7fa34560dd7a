#pragma once
// Where model updates come from. The image front end (core/frontend) implements it from camera frames;
// the simulator's oracle (sim_hal) implements it from ground truth for planner comparisons. The sensing
// executive (core/planning) talks only to this interface.
#include <cstdint>

#include "core/common/status.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/image/gray_image.hpp"
#include "core/model/primitive_pool.hpp"

namespace vantage {

// What one image did to the model. All counts are for this image only.
struct UpdateReport {
  std::uint32_t predicted_in_view = 0;   // primitives predicted inside the image and not occluded
  std::uint32_t matched = 0;             // observations found (image match or oracle)
  std::uint32_t updated = 0;             // EKF updates accepted
  std::uint32_t failed_matches = 0;      // searched but no unique match above threshold
  std::uint32_t gated_outliers = 0;      // matched but rejected by the Mahalanobis gate
  std::uint32_t spawned = 0;             // new primitives added (model augmentation)
  std::uint32_t merged = 0;              // primitives absorbed by neighbours (adaptive scale)
  std::uint32_t pool_full_rejections = 0;
  std::uint32_t gated_erased = 0;        // erased after rejections in a row (track loss, unsearchable ghosts)
};

class MeasurementSource {
 public:
  // Builds the initial model from two images with a small baseline (paper section VI).
  virtual Status initialize(const GrayImageView& first, const Viewpoint& first_view, const GrayImageView& second,
                            const Viewpoint& second_view, PrimitivePoolView& pool, UpdateReport* report) = 0;
  // Incorporates one new image taken from view: EKF updates of the primitives it sees, then augmentation.
  // On a bad image or pose: an error status, the model unchanged.
  virtual Status update(const GrayImageView& image, const Viewpoint& view, PrimitivePoolView& pool,
                        UpdateReport* report) = 0;
  virtual const PinholeIntrinsics& intrinsics() const = 0;

 protected:
  ~MeasurementSource() = default;
};

}  // namespace vantage
