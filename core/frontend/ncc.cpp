#include "core/frontend/ncc.hpp"

#include <cmath>

#include "core/frontend/float4.hpp"

namespace vantage {

namespace {

// NCC from the sums over the n correlated pixels (the template is zero-mean there, so sum(t * I) needs
// no mean). Below a tenth of a gray level of standard deviation the image patch is flat: no correlation.
float ncc_from_sums(float sum_ti, float sum_i, float sum_ii, float n, float tmpl_norm) {
  const float variance_sum = sum_ii - sum_i * sum_i / n;
  if (!(variance_sum > 0.01f * n)) return -1.0f;
  const float ncc = sum_ti / (tmpl_norm * std::sqrt(variance_sum));
  return ncc > 1.0f ? 1.0f : (ncc < -1.0f ? -1.0f : ncc);
}

void finish_template(NccTemplate* out) {
  // Masks are 0 or 1 (both make_template overloads set them so): plain sums, no branches.
  float sum = 0.0f;
  float count = 0.0f;
  for (int i = 0; i < kPatchPixels; ++i) {
    sum += out->mask[i] * out->values[i];
    count += out->mask[i];
  }
  out->valid_count = static_cast<int>(count);
  if (out->valid_count == 0) {
    out->values.fill(0.0f);
    out->norm = 0.0f;
    out->stddev_gray = 0.0f;
    return;
  }
  const float mean = sum / count;
  float sum_sq = 0.0f;
  for (int i = 0; i < kPatchPixels; ++i) {
    const float centred = (out->values[i] - mean) * out->mask[i];
    out->values[i] = centred;
    sum_sq += centred * centred;
  }
  out->norm = std::sqrt(sum_sq);
  out->stddev_gray = std::sqrt(sum_sq / count);
}

// ncc_from_sums on four lanes at once.
Float4 ncc_lanes(Float4 sum_ti, Float4 sum_i, Float4 sum_ii, float n, float tmpl_norm) {
  const Float4 variance_sum = sum_ii - sum_i * sum_i / splat4(n);
  const Float4 flat = splat4(0.01f * n);
  Float4 root;
  for (int lane = 0; lane < 4; ++lane) root[lane] = std::sqrt(variance_sum[lane] > 0.0f ? variance_sum[lane] : 0.0f);
  Float4 ncc = sum_ti / (splat4(tmpl_norm) * root);
  ncc = ncc > splat4(1.0f) ? splat4(1.0f) : ncc;
  ncc = ncc < splat4(-1.0f) ? splat4(-1.0f) : ncc;
  return variance_sum > flat ? ncc : splat4(-1.0f);
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
    return ncc_from_sums(sum_ti, static_cast<float>(sum_i), static_cast<float>(sum_ii), kPatchPixels, tmpl.norm);
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
  return ncc_from_sums(sum_ti, sum_i, sum_ii, static_cast<float>(tmpl.valid_count), tmpl.norm);
}

bool ncc_box(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x0, std::int32_t y0, std::int32_t w,
             std::int32_t h, Span<float> scratch, float* out) {
  if (w < 1 || h < 1 || scratch.size() < ncc_box_scratch_size(w, h)) return false;
  if (tmpl.norm <= 0.0f || tmpl.valid_count < 2) {
    for (std::int32_t i = 0; i < h * ncc_box_out_stride(w); ++i) out[i] = -1.0f;
    return true;
  }
  // Layout: the pixels under the box as floats (plane_h rows of plane_stride, zero past the region so
  // the padding lanes stay finite), then per plane row the 7-wide sums of I and of I^2 at each centre
  // column. Every value is an integer below 2^24, so these float sums are exact.
  const std::int32_t padded_w = ncc_box_out_stride(w);
  const std::int32_t plane_stride = ncc_box_plane_stride(w);
  const std::int32_t plane_h = h + kPatchSize - 1;
  float* plane = scratch.data();
  float* row_sum = plane + static_cast<std::size_t>(plane_h) * plane_stride;
  float* row_sum_sq = row_sum + static_cast<std::size_t>(plane_h) * padded_w;
  const std::int32_t region_w = w + kPatchSize - 1;
  for (std::int32_t r = 0; r < plane_h; ++r) {
    const std::uint8_t* src = image.pixels + static_cast<std::ptrdiff_t>(y0 - kPatchRadius + r) * image.stride_bytes +
                              (x0 - kPatchRadius);
    float* dst = plane + static_cast<std::size_t>(r) * plane_stride;
    bytes_to_floats(src, region_w, image.width_px - (x0 - kPatchRadius), dst, plane_stride);
    for (std::int32_t c = 0; c < padded_w; c += 4) {
      Float4 sum = splat4(0.0f);
      Float4 sum_sq = splat4(0.0f);
      for (std::int32_t dx = 0; dx < kPatchSize; ++dx) {
        const Float4 p = load4(dst + c + dx);
        sum += p;
        sum_sq += p * p;
      }
      store4(row_sum + static_cast<std::size_t>(r) * padded_w + c, sum);
      store4(row_sum_sq + static_cast<std::size_t>(r) * padded_w + c, sum_sq);
    }
  }
  // The template broadcast to lanes (masked pixels hold 0); the masked pixels are taken out of the box sums.
  Float4 values[kPatchPixels];
  for (std::int32_t k = 0; k < kPatchPixels; ++k) values[k] = splat4(tmpl.values[k]);
  std::int32_t masked_offsets[kPatchPixels];
  std::int32_t masked = 0;
  for (std::int32_t dy = 0; dy < kPatchSize && tmpl.valid_count < kPatchPixels; ++dy) {
    for (std::int32_t dx = 0; dx < kPatchSize; ++dx) {
      if (!(tmpl.mask[dy * kPatchSize + dx] > 0.5f)) masked_offsets[masked++] = dy * plane_stride + dx;
    }
  }
  const float n = static_cast<float>(tmpl.valid_count);
  for (std::int32_t y = 0; y < h; ++y) {
    for (std::int32_t c = 0; c < w; c += 8) {
      // Eight centres of one row: lanes 0-3 in *_lo, 4-7 in *_hi.
      const float* base = plane + static_cast<std::size_t>(y) * plane_stride + c;
      Float4 dot_lo = splat4(0.0f);
      Float4 dot_hi = splat4(0.0f);
      for (std::int32_t dy = 0; dy < kPatchSize; ++dy) {
        const float* row = base + static_cast<std::size_t>(dy) * plane_stride;
        const Float4* t = values + dy * kPatchSize;
        for (std::int32_t dx = 0; dx < kPatchSize; ++dx) {
          dot_lo += t[dx] * load4(row + dx);
          dot_hi += t[dx] * load4(row + dx + 4);
        }
      }
      Float4 sum_lo = splat4(0.0f);
      Float4 sum_hi = splat4(0.0f);
      Float4 sum_sq_lo = splat4(0.0f);
      Float4 sum_sq_hi = splat4(0.0f);
      for (std::int32_t dy = 0; dy < kPatchSize; ++dy) {
        const std::size_t row = static_cast<std::size_t>(y + dy) * padded_w + c;
        sum_lo += load4(row_sum + row);
        sum_hi += load4(row_sum + row + 4);
        sum_sq_lo += load4(row_sum_sq + row);
        sum_sq_hi += load4(row_sum_sq + row + 4);
      }
      for (std::int32_t k = 0; k < masked; ++k) {
        const Float4 p_lo = load4(base + masked_offsets[k]);
        const Float4 p_hi = load4(base + masked_offsets[k] + 4);
        sum_lo -= p_lo;
        sum_hi -= p_hi;
        sum_sq_lo -= p_lo * p_lo;
        sum_sq_hi -= p_hi * p_hi;
      }
      float* dst = out + static_cast<std::size_t>(y) * padded_w + c;
      store4(dst, ncc_lanes(dot_lo, sum_lo, sum_sq_lo, n, tmpl.norm));
      store4(dst + 4, ncc_lanes(dot_hi, sum_hi, sum_sq_hi, n, tmpl.norm));
    }
  }
  return true;
}

double parabola_peak_offset(double left, double centre, double right) {
  const double curvature = left - 2.0 * centre + right;
  if (!(curvature < 0.0) || left > centre || right > centre) return 0.0;
  const double offset = 0.5 * (left - right) / curvature;
  return offset > 0.5 ? 0.5 : (offset < -0.5 ? -0.5 : offset);
}

}  // namespace vantage
