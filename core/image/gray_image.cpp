#include "core/image/gray_image.hpp"

namespace vantage {

Status GrayImageView::validate() const {
  if (pixels == nullptr || width_px <= 0 || height_px <= 0 || stride_bytes < width_px) return Status::kInvalidImage;
  return Status::kOk;
}

}  // namespace vantage
