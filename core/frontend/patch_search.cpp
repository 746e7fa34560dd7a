#include "core/frontend/patch_search.hpp"

#include <cmath>
#include <cstdlib>
#include <limits>

#include "core/geometry/projection.hpp"

namespace vantage {

namespace {

// Two double lanes (GCC/Clang vector extensions: SSE2 on x86-64, NEON on aarch64).
using Double2 = double __attribute__((vector_size(16)));
using Long2 = std::int64_t __attribute__((vector_size(16)));
Double2 splat2(double value) { return Double2{value, value}; }

// The two lanes of a comparison mask (each all ones or zeros) as bits 0 and 1.
unsigned mask_bits(Long2 mask) {
#if defined(__SSE2__)
  return static_cast<unsigned>(__builtin_ia32_movmskpd(reinterpret_cast<Double2>(mask)));
#else
  return static_cast<unsigned>((mask[0] & 1) | (mask[1] & 2));
#endif
}

// Local maxima the window search keeps for its uniqueness test; more take a second scan.
constexpr std::int32_t kWindowSearchMaxPeaks = 16;
static_assert(kWindowSearchMaxBox <= 64, "a row of gate flags is one 64-bit word");

// refine_subpixel's stop: a step shorter than this (the searches take MatchConfig::subpixel_stop_step_px).
constexpr double kRefineStopStepPx = 1e-3;

// Subpixel refinement at an integer peak from its 4-neighbours' NCC.
Eigen::Vector2d refine(std::int32_t x, std::int32_t y, float centre, float left, float right, float up, float down) {
  return Eigen::Vector2d(x + parabola_peak_offset(left, centre, right), y + parabola_peak_offset(up, centre, down));
}

// std::lround (half away from zero) inline: truncation is exact for |value| < 2^30, and value minus its
// truncation is exact too; the library call (through the PLT) for anything else.
std::int32_t round_to_int(double value) {
  if (!(std::abs(value) < 1073741824.0)) return static_cast<std::int32_t>(std::lround(value));
  const std::int32_t truncated = static_cast<std::int32_t>(value);
  const double fraction = value - truncated;
  return truncated + (fraction >= 0.5 ? 1 : (fraction <= -0.5 ? -1 : 0));
}

// The kernel views of an image and a template.
match_kernel::Image kernel_image(const GrayImageView& image) {
  return match_kernel::Image{image.pixels, image.width_px, image.height_px, image.stride_bytes};
}
match_kernel::Template kernel_template(const NccTemplate& tmpl) {
  return match_kernel::Template{tmpl.values.data(), tmpl.mask.data(), tmpl.norm, tmpl.valid_count};
}

// refine_subpixel with a stop step and the chosen kernel's functions.
// ncc (may be null): the fit's NCC at its last linearization point (match_kernel::Fit::ncc).
bool refine_with(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x, std::int32_t y, int iterations,
                 double stop_step_px, const match_kernel::Functions& kernels, Eigen::Vector2d* uv_px,
                 Eigen::Matrix2d* covariance_px2, double* ncc = nullptr, double* last_step_px = nullptr) {
  // The kernel (match_kernel_impl.hpp) needs the patch, +-1 px of shift, the bilinear cell and the
  // central-difference gradient inside the image: 3 px of margin.
  if (!patch_inside(image, x, y, 3) || tmpl.valid_count < 8) return false;
  match_kernel::Fit fit{uv_px->x() - x, uv_px->y() - y, 0.0, 0.0, 0.0, 0.0, 0.0};
  if (!(std::abs(fit.dx) < 1.0 && std::abs(fit.dy) < 1.0)) return false;
  if (!kernels.refine(kernel_image(image), kernel_template(tmpl), x, y, iterations, stop_step_px, &fit)) return false;
  *uv_px = Eigen::Vector2d(x + fit.dx, y + fit.dy);
  if (covariance_px2 != nullptr) *covariance_px2 << fit.cov_xx, fit.cov_xy, fit.cov_xy, fit.cov_yy;
  if (ncc != nullptr) *ncc = fit.ncc;
  if (last_step_px != nullptr) *last_step_px = fit.last_step_px;
  return true;
}

// The direct path of a window search (WindowQuery::direct_fit): the photometric fit from the prediction
// itself (Kanade-Lucas-Tomasi style), taken when it converges (its last step shorter than
// subpixel_stop_step_px within subpixel_iterations) within a pixel of the prediction's nearest pixel and
// its NCC there reaches ncc_min. False, outputs untouched, otherwise (the caller then searches the window).
// No uniqueness test: inside a region smaller than the texture's correlation length the NCC surface has
// one lobe, and a second peak a full lobe away lies outside what the prior allows (EXPERIMENTS.md, "Speed").
bool fit_from_prediction(const GrayImageView& image, const NccTemplate& tmpl, const Eigen::Vector2d& predicted_px,
                         const MatchConfig& config, const match_kernel::Functions& kernels, Eigen::Vector2d* uv_px,
                         float* best_ncc, Eigen::Matrix2d* covariance_px2) {
  const std::int32_t x = round_to_int(predicted_px.x());
  const std::int32_t y = round_to_int(predicted_px.y());
  Eigen::Vector2d uv = predicted_px;
  Eigen::Matrix2d covariance;
  double ncc = -1.0;
  double last_step = 0.0;
  if (!refine_with(image, tmpl, x, y, config.subpixel_iterations, config.subpixel_stop_step_px, kernels, &uv,
                   &covariance, &ncc, &last_step) ||
      !(last_step < config.subpixel_stop_step_px) || !(ncc >= config.ncc_min)) {
    return false;
  }
  *uv_px = uv;
  *best_ncc = static_cast<float>(ncc);
  if (covariance_px2 != nullptr) *covariance_px2 = covariance;
  return true;
}

}  // namespace

bool refine_subpixel(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x, std::int32_t y,
                     int iterations, Eigen::Vector2d* uv_px, Eigen::Matrix2d* covariance_px2) {
  return refine_subpixel(image, tmpl, x, y, iterations, uv_px, covariance_px2, MatchKernel::kAuto);
}

bool refine_subpixel(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x, std::int32_t y,
                     int iterations, Eigen::Vector2d* uv_px, Eigen::Matrix2d* covariance_px2, MatchKernel kernel) {
  return refine_subpixel(image, tmpl, x, y, iterations, uv_px, covariance_px2, kernel, nullptr);
}

bool refine_subpixel(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x, std::int32_t y,
                     int iterations, Eigen::Vector2d* uv_px, Eigen::Matrix2d* covariance_px2, MatchKernel kernel,
                     double* last_step_px) {
  if (!match_kernel_supported(kernel)) return false;
  return refine_with(image, tmpl, x, y, iterations, kRefineStopStepPx, match_kernel::functions(kernel), uv_px,
                     covariance_px2, nullptr, last_step_px);
}

MatchOutcome search_window(const GrayImageView& image, const NccTemplate& tmpl, const WindowQuery& query,
                           const MatchConfig& config, Span<float> scratch, Eigen::Vector2d* uv_px, float* best_ncc,
                           Eigen::Matrix2d* covariance_px2) {
  if (!query.predicted_px.allFinite() || query.half_width_px < 1 || query.half_height_px < 1) {
    return MatchOutcome::kNoRoom;
  }
  if (query.direct_fit && config.subpixel_iterations > 0 &&
      fit_from_prediction(image, tmpl, query.predicted_px, config, match_kernel::functions(config.kernel), uv_px,
                          best_ncc, covariance_px2)) {
    return MatchOutcome::kMatched;
  }
  const std::int32_t cx = round_to_int(query.predicted_px.x());
  const std::int32_t cy = round_to_int(query.predicted_px.y());
  // The box holds the window plus a one-pixel ring so every candidate has its 4-neighbours' NCC.
  std::int32_t x0 = cx - query.half_width_px - 1;
  std::int32_t x1 = cx + query.half_width_px + 1;
  std::int32_t y0 = cy - query.half_height_px - 1;
  std::int32_t y1 = cy + query.half_height_px + 1;
  if (x0 < kPatchRadius) x0 = kPatchRadius;
  if (y0 < kPatchRadius) y0 = kPatchRadius;
  if (x1 > image.width_px - 1 - kPatchRadius) x1 = image.width_px - 1 - kPatchRadius;
  if (y1 > image.height_px - 1 - kPatchRadius) y1 = image.height_px - 1 - kPatchRadius;
  const std::int32_t w = x1 - x0 + 1;
  const std::int32_t h = y1 - y0 + 1;
  if (w < 3 || h < 3) return MatchOutcome::kNoRoom;
  if (w > kWindowSearchMaxBox || h > kWindowSearchMaxBox) return MatchOutcome::kNoRoom;
  const std::size_t ncc_size = static_cast<std::size_t>(h) * static_cast<std::size_t>(ncc_box_out_stride(w));
  if (ncc_size > scratch.size()) return MatchOutcome::kNoRoom;
  // Candidates inside the gate ellipse (the pixel nearest the prediction always counts as inside, so a
  // tiny ellipse between pixel centres still has one) as one bit per pixel: bit x - x0 of
  // inside[y - y0]; then the rectangle that holds them.
  std::uint64_t inside[kWindowSearchMaxBox];  // rows y0 + 1 .. y1 - 1 written below, the only ones read
  const double a = query.S_inv(0, 0);
  const double b = query.S_inv(0, 1);
  const double c = query.S_inv(1, 0);
  const double e = query.S_inv(1, 1);
  // The gate test four pixels at a time, the last one or two as a pair (each lane the scalar form's
  // operations in its order, so the same bits; the rows are short, and a compiler-vectorized loop spent
  // most of its time in its prologue and epilogue). A row's last group may test a pixel past its last
  // candidate: the ring column x1, cleared by interior_bits.
  const Double2 px2 = splat2(query.predicted_px.x());
  const Double2 a2 = splat2(a);
  const Double2 c2 = splat2(c);
  const Double2 gate2 = splat2(query.gate_chi2);
  const std::uint64_t interior_bits = ((std::uint64_t{1} << (w - 1)) - 1) & ~std::uint64_t{1};
  for (std::int32_t y = y0 + 1; y < y1; ++y) {
    const double dy = y - query.predicted_px.y();
    const Double2 dy2 = splat2(dy);
    const Double2 b_dy2 = splat2(b * dy);
    const Double2 e_dy2 = splat2(e * dy);
    // The two pixels at columns xs: inside the gate, as bits 0 and 1.
    auto in_gate = [&](Double2 xs) {
      const Double2 dx = xs - px2;
      return mask_bits(dx * (a2 * dx + b_dy2) + dy2 * (c2 * dx + e_dy2) <= gate2);
    };
    Double2 xa = Double2{static_cast<double>(x0 + 1), static_cast<double>(x0 + 2)};
    std::uint64_t bits = 0;
    std::int32_t x = x0 + 1;
    for (; x + 2 < x1; x += 4) {
      bits |= static_cast<std::uint64_t>(in_gate(xa) | (in_gate(xa + splat2(2.0)) << 2)) << (x - x0);
      xa += splat2(4.0);
    }
    if (x < x1) bits |= static_cast<std::uint64_t>(in_gate(xa)) << (x - x0);  // one or two left: one pair
    inside[y - y0] = bits & interior_bits;
  }
  if (cx > x0 && cx < x1 && cy > y0 && cy < y1) inside[cy - y0] |= std::uint64_t{1} << (cx - x0);
  std::int32_t in_x0 = x1;
  std::int32_t in_x1 = x0;
  std::int32_t in_y0 = y1;
  std::int32_t in_y1 = y0;
  for (std::int32_t y = y0 + 1; y < y1; ++y) {
    const std::uint64_t bits = inside[y - y0];
    if (bits == 0) continue;
    const std::int32_t first = x0 + __builtin_ctzll(bits);
    const std::int32_t last = x0 + 63 - __builtin_clzll(bits);
    in_x0 = first < in_x0 ? first : in_x0;
    in_x1 = last > in_x1 ? last : in_x1;
    in_y0 = y < in_y0 ? y : in_y0;
    in_y1 = y;
  }
  *best_ncc = -2.0f;
  if (in_x0 > in_x1) return MatchOutcome::kBelowThreshold;
  // NCC of that rectangle and its one-pixel ring (every candidate's 8-neighbours) at once: vectorized,
  // cheaper than evaluating the needed centres one by one.
  const std::int32_t n_x0 = in_x0 - 1;
  const std::int32_t n_y0 = in_y0 - 1;
  const std::int32_t n_w = in_x1 - in_x0 + 3;
  const std::int32_t n_h = in_y1 - in_y0 + 3;
  const std::int32_t n_stride = ncc_box_out_stride(n_w);
  float* ncc = scratch.data();
  float* const rest = ncc + ncc_size;
  // The kernel directly (ncc_box's checks, the kernel chosen once per search; a CPU without the
  // configured kernel gets the baseline). A flat template correlates at -1 everywhere: no match.
  if (scratch.size() - ncc_size < ncc_box_scratch_size(n_w, n_h)) return MatchOutcome::kNoRoom;
  if (tmpl.norm <= 0.0f || tmpl.valid_count < 2) {
    *best_ncc = -1.0f;
    return MatchOutcome::kBelowThreshold;
  }
  const match_kernel::Functions kernels = match_kernel::functions(config.kernel);
  const match_kernel::Box box{n_x0, n_y0, n_w, n_h, ncc_box_plane_stride(n_w), n_stride};
  kernels.ncc_box(kernel_image(image), kernel_template(tmpl), box, rest, ncc);
  auto value = [&](std::int32_t x, std::int32_t y) { return ncc[(y - n_y0) * n_stride + x - n_x0]; };
  // The eight neighbours, those below and right first: the scans below run in raster order, so a
  // candidate on the rising slope toward a peak usually fails on its first test.
  auto is_local_max = [&](std::int32_t x, std::int32_t y) {
    const float* centre = ncc + (y - n_y0) * n_stride + (x - n_x0);
    const std::int32_t s = n_stride;
    const float v = *centre;
    return !(centre[s] > v || centre[1] > v || centre[s + 1] > v || centre[s - 1] > v || centre[-1] > v ||
             centre[-s] > v || centre[-s + 1] > v || centre[-s - 1] > v);
  };
  // Every candidate in raster order: f(x, y), stopping when it returns true.
  auto for_each_candidate = [&](auto f) {
    for (std::int32_t y = in_y0; y <= in_y1; ++y) {
      for (std::uint64_t bits = inside[y - y0]; bits != 0; bits &= bits - 1) {
        if (f(x0 + __builtin_ctzll(bits), y)) return;
      }
    }
  };
  // One pass for the best local maximum inside the gate ellipse and the other local maxima that could make
  // it ambiguous. Once the best reaches ncc_min, only values >= low can be either: the uniqueness bound
  // ratio * best (rounded) never falls below ratio * ncc_min (rounded the same way), so low is the
  // smaller of that and ncc_min. A search whose best stays below ncc_min (no match) scans again for it,
  // as *best_ncc reports it; one with more peaks than the list holds checks uniqueness by a second scan.
  const float ratio = config.uniqueness_ratio;
  const float ratio_min = ratio * config.ncc_min;
  float low = ratio_min < config.ncc_min ? ratio_min : config.ncc_min;
  if (!(ratio >= 0.0f) || !(low >= -2.0f)) low = -2.0f;  // a negative ratio or NaN: every value counts
  struct Peak {
    std::int32_t x;
    std::int32_t y;
    float value;
  };
  Peak peaks[kWindowSearchMaxPeaks];
  std::int32_t peak_count = 0;
  bool peaks_overflow = false;
  float best = -2.0f;
  std::int32_t bx = 0;
  std::int32_t by = 0;
  for_each_candidate([&](std::int32_t x, std::int32_t y) {
    const float v = value(x, y);
    if (!(v >= low) || !is_local_max(x, y)) return false;
    if (peak_count < kWindowSearchMaxPeaks) {
      peaks[peak_count++] = Peak{x, y, v};
    } else {
      peaks_overflow = true;
    }
    if (v > best) {
      best = v;
      bx = x;
      by = y;
    }
    return false;
  });
  if (peak_count == 0) {
    for_each_candidate([&](std::int32_t x, std::int32_t y) {
      if (value(x, y) <= best || !is_local_max(x, y)) return false;
      best = value(x, y);
      bx = x;
      by = y;
      return false;
    });
  }
  *best_ncc = best;
  if (best < config.ncc_min) return MatchOutcome::kBelowThreshold;
  // Uniqueness over the other local maxima inside the ellipse: the region the prior allows.
  const float unique_below = config.uniqueness_ratio * best;
  if (peaks_overflow) {
    bool ambiguous = false;
    for_each_candidate([&](std::int32_t x, std::int32_t y) {
      if (std::abs(x - bx) <= 1 && std::abs(y - by) <= 1) return false;
      ambiguous = value(x, y) >= unique_below && is_local_max(x, y);
      return ambiguous;
    });
    if (ambiguous) return MatchOutcome::kAmbiguous;
  } else {
    for (std::int32_t k = 0; k < peak_count; ++k) {
      const Peak& peak = peaks[k];
      if (std::abs(peak.x - bx) <= 1 && std::abs(peak.y - by) <= 1) continue;
      if (peak.value >= unique_below) return MatchOutcome::kAmbiguous;
    }
  }
  Eigen::Vector2d uv = refine(bx, by, best, value(bx - 1, by), value(bx + 1, by), value(bx, by - 1), value(bx, by + 1));
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Constant(std::numeric_limits<double>::quiet_NaN());
  double last_step = 0.0;
  if (config.subpixel_iterations > 0 &&
      (!refine_with(image, tmpl, bx, by, config.subpixel_iterations, config.subpixel_stop_step_px, kernels, &uv,
                    &covariance, nullptr, &last_step) ||
       (config.require_converged_fit && !(last_step < config.subpixel_stop_step_px)))) {
    return MatchOutcome::kNoSubpixel;
  }
  *uv_px = uv;
  if (covariance_px2 != nullptr) *covariance_px2 = covariance;
  return MatchOutcome::kMatched;
}

MatchOutcome search_epipolar(const GrayImageView& second_image, const NccTemplate& tmpl, const EpipolarQuery& query,
                             const PinholeIntrinsics& intrinsics, const MatchConfig& config, Span<float> scratch_ncc,
                             Span<std::int32_t> scratch_xy, Eigen::Vector2d* uv_second_px, float* best_ncc,
                             Eigen::Matrix2d* covariance_px2) {
  *best_ncc = -2.0f;
  if (!(query.depth_min > 0.0) || !(query.depth_max > query.depth_min)) return MatchOutcome::kNoRoom;
  if (std::isnan(query.guard_fraction)) return MatchOutcome::kNoRoom;
  const Eigen::Vector3d ray = back_project_ray_world(query.uv_first_px, query.first, intrinsics);
  const double ray_z = ray.dot(query.first.R_world_cam.col(2));
  if (!(ray_z > 0.0)) return MatchOutcome::kNoRoom;
  // Knots uniform in inverse depth, joined by straight pieces: exact without distortion, close with it.
  // The range's own pieces first as knots 0..kKnots-1 (near to far), the guard's on either side with
  // about the same spacing; the far guard stops short of infinity, where the ray's point is not finite.
  constexpr int kKnots = 16;
  const double inverse_near = 1.0 / query.depth_min;
  const double inverse_far = 1.0 / query.depth_max;
  const double span = inverse_near - inverse_far;
  const double guard = query.guard_fraction > 0.0 ? query.guard_fraction * span : 0.0;
  const double far_guard = guard < inverse_far * (1.0 - 1e-3) ? guard : inverse_far * (1.0 - 1e-3);
  const double near_knots = guard > 0.0 ? std::ceil((kKnots - 1) * guard / span) : 0.0;
  const double far_knots = far_guard > 0.0 ? std::ceil((kKnots - 1) * far_guard / span) : 0.0;
  if (!(near_knots <= 16 * kKnots && far_knots <= 16 * kKnots)) return MatchOutcome::kNoRoom;  // huge
  const int near_pieces = static_cast<int>(near_knots);
  const int far_pieces = static_cast<int>(far_knots);
  auto inverse_depth_of = [&](int k) {  // k in [-near_pieces, kKnots - 1 + far_pieces]
    if (k < 0) return inverse_near + guard * (static_cast<double>(-k) / near_pieces);
    if (k >= kKnots) return inverse_far - far_guard * (static_cast<double>(k - (kKnots - 1)) / far_pieces);
    const double s = static_cast<double>(k) / (kKnots - 1);
    return (1.0 - s) / query.depth_min + s / query.depth_max;
  };
  const std::size_t capacity = scratch_ncc.size() < scratch_xy.size() / 2 ? scratch_ncc.size() : scratch_xy.size() / 2;
  std::size_t count = 0;
  // Samples [range_begin, range_end) are the range's, the rest the guard's (set at knots 1 and kKnots - 1,
  // which the loop always reaches: a range knot that fails returns).
  std::size_t range_begin = 0;
  std::size_t range_end = 0;
  std::int32_t last_x = -1;
  std::int32_t last_y = -1;
  bool have_previous = false;  // the first knot has no piece before it
  Eigen::Vector2d previous_px = Eigen::Vector2d::Zero();
  for (int k = -near_pieces; k < kKnots + far_pieces; ++k) {
    // The piece that ends at knot k belongs to the range when both its knots do; the guard's pieces
    // are cut where they leave the image or the second camera's front.
    const bool in_range = k > 0 && k < kKnots;
    if (k == 1) range_begin = count;
    const double inverse_depth = inverse_depth_of(k);
    const Eigen::Vector3d X = query.first.position_world + ray * (1.0 / inverse_depth / ray_z);
    Eigen::Vector2d px;
    if (!ok(project(X, query.second, intrinsics, &px)) || !px.allFinite() ||
        std::abs(px.x()) > 1e6 || std::abs(px.y()) > 1e6) {
      if (k >= 0 && k < kKnots) return MatchOutcome::kNoRoom;  // part of the depth range behind the second camera
      have_previous = false;
      continue;
    }
    if (have_previous) {
      const Eigen::Vector2d step = px - previous_px;
      const int pieces = static_cast<int>(std::ceil(step.cwiseAbs().maxCoeff())) + 1;
      for (int i = 0; i <= pieces; ++i) {
        const Eigen::Vector2d p = previous_px + step * (static_cast<double>(i) / pieces);
        const std::int32_t x = round_to_int(p.x());
        const std::int32_t y = round_to_int(p.y());
        if (x == last_x && y == last_y) continue;
        // A depth range that leaves the image may hold the true match where it cannot be searched: then
        // the best in-image peak proves nothing, so the seed is not matched at all.
        if (!patch_inside(second_image, x, y, 1)) {
          if (in_range) return MatchOutcome::kNoRoom;
          continue;
        }
        if (count == capacity) return MatchOutcome::kNoRoom;
        scratch_xy[2 * count] = x;
        scratch_xy[2 * count + 1] = y;
        scratch_ncc[count] = ncc_at(second_image, x, y, tmpl);
        ++count;
        last_x = x;
        last_y = y;
      }
    }
    if (k == kKnots - 1) range_end = count;
    previous_px = px;
    have_previous = true;
  }
  if (count < 3) return MatchOutcome::kNoRoom;
  // Interior local maxima of the sequence; its ends are not candidates (a peak there may lie beyond what
  // was searched).
  float best = -2.0f;
  std::size_t best_i = 0;
  for (std::size_t i = 1; i + 1 < count; ++i) {
    const float c = scratch_ncc[i];
    if (c > best && c >= scratch_ncc[i - 1] && c >= scratch_ncc[i + 1]) {
      best = c;
      best_i = i;
    }
  }
  *best_ncc = best;
  if (best < config.ncc_min) return MatchOutcome::kBelowThreshold;
  if (best_i < range_begin || best_i >= range_end) return MatchOutcome::kBeyondDepthRange;
  const std::int32_t seq_x = scratch_xy[2 * best_i];
  const std::int32_t seq_y = scratch_xy[2 * best_i + 1];
  for (std::size_t i = 1; i + 1 < count; ++i) {
    const std::int32_t x = scratch_xy[2 * i];
    const std::int32_t y = scratch_xy[2 * i + 1];
    if (std::abs(x - seq_x) <= 1 && std::abs(y - seq_y) <= 1) continue;
    const float c = scratch_ncc[i];
    if (c >= config.uniqueness_ratio * best && c >= scratch_ncc[i - 1] && c >= scratch_ncc[i + 1]) {
      return MatchOutcome::kAmbiguous;
    }
  }
  // Rounding to the pixel grid can land beside the 2D peak: climb to it (at most two steps), then refine.
  std::int32_t bx = scratch_xy[2 * best_i];
  std::int32_t by = scratch_xy[2 * best_i + 1];
  for (int climb = 0; climb < 2; ++climb) {
    std::int32_t next_x = bx;
    std::int32_t next_y = by;
    for (std::int32_t dy = -1; dy <= 1; ++dy) {
      for (std::int32_t dx = -1; dx <= 1; ++dx) {
        if ((dx == 0 && dy == 0) || !patch_inside(second_image, bx + dx, by + dy, 1)) continue;
        const float c = ncc_at(second_image, bx + dx, by + dy, tmpl);
        if (c > best) {
          best = c;
          next_x = bx + dx;
          next_y = by + dy;
        }
      }
    }
    if (next_x == bx && next_y == by) break;
    bx = next_x;
    by = next_y;
  }
  *best_ncc = best;
  const float left = ncc_at(second_image, bx - 1, by, tmpl);
  const float right = ncc_at(second_image, bx + 1, by, tmpl);
  const float up = ncc_at(second_image, bx, by - 1, tmpl);
  const float down = ncc_at(second_image, bx, by + 1, tmpl);
  Eigen::Vector2d uv = refine(bx, by, best, left, right, up, down);
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Constant(std::numeric_limits<double>::quiet_NaN());
  if (config.subpixel_iterations > 0 &&
      !refine_with(second_image, tmpl, bx, by, config.subpixel_iterations, config.subpixel_stop_step_px,
                   match_kernel::functions(config.kernel), &uv, &covariance)) {
    return MatchOutcome::kNoSubpixel;
  }
  *uv_second_px = uv;
  if (covariance_px2 != nullptr) *covariance_px2 = covariance;
  return MatchOutcome::kMatched;
}

}  // namespace vantage
