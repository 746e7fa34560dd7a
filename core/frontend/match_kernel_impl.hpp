// The matcher's inner loops (match_kernel.hpp), written with GCC/Clang vector extensions: float vectors
// of the ISA's width (8 lanes with AVX, 4 with SSE2 or NEON). Included once per build, with
// VANTAGE_MATCH_KERNEL_NS naming the namespace of that build (match_kernel.cpp: baseline,
// match_kernel_avx2.cpp: avx2_fma). Everything here has internal linkage or lives in that namespace, and
// nothing from another header is instantiated (builtins only), so the builds cannot leak into each other.
#ifndef VANTAGE_MATCH_KERNEL_NS
#error "define VANTAGE_MATCH_KERNEL_NS before including match_kernel_impl.hpp"
#endif

#include <cstddef>
#include <cstdint>

#include "core/frontend/match_kernel.hpp"

namespace vantage::match_kernel::VANTAGE_MATCH_KERNEL_NS {
namespace {

#define VANTAGE_MATCH_INLINE inline __attribute__((always_inline))

#if defined(__AVX__)
constexpr int kWidth = 8;
#else
constexpr int kWidth = 4;
#endif
typedef float vf __attribute__((vector_size(4 * kWidth)));
typedef std::int32_t vi __attribute__((vector_size(4 * kWidth)));
typedef std::uint8_t vb __attribute__((vector_size(kWidth)));
// The NCC box computes centres in groups of 8 (ncc_box_out_stride), the fit a patch row as 8 lanes.
constexpr int kGroup = 8;
constexpr int kVecs = kGroup / kWidth;
static_assert(kSize + 1 == kGroup, "a patch row is one group of 8 lanes with one spare lane");

VANTAGE_MATCH_INLINE vf load(const float* p) {
  vf v;
  __builtin_memcpy(&v, p, sizeof v);
  return v;
}
VANTAGE_MATCH_INLINE void store(float* p, vf v) { __builtin_memcpy(p, &v, sizeof v); }
// A braced list of copies compiles to one broadcast (vf{} + s would add 0 first: s may be -0, and a lane
// loop becomes a chain of inserts).
VANTAGE_MATCH_INLINE vf splat(float s) {
#if defined(__AVX__)
  return vf{s, s, s, s, s, s, s, s};
#else
  return vf{s, s, s, s};
#endif
}
// dst[k] = src[k] for k < 8.
VANTAGE_MATCH_INLINE void bytes8_to_floats(const std::uint8_t* src, float* dst) {
#if defined(__AVX2__)
  // Widened from a braced list: one vpmovzxbd and one conversion (GCC lowers __builtin_convertvector
  // from a byte vector lane by lane).
  const vi widened = {src[0], src[1], src[2], src[3], src[4], src[5], src[6], src[7]};
  store(dst, __builtin_convertvector(widened, vf));
#else
  // A fixed-size loop the compiler vectorizes (SSE2 unpacks, NEON uxtl).
  std::uint8_t chunk[8];
  __builtin_memcpy(chunk, src, sizeof chunk);
  for (int k = 0; k < 8; ++k) dst[k] = static_cast<float>(chunk[k]);
#endif
}
// dst[k] = src[k] for k < 16.
VANTAGE_MATCH_INLINE void bytes16_to_floats(const std::uint8_t* src, float* dst) {
#if defined(__AVX2__)
  bytes8_to_floats(src, dst);
  bytes8_to_floats(src + 8, dst + 8);
#else
  std::uint8_t chunk[16];
  __builtin_memcpy(chunk, src, sizeof chunk);
  for (int k = 0; k < 16; ++k) dst[k] = static_cast<float>(chunk[k]);
#endif
}
VANTAGE_MATCH_INLINE float sum_lanes(vf v) {
#if defined(__AVX__)
  return ((v[0] + v[1]) + (v[2] + v[3])) + ((v[4] + v[5]) + (v[6] + v[7]));
#else
  return (v[0] + v[1]) + (v[2] + v[3]);
#endif
}
// Lane sums of several vectors at once (a transposing shuffle-and-add tree, cheaper than one horizontal
// sum per vector): sum_pairs(a, b) holds the sums of adjacent lanes of a and b interleaved, and so on up
// to one vector whose lane i is the sum of the lanes of the i-th input.
VANTAGE_MATCH_INLINE vf sum_pairs(vf a, vf b) {
#if defined(__AVX__)
  return __builtin_shufflevector(a, b, 0, 8, 2, 10, 4, 12, 6, 14) + __builtin_shufflevector(a, b, 1, 9, 3, 11, 5, 13, 7, 15);
#else
  return __builtin_shufflevector(a, b, 0, 4, 2, 6) + __builtin_shufflevector(a, b, 1, 5, 3, 7);
#endif
}
VANTAGE_MATCH_INLINE vf sum_quads(vf ab, vf cd) {
#if defined(__AVX__)
  return __builtin_shufflevector(ab, cd, 0, 1, 8, 9, 4, 5, 12, 13) + __builtin_shufflevector(ab, cd, 2, 3, 10, 11, 6, 7, 14, 15);
#else
  return __builtin_shufflevector(ab, cd, 0, 1, 4, 5) + __builtin_shufflevector(ab, cd, 2, 3, 6, 7);
#endif
}
#if defined(__AVX__)
VANTAGE_MATCH_INLINE vf sum_octs(vf abcd, vf efgh) {
  return __builtin_shufflevector(abcd, efgh, 0, 1, 2, 3, 8, 9, 10, 11) +
         __builtin_shufflevector(abcd, efgh, 4, 5, 6, 7, 12, 13, 14, 15);
}
#endif
// sums[i] = the sum of the lanes of v[i], i < 8.
VANTAGE_MATCH_INLINE void sum_lanes8(const vf* v, float* sums) {
#if defined(__AVX__)
  store(sums, sum_octs(sum_quads(sum_pairs(v[0], v[1]), sum_pairs(v[2], v[3])),
                       sum_quads(sum_pairs(v[4], v[5]), sum_pairs(v[6], v[7]))));
#else
  for (int i = 0; i < 8; i += 4) store(sums + i, sum_quads(sum_pairs(v[i], v[i + 1]), sum_pairs(v[i + 2], v[i + 3])));
#endif
}
// sums[i] = the sum of the lanes of v[i], i < 12: the first eight as sum_lanes8, the last four by one more tree.
VANTAGE_MATCH_INLINE void sum_lanes12(const vf* v, float* sums) {
  sum_lanes8(v, sums);
#if defined(__AVX__)
  float rest[8];
  store(rest, sum_octs(sum_quads(sum_pairs(v[8], v[9]), sum_pairs(v[10], v[11])), vf{}));
  for (int i = 0; i < 4; ++i) sums[8 + i] = rest[i];
#else
  store(sums + 8, sum_quads(sum_pairs(v[8], v[9]), sum_pairs(v[10], v[11])));
#endif
}
VANTAGE_MATCH_INLINE vf max_zero(vf v) { return v > vf{} ? v : vf{}; }
VANTAGE_MATCH_INLINE vf sqrt_lanes(vf v) {
  vf r;
  for (int lane = 0; lane < kWidth; ++lane) r[lane] = __builtin_sqrtf(v[lane]);
  return r;
}
VANTAGE_MATCH_INLINE double abs_d(double v) { return __builtin_fabs(v); }
VANTAGE_MATCH_INLINE bool finite(double v) { return __builtin_isfinite(v); }

// dst[i] = src[i] for i < n, and for i < dst_n (a multiple of 16) whole 16-byte chunks: those past n hold
// further bytes of src while a whole chunk of them is within `readable`, else zeros (finite either way).
VANTAGE_MATCH_INLINE void convert_row(const std::uint8_t* src, std::int32_t n, std::int32_t readable, float* dst,
                                      std::int32_t dst_n) {
  for (std::int32_t i = 0; i < dst_n; i += 16) {
    if (i + 16 <= readable) {
      bytes16_to_floats(src + i, dst + i);
      continue;
    }
    std::uint8_t chunk[16] = {};
    for (std::int32_t k = 0; k < 16 && i + k < n; ++k) chunk[k] = src[i + k];
    bytes16_to_floats(chunk, dst + i);
  }
}

}  // namespace

void ncc_box(const Image& image, const Template& tmpl, const Box& box, float* scratch, float* out) {
  // Layout: the pixels under the box as floats (plane_h rows of plane_stride, finite past the region so
  // the padding lanes stay finite), then per plane row the 7-wide sums of I and of I^2 at each centre
  // column. Every value is an integer below 2^24, so all these float sums are exact (sliding sums too).
  const std::int32_t padded_w = box.out_stride;
  const std::int32_t plane_stride = box.plane_stride;
  const std::int32_t plane_h = box.h + kSize - 1;
  const std::int32_t region_w = box.w + kSize - 1;
  const std::int32_t left = box.x0 - kSize / 2;
  float* plane = scratch;
  float* row_sum = plane + static_cast<std::size_t>(plane_h) * plane_stride;
  float* row_sum_sq = row_sum + static_cast<std::size_t>(plane_h) * padded_w;
  const std::int32_t readable = image.width_px - left;
  const std::uint8_t* src = image.pixels + static_cast<std::ptrdiff_t>(box.y0 - kSize / 2) * image.stride_bytes + left;
  float* dst = plane;
  if (readable >= plane_stride) {
    // The usual case: whole 16-pixel chunks of every row are inside the image.
    for (std::int32_t r = 0; r < plane_h; ++r, src += image.stride_bytes, dst += plane_stride) {
      for (std::int32_t i = 0; i < plane_stride; i += 16) bytes16_to_floats(src + i, dst + i);
    }
  } else {
    for (std::int32_t r = 0; r < plane_h; ++r, src += image.stride_bytes, dst += plane_stride) {
      convert_row(src, region_w, readable, dst, plane_stride);
    }
  }
  // The template broadcast to lanes, once per box.
  vf t_lanes[kPixels];
#pragma GCC unroll 49
  for (int k = 0; k < kPixels; ++k) t_lanes[k] = splat(tmpl.values[k]);
  // Dot products plane row by plane row: a row's seven shifted vectors are loaded once and serve its row
  // sums and every centre row whose patch holds it (up to seven); the centre rows accumulate in `out`.
  for (std::int32_t c = 0; c < box.w; c += kGroup) {
    for (std::int32_t y = 0; y < box.h; ++y) {
      for (int v = 0; v < kVecs; ++v) store(out + static_cast<std::size_t>(y) * padded_w + c + v * kWidth, vf{});
    }
    for (std::int32_t r = 0; r < plane_h; ++r) {
      const float* row = plane + static_cast<std::size_t>(r) * plane_stride + c;
      vf p[kSize][kVecs];
      for (int dx = 0; dx < kSize; ++dx) {
        for (int v = 0; v < kVecs; ++v) p[dx][v] = load(row + dx + v * kWidth);
      }
      for (int v = 0; v < kVecs; ++v) {
        vf sum = p[0][v];
        vf sum_sq = p[0][v] * p[0][v];
        for (int dx = 1; dx < kSize; ++dx) {
          sum += p[dx][v];
          sum_sq += p[dx][v] * p[dx][v];
        }
        store(row_sum + static_cast<std::size_t>(r) * padded_w + c + v * kWidth, sum);
        store(row_sum_sq + static_cast<std::size_t>(r) * padded_w + c + v * kWidth, sum_sq);
      }
      // Centre row y = r - k uses template row k.
      const std::int32_t k_first = r < kSize - 1 ? r : kSize - 1;
      const std::int32_t k_last = r - (box.h - 1) > 0 ? r - (box.h - 1) : 0;
      float* acc = out + static_cast<std::size_t>(r - k_first) * padded_w + c;
      const vf* t = t_lanes + k_first * kSize;
      for (std::int32_t k = k_first; k >= k_last; --k, acc += padded_w, t -= kSize) {
        for (int v = 0; v < kVecs; ++v) {
          vf dot = load(acc + v * kWidth);
          for (int dx = 0; dx < kSize; ++dx) dot += t[dx] * p[dx][v];
          store(acc + v * kWidth, dot);
        }
      }
    }
  }
  // Masked pixels hold 0 in the template; they are taken out of the box sums.
  std::int32_t masked_offsets[kPixels];
  std::int32_t masked = 0;
  if (tmpl.valid_count < kPixels) {
    for (int k = 0; k < kPixels; ++k) {
      if (!(tmpl.mask[k] > 0.5f)) masked_offsets[masked++] = (k / kSize) * plane_stride + k % kSize;
    }
  }
  const vf n_v = splat(static_cast<float>(tmpl.valid_count));
  const vf flat_v = splat(0.01f * static_cast<float>(tmpl.valid_count));
  const vf norm_v = splat(tmpl.norm);
  const vf one = splat(1.0f);
  const vf minus_one = splat(-1.0f);
  for (std::int32_t col = 0; col < box.w; col += kWidth) {
    // Box sums of I and I^2 sliding down the rows.
    vf box_sum = vf{};
    vf box_sum_sq = vf{};
    for (int dy = 0; dy < kSize - 1; ++dy) {
      box_sum += load(row_sum + static_cast<std::size_t>(dy) * padded_w + col);
      box_sum_sq += load(row_sum_sq + static_cast<std::size_t>(dy) * padded_w + col);
    }
    for (std::int32_t y = 0; y < box.h; ++y) {
      box_sum += load(row_sum + static_cast<std::size_t>(y + kSize - 1) * padded_w + col);
      box_sum_sq += load(row_sum_sq + static_cast<std::size_t>(y + kSize - 1) * padded_w + col);
      vf sum = box_sum;
      vf sum_sq = box_sum_sq;
      box_sum -= load(row_sum + static_cast<std::size_t>(y) * padded_w + col);
      box_sum_sq -= load(row_sum_sq + static_cast<std::size_t>(y) * padded_w + col);
      const float* base = plane + static_cast<std::size_t>(y) * plane_stride + col;
      for (std::int32_t k = 0; k < masked; ++k) {
        const vf p = load(base + masked_offsets[k]);
        sum -= p;
        sum_sq -= p * p;
      }
      // NCC from the sums (the template is zero-mean over its valid pixels, so sum(t * I) needs no
      // mean); below a tenth of a gray level of standard deviation the image patch is flat: -1.
      float* ncc_out = out + static_cast<std::size_t>(y) * padded_w + col;
      const vf variance_sum = sum_sq - sum * sum / n_v;
      vf ncc = load(ncc_out) / (norm_v * sqrt_lanes(max_zero(variance_sum)));
      ncc = ncc > one ? one : ncc;
      ncc = ncc < minus_one ? minus_one : ncc;
      store(ncc_out, variance_sum > flat_v ? ncc : minus_one);
    }
  }
}

bool refine(const Image& image, const Template& tmpl, std::int32_t x, std::int32_t y, int iterations,
            double stop_step_px, Fit* fit) {
  // Block of image values around the peak: the patch, +-1 px of shift, one more for the bilinear cell and
  // one for the central-difference gradient; rows padded to whole vectors with finite values.
  constexpr int kMargin = 3;
  constexpr int kBlock = kSize + 2 * kMargin;
  constexpr int kResampled = kSize + 2;  // the patch plus a one-pixel ring for the gradient
  constexpr int kResampledCols = kGroup + 2;
  constexpr int kResampledStride = (kResampledCols + kWidth - 1) / kWidth * kWidth;
  constexpr int kBlockStride = (kMargin + kResampledStride + 15) / 16 * 16;  // whole conversion chunks
  // The columns the resampling reads (up to kMargin - 1 + kResampledStride), in whole chunks of 16 and 8.
  constexpr int kBlockRead = (kMargin + kResampledStride + 7) / 8 * 8;
  static_assert(kMargin - 1 + kResampledStride + 1 <= kBlockRead && kBlockRead <= kBlockStride,
                "block rows too short for the resampling");
  // Rows 0 and kBlock - 1 are never read (a shift within a pixel reaches one row of margin less on each
  // side than the block holds), so they are not converted.
  float block[kBlock][kBlockStride];
  const std::int32_t block_x = x - kSize / 2 - kMargin;
  const std::uint8_t* src = image.pixels + static_cast<std::ptrdiff_t>(y - kSize / 2 - kMargin + 1) * image.stride_bytes + block_x;
  const std::int32_t readable = image.width_px - block_x;
#pragma GCC unroll 16
  for (int j = 1; j + 1 < kBlock; ++j, src += image.stride_bytes) {
    if (readable >= kBlockRead) {
      int i = 0;
      for (; i + 16 <= kBlockRead; i += 16) bytes16_to_floats(src + i, block[j] + i);
      if (i < kBlockRead) bytes8_to_floats(src + i, block[j] + i);
    } else {
      convert_row(src, kBlock, readable, block[j], kBlockStride);
    }
  }
  // The template in rows of 8 lanes (0 at masked pixels; the eighth lane is masked).
  float t8[kSize][kGroup];
  float m8[kSize][kGroup];
#if defined(__AVX__)
  // A row is one vector: 8 values from the row's start with the eighth lane zeroed (by a bit mask: one
  // AND, where GCC builds the equal shuffle with a zero vector from three lane moves); the last row loads
  // from one value earlier and shifts down (no read past the template's 49 values).
  const vi first_seven = {-1, -1, -1, -1, -1, -1, -1, 0};
  auto row_of_seven = [&](const float* p) { return reinterpret_cast<vf>(reinterpret_cast<vi>(load(p)) & first_seven); };
  for (int ty = 0; ty + 1 < kSize; ++ty) {
    store(t8[ty], row_of_seven(tmpl.values + ty * kSize));
    store(m8[ty], row_of_seven(tmpl.mask + ty * kSize));
  }
  store(t8[kSize - 1], __builtin_shufflevector(load(tmpl.values + kPixels - kGroup), vf{}, 1, 2, 3, 4, 5, 6, 7, 8));
  store(m8[kSize - 1], __builtin_shufflevector(load(tmpl.mask + kPixels - kGroup), vf{}, 1, 2, 3, 4, 5, 6, 7, 8));
#else
  for (int ty = 0; ty < kSize; ++ty) {
    for (int tx = 0; tx < kGroup; ++tx) {
      t8[ty][tx] = tx < kSize ? tmpl.values[ty * kSize + tx] : 0.0f;
      m8[ty][tx] = tx < kSize ? tmpl.mask[ty * kSize + tx] : 0.0f;
    }
  }
#endif
  // Template-only sums of J^T J (J = [gx, gy, -t, -1]) do not change between iterations; beta starts at
  // the mean of the image patch.
  vf sum_tt = vf{};
  vf sum_t = vf{};
  vf sum_image = vf{};
  for (int ty = 0; ty < kSize; ++ty) {
    for (int lane = 0; lane < kGroup; lane += kWidth) {
      const vf t = load(&t8[ty][lane]);
      sum_tt += t * t;
      sum_t += t;
      sum_image += load(&m8[ty][lane]) * load(&block[ty + kMargin][kMargin + lane]);
    }
  }
  // The three lane sums by one shuffle-and-add tree (each lane sum in sum_lanes' order: the same values).
  const vf setup_acc[8] = {sum_tt, sum_t, sum_image, vf{}, vf{}, vf{}, vf{}, vf{}};
  float setup_sums[8];
  sum_lanes8(setup_acc, setup_sums);
  const double s_tt = setup_sums[0];
  const double s_t = setup_sums[1];
  const double s_1 = tmpl.valid_count;
  double beta = static_cast<double>(setup_sums[2]) / s_1;
  double alpha = 1.0;
  // The photometric block C = [[s_tt, s_t], [s_t, s_1]] of J^T J and its inverse (the 4x4 normal
  // equations are solved by the Schur complement on the shift: same solution, 2x2 inverses only).
  const double det_c = s_tt * s_1 - s_t * s_t;
  if (!(det_c > 0.0)) return false;
  const double ci00 = s_1 / det_c;
  const double ci01 = -s_t / det_c;
  const double ci11 = s_tt / det_c;
  double dx = fit->dx;
  double dy = fit->dy;
  double cov_xx = 1.0;
  double cov_xy = 0.0;
  double cov_yy = 1.0;
  double ncc = -1.0;
  double last_step = 0.0;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    const int ix = static_cast<int>(__builtin_floor(dx));
    const int iy = static_cast<int>(__builtin_floor(dy));
    const float fx = static_cast<float>(dx - ix);
    const float fy = static_cast<float>(dy - iy);
    const vf w00 = splat((1.0f - fx) * (1.0f - fy));
    const vf w01 = splat(fx * (1.0f - fy));
    const vf w10 = splat((1.0f - fx) * fy);
    const vf w11 = splat(fx * fy);
    // The image resampled at the shifted patch and its ring: resampled[j][i] = I(patch (i - 1, j - 1) + d).
    // Bilinear interpolation is linear and shift-invariant, so central differences of the resampled
    // values equal the resampled central-difference gradients: one interpolation per pixel, not three.
    // The ring's top and bottom rows serve only the vertical differences: their columns 1 .. kGroup (one
    // group of lanes; each lane's value is the same expression wherever its vector starts), the others
    // are never read.
    float resampled[kResampled][kResampledStride];
    auto resample = [&](int j, int i) {
      const float* r0 = &block[j + kMargin - 1 + iy][kMargin - 1 + ix];
      const float* r1 = r0 + kBlockStride;
      store(&resampled[j][i], w00 * load(r0 + i) + w01 * load(r0 + i + 1) + w10 * load(r1 + i) + w11 * load(r1 + i + 1));
    };
    for (int i = 1; i < 1 + kGroup; i += kWidth) resample(0, i);
    for (int j = 1; j + 1 < kResampled; ++j) {
      for (int i = 0; i < kResampledStride; i += kWidth) resample(j, i);
    }
    for (int i = 1; i < 1 + kGroup; i += kWidth) resample(kResampled - 1, i);
    // J^T J and J^T r as lane sums (r = I(p + d) - alpha * t - beta): the tracker's hot path.
    const vf alpha_v = splat(static_cast<float>(alpha));
    const vf beta_v = splat(static_cast<float>(beta));
    const vf half = splat(0.5f);
    // Accumulators: a_xx, a_xy, a_xt, a_x, a_yy, a_yt, a_y (J^T J), b_x, b_y, b_t, b_1 (J^T r), b_rr.
    vf acc[12];
    for (int k = 0; k < 12; ++k) acc[k] = vf{};
    for (int ty = 0; ty < kSize; ++ty) {
      for (int lane = 0; lane < kGroup; lane += kWidth) {
        const float* row = &resampled[ty + 1][lane];
        const vf m = load(&m8[ty][lane]);
        const vf t = load(&t8[ty][lane]);
        const vf gx = half * (load(row + 2) - load(row)) * m;
        const vf gy = half * (load(row + 1 + kResampledStride) - load(row + 1 - kResampledStride)) * m;
        const vf r = (load(row + 1) - alpha_v * t - beta_v) * m;
        acc[0] += gx * gx;
        acc[1] += gx * gy;
        acc[2] += gx * t;
        acc[3] += gx;
        acc[4] += gy * gy;
        acc[5] += gy * t;
        acc[6] += gy;
        acc[7] += gx * r;
        acc[8] += gy * r;
        acc[9] += t * r;
        acc[10] += r;
        acc[11] += r * r;
      }
    }
    float sums[12];
    sum_lanes12(acc, sums);
    // Normal equations [[A, B], [B^T, C]] (shift, photometric), step = -(g_a, g_c).
    const double a00 = sums[0];
    const double a01 = sums[1];
    const double a11 = sums[4];
    const double b00 = -static_cast<double>(sums[2]);
    const double b01 = -static_cast<double>(sums[3]);
    const double b10 = -static_cast<double>(sums[5]);
    const double b11 = -static_cast<double>(sums[6]);
    const double ga0 = sums[7];
    const double ga1 = sums[8];
    const double gc0 = -static_cast<double>(sums[9]);
    const double gc1 = -static_cast<double>(sums[10]);
    // Schur complement S = A - B C^-1 B^T: its inverse is the shift block of (J^T J)^-1.
    const double bc00 = b00 * ci00 + b01 * ci01;
    const double bc01 = b00 * ci01 + b01 * ci11;
    const double bc10 = b10 * ci00 + b11 * ci01;
    const double bc11 = b10 * ci01 + b11 * ci11;
    const double s00 = a00 - (bc00 * b00 + bc01 * b01);
    const double s01 = a01 - (bc00 * b10 + bc01 * b11);
    const double s10 = a01 - (bc10 * b00 + bc11 * b01);
    const double s11 = a11 - (bc10 * b10 + bc11 * b11);
    const double det_s = s00 * s11 - s01 * s10;
    if (!(det_s > 0.0) || !(s00 > 0.0)) return false;
    const double si00 = s11 / det_s;
    const double si01 = -s01 / det_s;
    const double si10 = -s10 / det_s;
    const double si11 = s00 / det_s;
    // step_shift = -S^-1 (g_a - B C^-1 g_c), step_photometric = -C^-1 (g_c + B^T step_shift).
    const double cg0 = ci00 * gc0 + ci01 * gc1;
    const double cg1 = ci01 * gc0 + ci11 * gc1;
    const double rhs0 = ga0 - (b00 * cg0 + b01 * cg1);
    const double rhs1 = ga1 - (b10 * cg0 + b11 * cg1);
    const double step_x = -(si00 * rhs0 + si01 * rhs1);
    const double step_y = -(si10 * rhs0 + si11 * rhs1);
    const double q0 = gc0 + b00 * step_x + b10 * step_y;
    const double q1 = gc1 + b01 * step_x + b11 * step_y;
    const double step_alpha = -(ci00 * q0 + ci01 * q1);
    const double step_beta = -(ci01 * q0 + ci11 * q1);
    if (!finite(step_x) || !finite(step_y) || !finite(step_alpha) || !finite(step_beta)) return false;
    const double step_norm = __builtin_sqrt(step_x * step_x + step_y * step_y);
    const bool converged = step_norm < stop_step_px;
    if (iteration + 1 == iterations || converged) {
      // Least-squares covariance of the shift: residual variance (image noise plus what the model misses,
      // 4 parameters fitted) times the shift block of (J^T J)^-1.
      const double dof = s_1 - 4.0;
      const double variance = dof > 0.0 ? static_cast<double>(sums[11]) / dof : 0.0;
      cov_xx = variance * si00;
      cov_xy = variance * 0.5 * (si01 + si10);
      cov_yy = variance * si11;
      // NCC at this linearization point: I = r + alpha t + beta over the valid pixels, so the centred sums
      // are c_ti = c_tr + alpha c_tt and c_ii = c_rr + 2 alpha c_tr + alpha^2 c_tt.
      const double b_r = sums[10];
      const double c_tt = s_tt - s_t * s_t / s_1;
      const double c_tr = static_cast<double>(sums[9]) - s_t * b_r / s_1;
      const double c_rr = static_cast<double>(sums[11]) - b_r * b_r / s_1;
      const double c_ti = c_tr + alpha * c_tt;
      const double c_ii = c_rr + 2.0 * alpha * c_tr + alpha * alpha * c_tt;
      ncc = c_ii > 0.01 * s_1 && c_tt > 0.0 ? c_ti / __builtin_sqrt(c_tt * c_ii) : -1.0;
      last_step = step_norm;
    }
    dx += step_x;
    dy += step_y;
    alpha += step_alpha;
    beta += step_beta;
    if (!(abs_d(dx) < 1.0 && abs_d(dy) < 1.0) || !(alpha > 0.0)) return false;
    if (converged) break;
  }
  if (!finite(cov_xx) || !finite(cov_xy) || !finite(cov_yy)) return false;
  fit->dx = dx;
  fit->dy = dy;
  fit->cov_xx = cov_xx;
  fit->cov_xy = cov_xy;
  fit->cov_yy = cov_yy;
  fit->ncc = ncc;
  fit->last_step_px = last_step;
  return true;
}

bool photometric(const Image& image, const std::uint8_t* patch, PhotometricPass* pass) {
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "four pixels are read as one little-endian word");
  const double inputs[16] = {pass->u_x,    pass->u_y,    pass->M[0],   pass->M[1],   pass->M[2],  pass->M[3],
                             pass->dM0[0], pass->dM0[1], pass->dM0[2], pass->dM0[3], pass->dM1[0], pass->dM1[1],
                             pass->dM1[2], pass->dM1[3], pass->gain,   pass->offset};
  for (const double v : inputs) {
    if (!finite(v)) return false;
  }
  // The map is affine, so the grid's extremes are its corners: every p inside [1, w - 2) x [1, h - 2)
  // (one more pixel each side for the central differences) when the four corners are.
  constexpr int kRadius = kSize / 2;
  for (int cy = -kRadius; cy <= kRadius; cy += 2 * kRadius) {
    for (int cx = -kRadius; cx <= kRadius; cx += 2 * kRadius) {
      const double px = pass->u_x + pass->M[0] * cx + pass->M[1] * cy;
      const double py = pass->u_y + pass->M[2] * cx + pass->M[3] * cy;
      if (!(px >= 1.0 && py >= 1.0 && px < image.width_px - 2.0 && py < image.height_px - 2.0)) return false;
    }
  }
  // Positions relative to u's integer part: small floats, resolved to ~1e-6 px.
  const double base_x = __builtin_floor(pass->u_x);
  const double base_y = __builtin_floor(pass->u_y);
  const std::int32_t base_xi = static_cast<std::int32_t>(base_x);
  const std::int32_t base_yi = static_cast<std::int32_t>(base_y);
  const float fx0 = static_cast<float>(pass->u_x - base_x);
  const float fy0 = static_cast<float>(pass->u_y - base_y);
  float m[4];
  float d0[4];
  float d1[4];
  for (int k = 0; k < 4; ++k) {
    m[k] = static_cast<float>(pass->M[k]);
    d0[k] = static_cast<float>(pass->dM0[k]);
    d1[k] = static_cast<float>(pass->dM1[k]);
  }
  // The template in rows of 8 lanes (the eighth lane 0 and out of every sum), the lanes' column offsets
  // (the eighth repeats the seventh's, so it stays inside the image) and weights.
  float t8[kSize][kGroup];
  for (int ty = 0; ty < kSize; ++ty) {
    for (int tx = 0; tx < kGroup; ++tx) t8[ty][tx] = tx < kSize ? static_cast<float>(patch[ty * kSize + tx]) : 0.0f;
  }
  const float column_offsets[kGroup] = {-3.0f, -2.0f, -1.0f, 0.0f, 1.0f, 2.0f, 3.0f, 3.0f};
  const float weights[kGroup] = {1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 0.0f};
  static_assert(kSize == 7 && kGroup == 8, "the lane tables above are for a 7x7 patch");
  const vf gain = splat(static_cast<float>(pass->gain));
  const vf offset = splat(static_cast<float>(pass->offset));
  const vf one = splat(1.0f);
  const vf half = splat(0.5f);
  const vi min_xy = vi{} + 1;
  const vi max_x = vi{} + (image.width_px - 3);
  const vi max_y = vi{} + (image.height_px - 3);
  // Accumulators: the products of [gx, gy, j2, j3, T] (upper triangle, 15), their sums (5), their
  // products with r (5), r and r^2; padded to whole groups of 12 for the lane sums.
  constexpr int kAcc = 36;
  vf acc[kAcc];
  for (int k = 0; k < kAcc; ++k) acc[k] = vf{};
  for (int ty = 0; ty < kSize; ++ty) {
    const float yy = static_cast<float>(ty - kRadius);
    for (int lane = 0; lane < kGroup; lane += kWidth) {
      const vf yx = load(column_offsets + lane);
      const vf w = load(weights + lane);
      const vf px = splat(fx0 + m[1] * yy) + splat(m[0]) * yx;
      const vf py = splat(fy0 + m[3] * yy) + splat(m[2]) * yx;
      // Floor (truncation, one less below an integer).
      vi ix = __builtin_convertvector(px, vi);
      ix += (px < __builtin_convertvector(ix, vf));
      vi iy = __builtin_convertvector(py, vi);
      iy += (py < __builtin_convertvector(iy, vf));
      const vf fx = px - __builtin_convertvector(ix, vf);
      const vf fy = py - __builtin_convertvector(iy, vf);
      const vi x0 = ix + base_xi;
      const vi y0 = iy + base_yi;
      // The corner test above holds the real positions inside; this one the rounded cells (reads below).
      const vi inside = (x0 >= min_xy) & (x0 <= max_x) & (y0 >= min_xy) & (y0 <= max_y);
      // Each lane's 4x4 neighbourhood (rows y0 - 1 .. y0 + 2, columns x0 - 1 .. x0 + 2): one 32-bit read
      // per row.
      vi word[4];
#if defined(__AVX2__)
      // One gather per row of the neighbourhoods (the same words as the scalar reads below; the lanes'
      // offsets fit 32 bits: the cells are inside the image).
      if (__builtin_ia32_movmskps256(reinterpret_cast<vf>(inside)) != 0xFF) return false;
      const vi offsets = (y0 - 1) * image.stride_bytes + (x0 - 1);
      for (int r = 0; r < 4; ++r) {
        const std::uint8_t* row = image.pixels + static_cast<std::ptrdiff_t>(r) * image.stride_bytes;
        word[r] = __builtin_ia32_gathersiv8si(vi{}, reinterpret_cast<const int*>(row), offsets, vi{} - 1, 1);
      }
#else
      std::int32_t inside_lanes[kWidth];
      std::int32_t xs[kWidth];
      std::int32_t ys[kWidth];
      __builtin_memcpy(inside_lanes, &inside, sizeof inside_lanes);
      __builtin_memcpy(xs, &x0, sizeof xs);
      __builtin_memcpy(ys, &y0, sizeof ys);
      bool all_inside = true;
      for (int k = 0; k < kWidth; ++k) all_inside = all_inside && inside_lanes[k] != 0;
      if (!all_inside) return false;
      std::uint32_t words[4][kWidth];
      for (int k = 0; k < kWidth; ++k) {
        const std::uint8_t* src = image.pixels + static_cast<std::ptrdiff_t>(ys[k] - 1) * image.stride_bytes + (xs[k] - 1);
        for (int r = 0; r < 4; ++r) __builtin_memcpy(&words[r][k], src + static_cast<std::ptrdiff_t>(r) * image.stride_bytes, 4);
      }
      for (int r = 0; r < 4; ++r) __builtin_memcpy(&word[r], words[r], sizeof word[r]);
#endif
      vf pix[4][4];
      for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) pix[r][c] = __builtin_convertvector((word[r] >> (8 * c)) & 255, vf);
      }
      // The bilinear blends: the value and the four samples one pixel away share fx and fy.
      const vf gx0 = one - fx;
      const vf gy0 = one - fy;
      auto blend = [&](int r, int c) { return gx0 * pix[r][c] + fx * pix[r][c + 1]; };
      auto vertical = [&](vf top, vf bottom) { return gy0 * top + fy * bottom; };
      const vf centre_1 = blend(1, 1);
      const vf centre_2 = blend(2, 1);
      const vf value = vertical(centre_1, centre_2);
      const vf right = vertical(blend(1, 2), blend(2, 2));
      const vf left = vertical(blend(1, 0), blend(2, 0));
      const vf down = vertical(centre_2, blend(3, 1));
      const vf up = vertical(blend(0, 1), centre_1);
      const vf gx = half * (right - left) * w;
      const vf gy = half * (down - up) * w;
      const vf t = load(&t8[ty][lane]);
      const vf r = (value - gain * t - offset) * w;
      const vf j2 = gx * (splat(d0[0]) * yx + splat(d0[1] * yy)) + gy * (splat(d0[2]) * yx + splat(d0[3] * yy));
      const vf j3 = gx * (splat(d1[0]) * yx + splat(d1[1] * yy)) + gy * (splat(d1[2]) * yx + splat(d1[3] * yy));
      store(&pass->rows[0][ty][lane], gx);
      store(&pass->rows[1][ty][lane], gy);
      store(&pass->rows[2][ty][lane], j2);
      store(&pass->rows[3][ty][lane], j3);
      store(&pass->rows[4][ty][lane], r);
      const vf j[5] = {gx, gy, j2, j3, t};
      int a = 0;
      for (int p = 0; p < 5; ++p) {
        for (int q = p; q < 5; ++q) acc[a++] += j[p] * j[q];
      }
      for (int p = 0; p < 5; ++p) acc[a++] += j[p];
      for (int p = 0; p < 5; ++p) acc[a++] += j[p] * r;
      acc[a++] += r;
      acc[a++] += r * r;
    }
  }
  float sums[kAcc];
  for (int k = 0; k < kAcc; k += 12) sum_lanes12(acc + k, sums + k);
  // J = [gx, gy, j2, j3, -T, -1]: the signs of the last two columns.
  const double sign[6] = {1.0, 1.0, 1.0, 1.0, -1.0, -1.0};
  int a = 0;
  for (int p = 0; p < 5; ++p) {
    for (int q = p; q < 5; ++q, ++a) {
      pass->JtJ[p][q] = sign[p] * sign[q] * static_cast<double>(sums[a]);
      pass->JtJ[q][p] = pass->JtJ[p][q];
    }
  }
  for (int p = 0; p < 5; ++p, ++a) {
    pass->JtJ[p][5] = -sign[p] * static_cast<double>(sums[a]);
    pass->JtJ[5][p] = pass->JtJ[p][5];
  }
  pass->JtJ[5][5] = kPixels;
  for (int p = 0; p < 5; ++p, ++a) pass->Jtr[p] = sign[p] * static_cast<double>(sums[a]);
  pass->Jtr[5] = -static_cast<double>(sums[a++]);
  pass->sum_r2 = sums[a];
  return true;
}

}  // namespace vantage::match_kernel::VANTAGE_MATCH_KERNEL_NS

#undef VANTAGE_MATCH_INLINE
