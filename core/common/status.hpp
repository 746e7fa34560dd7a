#pragma once
// One status type for the whole core: every fallible call returns it ([[nodiscard]]), nothing throws.
#include <cstdint>

namespace vantage {

enum class [[nodiscard]] Status : std::uint8_t {
  kOk = 0,
  kNonFiniteInput,      // NaN or Inf in a measurement, pose, intrinsics or covariance
  kNotSpd,              // a covariance that is not symmetric positive definite
  kInvalidArgument,     // a value outside its documented range
  kInvalidImage,        // zero-size, null or truncated image
  kPoolFull,            // a fixed-capacity pool or buffer has no free slot
  kNotFound,            // an index or element that does not exist
  kBehindCamera,        // a point at or behind the camera's image plane
  kOutsideImage,        // a projection outside the image
  kGatedOutlier,        // a measurement rejected by the Mahalanobis gate
  kNoPath,              // no path between two grid cells
  kNoFreeCell,          // no free cell to plan for
  kUnusableImage,       // a well-formed image without usable content: constant, all black or saturated
  kNotInitialized,      // an update before the initialization that it builds on
};

const char* to_string(Status status);

inline bool ok(Status status) { return status == Status::kOk; }

}  // namespace vantage
