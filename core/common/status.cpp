#include "core/common/status.hpp"

namespace vantage {

const char* to_string(Status status) {
  switch (status) {
    case Status::kOk: return "ok";
    case Status::kNonFiniteInput: return "non-finite input (NaN or Inf)";
    case Status::kNotSpd: return "covariance is not symmetric positive definite";
    case Status::kInvalidArgument: return "invalid argument";
    case Status::kInvalidImage: return "invalid image (null, zero-size or truncated)";
    case Status::kPoolFull: return "pool full";
    case Status::kNotFound: return "not found";
    case Status::kBehindCamera: return "point behind the camera";
    case Status::kOutsideImage: return "projection outside the image";
    case Status::kGatedOutlier: return "measurement rejected by the Mahalanobis gate";
    case Status::kNoPath: return "no path";
    case Status::kNoFreeCell: return "no free cell";
    case Status::kUnusableImage: return "unusable image (constant, all black or saturated)";
    case Status::kNotInitialized: return "not initialized";
  }
  return "unknown status";
}

}  // namespace vantage
