#include "core/frontend/ncc.hpp"

#include <cmath>

namespace vantage {

namespace {

void finish_template(NccTemplate* out) {
  double sum = 0.0;
  int count = 0;
  for (int i = 0; i < kPatchPixels; ++i) {
    if (out->mask[i] > 0.5f) {
      sum += out->values[i];
      ++count;
    }
  }
  out->valid_count = count;
  if (count == 0) {
    out->norm = 0.0f;
    out->stddev_gray = 0.0f;
    return;
  }
  const double mean = sum / count;
  double sum_sq = 0.0;
  for (int i = 0; i < kPatchPixels; ++i) {
    if (out->mask[i] > 0.5f) {
      const double centred = out->values[i] - mean;
      out->values[i] = static_cast<float>(centred);
      sum_sq += centred * centred;
    } else {
      out->values[i] = 0.0f;
    }
  }
  out->norm = static_cast<float>(std::sqrt(sum_sq));
  out->stddev_gray = static_cast<float>(std::sqrt(sum_sq / count));
}

}  // namespace

void make_template(const std::array<std::uint8_t, kPatchPixels>& patch, NccTemplate* out) {
  for (int i = 0; i < kPatchPixels; ++i) {
    out->values[i] = static_cast<float>(patch[i]);
    out->mask[i] = 1.0f;
  }
  finish_template(out);
}

void make_template(const std::array<float, kPatchPixels>& gray, const std::array<float, kPatchPixels>& mask,
                   NccTemplate* out) {
  for (int i = 0; i < kPatchPixels; ++i) {
    out->mask[i] = mask[i] > 0.5f ? 1.0f : 0.0f;
    out->values[i] = gray[i];
  }
  finish_template(out);
}

void extract_patch(const GrayImageView& image, std::int32_t cx, std::int32_t cy,
                   std::array<std::uint8_t, kPatchPixels>* out) {
  for (int dy = 0; dy < kPatchSize; ++dy) {
    const std::uint8_t* row = image.pixels + (cy - kPatchRadius + dy) * image.stride_bytes + (cx - kPatchRadius);
    for (int dx = 0; dx < kPatchSize; ++dx) (*out)[dy * kPatchSize + dx] = row[dx];
  }
}

bool patch_inside(const GrayImageView& image, std::int32_t cx, std::int32_t cy, std::int32_t margin_px) {
  const std::int32_t r = kPatchRadius + margin_px;
  return cx - r >= 0 && cy - r >= 0 && cx + r < image.width_px && cy + r < image.height_px;
}

float ncc_at(const GrayImageView& image, std::int32_t cx, std::int32_t cy, const NccTemplate& tmpl) {
  if (tmpl.norm <= 0.0f || tmpl.valid_count < 2) return -1.0f;
  if (tmpl.valid_count == kPatchPixels) {
    // Unmasked: integer sums of I and I^2 (exact, and what the compiler vectorizes best).
    std::int32_t sum_i = 0;
    std::int32_t sum_ii = 0;
    float sum_ti = 0.0f;
    const float* t = tmpl.values.data();
    for (int dy = 0; dy < kPatchSize; ++dy) {
      const std::uint8_t* row = image.pixels + (cy - kPatchRadius + dy) * image.stride_bytes + (cx - kPatchRadius);
      for (int dx = 0; dx < kPatchSize; ++dx) {
        const std::int32_t value = row[dx];
        sum_i += value;
        sum_ii += value * value;
        sum_ti += t[dx] * static_cast<float>(value);
      }
      t += kPatchSize;
    }
    const float variance_sum =
        static_cast<float>(sum_ii) - static_cast<float>(sum_i) * static_cast<float>(sum_i) / kPatchPixels;
    if (!(variance_sum > 0.01f * kPatchPixels)) return -1.0f;
    const float ncc = sum_ti / (tmpl.norm * std::sqrt(variance_sum));
    return ncc > 1.0f ? 1.0f : (ncc < -1.0f ? -1.0f : ncc);
  }
  // Sums over the valid pixels only; the template is zero-mean there, so sum(t * I) needs no mean.
  float sum_i = 0.0f;
  float sum_ii = 0.0f;
  float sum_ti = 0.0f;
  const float* t = tmpl.values.data();
  const float* m = tmpl.mask.data();
  for (int dy = 0; dy < kPatchSize; ++dy) {
    const std::uint8_t* row = image.pixels + (cy - kPatchRadius + dy) * image.stride_bytes + (cx - kPatchRadius);
    for (int dx = 0; dx < kPatchSize; ++dx) {
      const float value = static_cast<float>(row[dx]);
      const float masked = value * m[dx];
      sum_i += masked;
      sum_ii += masked * value;
      sum_ti += t[dx] * value;
    }
    t += kPatchSize;
    m += kPatchSize;
  }
  const float variance_sum = sum_ii - sum_i * sum_i / static_cast<float>(tmpl.valid_count);
  // Below a tenth of a gray level of standard deviation the image patch is flat: no correlation.
  if (!(variance_sum > 0.01f * static_cast<float>(tmpl.valid_count))) return -1.0f;
  const float ncc = sum_ti / (tmpl.norm * std::sqrt(variance_sum));
  return ncc > 1.0f ? 1.0f : (ncc < -1.0f ? -1.0f : ncc);
}

double parabola_peak_offset(double left, double centre, double right) {
  const double curvature = left - 2.0 * centre + right;
  if (!(curvature < 0.0) || left > centre || right > centre) return 0.0;
  const double offset = 0.5 * (left - right) / curvature;
  return offset > 0.5 ? 0.5 : (offset < -0.5 ? -0.5 : offset);
}

}  // namespace vantage
