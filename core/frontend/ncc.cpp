#include "core/frontend/ncc.hpp"

#include <cmath>

#include "core/criterion/criterion_model.hpp"
#include "core/frontend/float4.hpp"

namespace vantage {

static_assert(match_kernel::kSize == kPatchSize, "the matcher's kernels are built for kPatchSize");

namespace {

// NCC from the sums over the n correlated pixels (the template is zero-mean there, so sum(t * I) needs
// no mean). Below a tenth of a gray level of standard deviation the image patch is flat: no correlation.
float ncc_from_sums(float sum_ti, float sum_i, float sum_ii, float n, float tmpl_norm) {
  const float variance_sum = sum_ii - sum_i * sum_i / n;
  if (!(variance_sum > 0.01f * n)) return -1.0f;
  const float ncc = sum_ti / (tmpl_norm * std::sqrt(variance_sum));
  return ncc > 1.0f ? 1.0f : (ncc < -1.0f ? -1.0f : ncc);
}

// Centres the pixels gray on mean into out->values (times the mask when kMasked; masks are 0 or 1, so
// without it the same arithmetic minus the products with 1) and sets the norm and the standard deviation
// over count pixels. gray may be out->values itself.
template <bool kMasked>
void centre_template(const float* gray, const float* mask, float mean, float count, NccTemplate* out) {
  constexpr int kWhole = kPatchPixels / 4 * 4;
  float* centred = out->values.data();
  const Float4 mean4 = splat4(mean);
  Float4 sum_sq4 = splat4(0.0f);
  for (int i = 0; i < kWhole; i += 4) {
    Float4 c = load4(gray + i) - mean4;
    if constexpr (kMasked) c *= load4(mask + i);
    store4(centred + i, c);
    sum_sq4 += c * c;
  }
  float sum_sq = sum_lanes(sum_sq4);
  for (int i = kWhole; i < kPatchPixels; ++i) {
    centred[i] = kMasked ? (gray[i] - mean) * mask[i] : gray[i] - mean;
    sum_sq += centred[i] * centred[i];
  }
  out->norm = std::sqrt(sum_sq);
  out->stddev_gray = std::sqrt(sum_sq / count);
}

void finish_template(NccTemplate* out) {
  // Masks are 0 or 1 (both make_template overloads set them so): plain sums, no branches. The sums run
  // in four lanes (float sums are not vectorized otherwise; each tracked primitive makes a template).
  constexpr int kWhole = kPatchPixels / 4 * 4;
  const float* values = out->values.data();
  const float* mask = out->mask.data();
  Float4 sum4 = splat4(0.0f);
  Float4 count4 = splat4(0.0f);
  for (int i = 0; i < kWhole; i += 4) {
    const Float4 m = load4(mask + i);
    sum4 += m * load4(values + i);
    count4 += m;
  }
  float sum = sum_lanes(sum4);
  float count = sum_lanes(count4);
  for (int i = kWhole; i < kPatchPixels; ++i) {
    sum += mask[i] * values[i];
    count += mask[i];
  }
  out->valid_count = static_cast<int>(count);
  if (out->valid_count == 0) {
    out->values.fill(0.0f);
    out->norm = 0.0f;
    out->stddev_gray = 0.0f;
    return;
  }
  centre_template<true>(values, mask, sum / count, count, out);
}

}  // namespace

void make_template(const std::array<std::uint8_t, kPatchPixels>& patch, NccTemplate* out) {
  // Nothing masked: finish_template's arithmetic without the mask (its products with 1 are exact, the
  // count of ones is exactly kPatchPixels), so the same values in fewer instructions (every tracked
  // primitive makes a template per frame).
  constexpr int kWhole = kPatchPixels / 4 * 4;
  alignas(16) float gray[64];
  bytes_to_floats(patch.data(), kPatchPixels, kPatchPixels, gray, 64);
  Float4 sum4 = splat4(0.0f);
  for (int i = 0; i < kWhole; i += 4) sum4 += load4(gray + i);
  float sum = sum_lanes(sum4);
  for (int i = kWhole; i < kPatchPixels; ++i) sum += gray[i];
  const float count = static_cast<float>(kPatchPixels);
  centre_template<false>(gray, nullptr, sum / count, count, out);
  out->mask.fill(1.0f);
  out->valid_count = kPatchPixels;
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
  return ncc_box(image, tmpl, x0, y0, w, h, scratch, out, MatchKernel::kAuto);
}

bool ncc_box(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x0, std::int32_t y0, std::int32_t w,
             std::int32_t h, Span<float> scratch, float* out, MatchKernel kernel) {
  if (w < 1 || h < 1 || scratch.size() < ncc_box_scratch_size(w, h) || !match_kernel_supported(kernel)) return false;
  if (tmpl.norm <= 0.0f || tmpl.valid_count < 2) {
    for (std::int32_t i = 0; i < h * ncc_box_out_stride(w); ++i) out[i] = -1.0f;
    return true;
  }
  // The kernel (match_kernel_impl.hpp): the pixels converted once, the sums of I and I^2 as box sums of
  // that copy, eight centres sharing each template multiply.
  const match_kernel::Image view{image.pixels, image.width_px, image.height_px, image.stride_bytes};
  const match_kernel::Template t{tmpl.values.data(), tmpl.mask.data(), tmpl.norm, tmpl.valid_count};
  const match_kernel::Box box{x0, y0, w, h, ncc_box_plane_stride(w), ncc_box_out_stride(w)};
  match_kernel::functions(kernel).ncc_box(view, t, box, scratch.data(), out);
  return true;
}

double parabola_peak_offset(double left, double centre, double right) {
  const double curvature = left - 2.0 * centre + right;
  if (!(curvature < 0.0) || left > centre || right > centre) return 0.0;
  const double offset = 0.5 * (left - right) / curvature;
  return offset > 0.5 ? 0.5 : (offset < -0.5 ? -0.5 : offset);
}

// Choice of the matcher's kernel build (match_kernel.hpp).
namespace {

// The criterion's kernels are the same two builds (baseline ISA, AVX2 + FMA): its names and its CPU
// check serve here too.
CriterionKernel as_criterion_kernel(MatchKernel kernel) {
  switch (kernel) {
    case MatchKernel::kAuto:
      return CriterionKernel::kAuto;
    case MatchKernel::kBaseline:
      return CriterionKernel::kBaseline;
    case MatchKernel::kAvx2Fma:
      return CriterionKernel::kAvx2Fma;
  }
  return CriterionKernel::kBaseline;
}

}  // namespace

const char* to_string(MatchKernel kernel) { return to_string(as_criterion_kernel(kernel)); }

bool match_kernel_supported(MatchKernel kernel) {
  // libgcc's CPU model (it also checks that the OS saves the AVX registers): a load and a bit test once
  // initialized, so it is asked on every search instead of cached in mutable state.
  return (kernel != MatchKernel::kAvx2Fma || VANTAGE_MATCH_HAS_AVX2_KERNEL) &&
         criterion_kernel_supported(as_criterion_kernel(kernel));
}

namespace match_kernel {

Functions functions(MatchKernel kernel) {
#if VANTAGE_MATCH_HAS_AVX2_KERNEL
  if ((kernel == MatchKernel::kAuto || kernel == MatchKernel::kAvx2Fma) &&
      match_kernel_supported(MatchKernel::kAvx2Fma)) {
    return {avx2_fma::ncc_box, avx2_fma::refine, avx2_fma::photometric};
  }
#endif
  (void)kernel;
  return {baseline::ncc_box, baseline::refine, baseline::photometric};
}

}  // namespace match_kernel

}  // namespace vantage
