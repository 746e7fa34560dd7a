// The criterion's per-view inner loops (block_kernel.hpp), written with GCC/Clang vector extensions:
// float vectors of the ISA's width (8 lanes with AVX2, 4 with SSE2 or NEON), so the code is vector code
// whatever the autovectorizer decides. Included once per build of the kernel, with
// VANTAGE_KERNEL_NS naming the namespace of that build (block_kernel.cpp: baseline, block_kernel_avx2.cpp:
// avx2_fma). Everything here has internal linkage or lives in that namespace, and nothing from another
// header is instantiated, so the builds cannot leak into each other through the linker.
//
// Per view: render() computes for each kept cluster, 16 lanes at a time, the camera transform, facing,
// projection, plane gradients, footprint and visibility threshold, splats the single-pixel footprints
// (scalar, branch-free: masked lanes write a spare cell) and the larger ones (general splat), and writes
// one (pixel, threshold) entry per lane. sum_visible() then runs the depth test per cluster and computes
// the weight w g^h / f (log2/exp2/sqrt) only for clusters with a visible lane: occluded clusters, about
// half of the kept ones on the bunny, never pay for it.
#ifndef VANTAGE_KERNEL_NS
#error "define VANTAGE_KERNEL_NS before including block_kernel_impl.hpp"
#endif

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "core/criterion/block_kernel.hpp"
#include "core/criterion/fast_math.hpp"  // the polynomial coefficients only (constants, no code)
#include "core/criterion/splat_general.hpp"

namespace vantage::criterion_kernel::VANTAGE_KERNEL_NS {
namespace {

#define VANTAGE_KERNEL_INLINE inline __attribute__((always_inline))

// The widest vectors the build's ISA has: GCC lowers wider generic vectors badly where the ISA lacks them
// (SSE2 compares of 8 lanes go scalar), so 8 lanes with AVX, else 4 (SSE2, NEON).
#if defined(__AVX__)
constexpr std::size_t kWidth = 8;
#else
constexpr std::size_t kWidth = 4;
#endif
typedef float vf __attribute__((vector_size(4 * kWidth)));
typedef std::int32_t vi __attribute__((vector_size(4 * kWidth)));
constexpr std::uint32_t kVectorBits = (1u << kWidth) - 1;
static_assert(kLanes % kWidth == 0, "a cluster is a whole number of vectors");
constexpr std::size_t kBlockClusters = 128;  // sum_visible's block; its float partial sums go to double after each

VANTAGE_KERNEL_INLINE vf load(const float* p) {
  vf v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
VANTAGE_KERNEL_INLINE vi load(const std::int32_t* p) {
  vi v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
VANTAGE_KERNEL_INLINE void store(float* p, vf v) { std::memcpy(p, &v, sizeof v); }
VANTAGE_KERNEL_INLINE void store(std::int32_t* p, vi v) { std::memcpy(p, &v, sizeof v); }
VANTAGE_KERNEL_INLINE vf broadcast(float s) { return vf{} + s; }
VANTAGE_KERNEL_INLINE vi broadcast(std::int32_t s) { return vi{} + s; }
VANTAGE_KERNEL_INLINE vf to_float(vi x) { return __builtin_convertvector(x, vf); }
VANTAGE_KERNEL_INLINE vi truncate(vf x) { return __builtin_convertvector(x, vi); }
VANTAGE_KERNEL_INLINE vf select(vi mask, vf a, vf b) { return mask ? a : b; }
VANTAGE_KERNEL_INLINE vi select(vi mask, vi a, vi b) { return mask ? a : b; }

VANTAGE_KERNEL_INLINE vf square_root(vf x) {
#if defined(__AVX__)
  return __builtin_ia32_sqrtps256(x);
#elif defined(__SSE__)
  return __builtin_ia32_sqrtps(x);
#elif defined(__aarch64__)
  return __builtin_aarch64_sqrtv4sf(x);
#else
  vf r;
  for (std::size_t i = 0; i < kWidth; ++i) r[i] = __builtin_sqrtf(x[i]);
  return r;
#endif
}

// Lane i's bit, 1 << i, in every lane.
VANTAGE_KERNEL_INLINE vi lane_bits() {
  vi w;
  for (std::size_t i = 0; i < kWidth; ++i) w[i] = static_cast<std::int32_t>(1u << i);
  return w;
}

// The mask's lanes as bits (lane i -> bit i).
VANTAGE_KERNEL_INLINE std::uint32_t bits(vi mask) {
#if defined(__AVX__)
  return static_cast<std::uint32_t>(__builtin_ia32_movmskps256(reinterpret_cast<vf>(mask)));
#elif defined(__SSE__)
  return static_cast<std::uint32_t>(__builtin_ia32_movmskps(reinterpret_cast<vf>(mask)));
#else
  const vi weighted = mask & lane_bits();
  std::uint32_t r = 0;
  for (std::size_t i = 0; i < kWidth; ++i) r |= static_cast<std::uint32_t>(weighted[i]);
  return r;
#endif
}

VANTAGE_KERNEL_INLINE vf gather(const float* base, vi index) {
  vf r;
  for (std::size_t i = 0; i < kWidth; ++i) r[i] = base[index[i]];
  return r;
}

// fast::log2 and fast::exp2 (fast_math.hpp) lane by lane: the same operations in the same order.
VANTAGE_KERNEL_INLINE vf log2(vf x) {
  const vi b = reinterpret_cast<vi>(x);
  vf exponent = to_float(((b >> 23) & 0xFF) - 127);
  vf m = reinterpret_cast<vf>((b & 0x007FFFFF) | 0x3F800000);  // [1, 2)
  const vi high = m > 1.41421356f;
  m = select(high, 0.5f * m, m);
  exponent = select(high, exponent + 1.0f, exponent);
  const vf t = m - 1.0f;
  const vf p = fast::kLog2C0 + t * (fast::kLog2C1 + t * (fast::kLog2C2 + t * fast::kLog2C3));
  return exponent + t * p;
}

VANTAGE_KERNEL_INLINE vf exp2(vf y) {
  y = select(y > -126.0f, y, broadcast(-126.0f));
  y = select(y < 127.0f, y, broadcast(127.0f));
  const vf shifted = y + 0.5f;
  const vi truncated = truncate(shifted);
  const vi i = truncated + (to_float(truncated) > shifted);  // floor(y + 0.5): a true mask is -1
  const vf f = y - to_float(i);
  const vf p = 1.0f + f * (fast::kExp2C1 + f * (fast::kExp2C2 + f * fast::kExp2C3));
  return p * reinterpret_cast<vf>((i + 127) << 23);
}

// The per-view constants, broadcast once, as a local of each entry point (kept in registers: no store
// through the output pointers can alias it).
struct Broadcast {
  explicit Broadcast(const ViewConstants& k)
      : r00(broadcast(k.r00)), r01(broadcast(k.r01)), r02(broadcast(k.r02)),
        r10(broadcast(k.r10)), r11(broadcast(k.r11)), r12(broadcast(k.r12)),
        r20(broadcast(k.r20)), r21(broadcast(k.r21)), r22(broadcast(k.r22)),
        cam_x(broadcast(k.cam_x)), cam_y(broadcast(k.cam_y)), cam_z(broadcast(k.cam_z)),
        fx(broadcast(k.fx)), fy(broadcast(k.fy)), cx(broadcast(k.cx)), cy(broadcast(k.cy)),
        inv_fx(broadcast(k.inv_fx)), inv_fy(broadcast(k.inv_fy)), f_max(broadcast(k.f_max)),
        u_max(broadcast(k.u_max)), v_max(broadcast(k.v_max)), u_clamp(broadcast(k.u_clamp)),
        v_clamp(broadcast(k.v_clamp)), width_plus_one(broadcast(static_cast<float>(k.width) + 1.0f)),
        height_plus_one(broadcast(static_cast<float>(k.height) + 1.0f)), minus_two(broadcast(-2.0f)),
        tolerance_radii(broadcast(k.tolerance_radii)), one_minus_relative(broadcast(1.0f - k.relative_tolerance)),
        near_depth(broadcast(k.near_depth)), grazing2(broadcast(k.grazing_cosine2)),
        log2_fxfy(broadcast(k.log2_fxfy)), width(broadcast(k.width)), last_column(broadcast(k.width - 1)),
        last_row(broadcast(k.height - 1)), spare(broadcast(k.spare)) {}
  vf r00, r01, r02, r10, r11, r12, r20, r21, r22;
  vf cam_x, cam_y, cam_z;
  vf fx, fy, cx, cy, inv_fx, inv_fy, f_max;
  vf u_max, v_max, u_clamp, v_clamp, width_plus_one, height_plus_one, minus_two;
  vf tolerance_radii, one_minus_relative, near_depth, grazing2, log2_fxfy;
  vi width, last_column, last_row, spare;
};

VANTAGE_KERNEL_INLINE vi min(vi a, vi b) { return select(a < b, a, b); }
VANTAGE_KERNEL_INLINE vi max(vi a, vi b) { return select(a > b, a, b); }
// In the operand order of maxps/minps (and NaN goes to lo).
VANTAGE_KERNEL_INLINE vf clamp(vf x, vf lo, vf hi) {
  x = select(x > lo, x, lo);
  return select(x < hi, x, hi);
}
VANTAGE_KERNEL_INLINE vi floor_int(vf x) {
  const vi t = truncate(x);
  return t + (to_float(t) > x);  // a true mask is -1
}

// What the scalar pass of one cluster needs.
struct ClusterLanes {
  // Single-pixel footprints with the centre in the image; other lanes aim at the spare cell.
  alignas(32) std::int32_t write_pixel[kLanes];
  alignas(32) float write_iz[kLanes];
  // Footprints of 0.5 to 1 pixel with the centre in the image: the pixel centres within [u - r, u + r] are 1
  // or 2 per axis, one of them the centre pixel, so the splat is a 2 x 2 block (a pixel repeated when 1),
  // computed in vector form exactly as splat_general does pixel by pixel.
  alignas(32) std::int32_t quad_pixel[4][kLanes];  // (i0, j0), (i1, j0), (i0, j1), (i1, j1)
  alignas(32) float quad_iz[4][kLanes];
  std::uint32_t single;  // bit i: lane i is a single-pixel splat
  std::uint32_t quad;    // bit i: lane i is a quad splat
  // Every other footprint that may touch the image (larger, or the centre outside): splat_general.
  alignas(32) float u[kLanes];
  alignas(32) float v[kLanes];
  alignas(32) float iz[kLanes];
  alignas(32) float du[kLanes];
  alignas(32) float dv[kLanes];
  alignas(32) float radius_px[kLanes];
  std::uint32_t general;  // bit i: lane i needs splat_general
};

// Lanes [o, o + 8) of the cluster at slot `base`, entries from `entry`: the projection and footprint of
// every lane, computed unmasked (lanes behind the camera or facing away compute garbage that the masks
// drop). Returns the candidate mask (front-facing, centre in the image).
inline vi project(const Slots& s, const Broadcast& b, std::size_t base, std::size_t entry, std::size_t o,
                                 const Target& target, ClusterLanes& out) {
  const std::size_t slot = base + o;
  const vf ux = load(s.x + slot) - b.cam_x;
  const vf uy = load(s.y + slot) - b.cam_y;
  const vf uz = load(s.z + slot) - b.cam_z;
  const vf nx = load(s.nx + slot), ny = load(s.ny + slot), nz = load(s.nz + slot);
  const vf xc = b.r00 * ux + b.r01 * uy + b.r02 * uz;
  const vf yc = b.r10 * ux + b.r11 * uy + b.r12 * uz;
  const vf zc = b.r20 * ux + b.r21 * uy + b.r22 * uz;
  const vf facing = -(nx * ux + ny * uy + nz * uz);  // n . (camera - X)
  const vf ncx = b.r00 * nx + b.r01 * ny + b.r02 * nz;
  const vf ncy = b.r10 * nx + b.r11 * ny + b.r12 * nz;
  const vf dist2 = ux * ux + uy * uy + uz * uz;
  const vi front = (zc > b.near_depth) & (facing > 0.0f);
  const vf inv_z = 1.0f / zc;
  const vf u = b.fx * xc * inv_z + b.cx;
  const vf v = b.fy * yc * inv_z + b.cy;
  // 1/z gradients of the disc's plane n_cam . X = k with k = -facing (see splat_math).
  const vi grazing = facing * facing < b.grazing2 * dist2;
  const vf inv_k = select(grazing, vf{}, -1.0f / facing);
  const vf du = ncx * inv_k * b.inv_fx;
  const vf dv = ncy * inv_k * b.inv_fy;
  const vf radius = load(s.radius + slot);
  const vf radius_px = radius * b.f_max * inv_z;
  const vi in_image = (u >= -0.5f) & (v >= -0.5f) & (u < b.u_max) & (v < b.v_max);
  vf uc = select(u > -1.0f, u, broadcast(-1.0f));  // NaN goes to -1
  uc = select(uc < b.u_clamp, uc, b.u_clamp);
  vf vc = select(v > -1.0f, v, broadcast(-1.0f));
  vc = select(vc < b.v_clamp, vc, b.v_clamp);
  const vi pi = truncate(uc + 0.5f);
  const vi pj = truncate(vc + 0.5f);
  const vi pixel = pj * b.width + pi;
  const vf iz_pixel = inv_z + du * (to_float(pi) - u) + dv * (to_float(pj) - v);
  // splat_math::visibility_threshold: <= 0 means the tolerance reaches the camera (always visible).
  const vf threshold = iz_pixel / (b.one_minus_relative - b.tolerance_radii * radius * iz_pixel);
  const vi member = front & in_image;
  const vi single = member & (radius_px < 0.5f);
  const vi quad = member & ~single & (radius_px < 1.0f);
  store(target.pixel + entry + o, select(member, pixel, b.spare));
  store(target.threshold + entry + o,
        select(member, select(threshold > 0.0f, threshold, broadcast(3.0e38f)), broadcast(-1.0f)));
  store(out.write_pixel + o, select(single, pixel, b.spare));
  store(out.write_iz + o, iz_pixel);
  out.single |= bits(single) << o;
  // Quads and general splats are rare in far views: their data only when a lane needs it.
  const std::uint32_t quad_bits = bits(quad);
  if (quad_bits != 0) {
    // splat_general's pixel range: for 0.5 <= r < 1 it holds the centre pixel, so no min/max with it.
    const vi i0 = max(-floor_int(-clamp(u - radius_px, b.minus_two, b.width_plus_one)), vi{});
    const vi i1 = min(floor_int(clamp(u + radius_px, b.minus_two, b.width_plus_one)), b.last_column);
    const vi j0 = max(-floor_int(-clamp(v - radius_px, b.minus_two, b.height_plus_one)), vi{});
    const vi j1 = min(floor_int(clamp(v + radius_px, b.minus_two, b.height_plus_one)), b.last_row);
    const vf row0 = inv_z + dv * (to_float(j0) - v);
    const vf row1 = inv_z + dv * (to_float(j1) - v);
    const vf step0 = du * (to_float(i0) - u);
    const vf step1 = du * (to_float(i1) - u);
    store(out.quad_pixel[0] + o, j0 * b.width + i0);
    store(out.quad_pixel[1] + o, j0 * b.width + i1);
    store(out.quad_pixel[2] + o, j1 * b.width + i0);
    store(out.quad_pixel[3] + o, j1 * b.width + i1);
    store(out.quad_iz[0] + o, row0 + step0);
    store(out.quad_iz[1] + o, row0 + step1);
    store(out.quad_iz[2] + o, row1 + step0);
    store(out.quad_iz[3] + o, row1 + step1);
    out.quad |= quad_bits << o;
  }
  // Larger footprints, and those with the centre outside the image unless the square misses it.
  vi general = member & ~single & ~quad;
  const vi off_centre = front & ~in_image;
  if (bits(off_centre) != 0) {
    general |= off_centre & (u + radius_px >= -0.5f) & (v + radius_px >= -0.5f) & (u - radius_px < b.u_max) &
               (v - radius_px < b.v_max);
  }
  const std::uint32_t general_bits = bits(general);
  if (general_bits != 0) {
    store(out.u + o, u);
    store(out.v + o, v);
    store(out.iz + o, inv_z);
    store(out.du + o, du);
    store(out.dv + o, dv);
    store(out.radius_px + o, radius_px);
    out.general |= general_bits << o;
  }
  return member;
}

// The scalar pass of one cluster: single-pixel splats (branch-free, masked lanes write the spare cell),
// then the quads and the general splats, lane by lane through their bit masks.
inline void splat_cluster(const ClusterLanes& in, const ViewConstants& kc, float* __restrict depth) {
  for (std::size_t o = 0; o < kLanes; o += kWidth) {
    if ((in.single >> o & kVectorBits) == 0) continue;  // near views: no single-pixel lane in whole vectors
    for (std::size_t i = o; i < o + kWidth; ++i) {
      float& cell = depth[in.write_pixel[i]];
      const float iz = in.write_iz[i];
      cell = iz > cell ? iz : cell;
    }
  }
  for (std::uint32_t m = in.quad; m != 0; m &= m - 1) {
    const int i = __builtin_ctz(m);
    for (std::size_t c = 0; c < 4; ++c) {
      float& cell = depth[in.quad_pixel[c][i]];
      const float iz = in.quad_iz[c][i];
      cell = iz > cell ? iz : cell;
    }
  }
  for (std::uint32_t m = in.general; m != 0; m &= m - 1) {
    const int i = __builtin_ctz(m);
    splat_kernel::splat_general(depth, kc.width, kc.height, in.u[i], in.v[i], in.iz[i], in.du[i], in.dv[i],
                                in.radius_px[i]);
  }
}

// w' g^h / f' of lanes [o, o + 8) of the cluster at slot `base` (scaled units), for lanes that passed
// the depth test: |u| / |Sigma' u| * 2^(log2(w' (pi r^2)^h) + h log2(fx fy facing / z^3)), u = X - x.
inline vf weights(const Slots& s, const Broadcast& b, std::size_t slot) {
  const vf ux = load(s.x + slot) - b.cam_x;
  const vf uy = load(s.y + slot) - b.cam_y;
  const vf uz = load(s.z + slot) - b.cam_z;
  const vf zc = b.r20 * ux + b.r21 * uy + b.r22 * uz;
  const vf facing = -(load(s.nx + slot) * ux + load(s.ny + slot) * uy + load(s.nz + slot) * uz);
  const vf dist2 = ux * ux + uy * uy + uz * uz;
  const vf inv_z = 1.0f / zc;
  // f = |Sigma v|: with Sigma' = Sigma / scale, f' = |Sigma' u| / |u|.
  const vf s01 = load(s.s01 + slot), s02 = load(s.s02 + slot), s12 = load(s.s12 + slot);
  const vf su_x = load(s.s00 + slot) * ux + s01 * uy + s02 * uz;
  const vf su_y = s01 * ux + load(s.s11 + slot) * uy + s12 * uz;
  const vf su_z = s02 * ux + s12 * uy + load(s.s22 + slot) * uz;
  const vf qu = su_x * su_x + su_y * su_y + su_z * su_z;
  const vf log2_g_rest = log2(facing * inv_z * inv_z * inv_z);
  const vf log2_wa = load(s.log2_wa + slot);
  const vf weight = exp2(log2_wa + load(s.h + slot) * (b.log2_fxfy + log2_g_rest)) * square_root(dist2 / qu);
  // A zero-radius footprint has g = 0: it adds exactly 0 (never 0^0 = 1); so does a dropped weight.
  return select((load(s.radius + slot) > 0.0f) & (log2_wa > kZeroWeightLog2), weight, vf{});
}

}  // namespace

std::size_t cull(const Bounds& bo, const ViewConstants& kc, std::size_t count, std::uint32_t* kept) {
  const Broadcast b(kc);
  std::size_t n = 0;
  alignas(32) std::int32_t keep[kWidth];
  for (std::size_t c0 = 0; c0 < count; c0 += kWidth) {
    const vf dx = load(bo.centre_x + c0) - b.cam_x;  // centre - camera
    const vf dy = load(bo.centre_y + c0) - b.cam_y;
    const vf dz = load(bo.centre_z + c0) - b.cam_z;
    const vf r = load(bo.radius + c0);
    const vf xc = b.r00 * dx + b.r01 * dy + b.r02 * dz;
    const vf yc = b.r10 * dx + b.r11 * dy + b.r12 * dz;
    const vf zc = b.r20 * dx + b.r21 * dy + b.r22 * dz;
    const vi outside = (zc < b.near_depth - r) | (kc.left_x * xc + kc.left_z * zc < -r) |
                       (kc.right_x * xc + kc.right_z * zc < -r) | (kc.top_y * yc + kc.top_z * zc < -r) |
                       (kc.bottom_y * yc + kc.bottom_z * zc < -r);
    // Normal cone (axis a, half-angle alpha) against the directions from the sphere to the camera, which
    // lie within beta = asin(r / d) of (camera - centre); a cone of 90 degrees or more has cos <= 0.
    const vf cos_alpha = load(bo.cos_half_angle + c0);
    const vf sin_alpha = load(bo.sin_half_angle + c0);
    const vf d = square_root(dx * dx + dy * dy + dz * dz);
    const vf sin_beta = r / d;  // garbage when d <= r: masked below
    const vf cos_beta2 = 1.0f - sin_beta * sin_beta;
    const vf cos_beta = square_root(select(cos_beta2 > 0.0f, cos_beta2, vf{}));
    const vf cos_sum = cos_alpha * cos_beta - sin_alpha * sin_beta;  // cos(alpha + beta)
    const vf sin_sum = sin_alpha * cos_beta + cos_alpha * sin_beta;
    const vf axis_to_camera = -(load(bo.axis_x + c0) * dx + load(bo.axis_y + c0) * dy + load(bo.axis_z + c0) * dz);
    const vi away = (cos_alpha > 0.0f) & (d > r) & (cos_sum > 0.0f) & (axis_to_camera < -sin_sum * d);
    store(keep, ~(outside | away));
    const std::size_t lanes = count - c0 < kWidth ? count - c0 : kWidth;
    for (std::size_t i = 0; i < lanes; ++i) {
      kept[n] = static_cast<std::uint32_t>(c0 + i);
      n += static_cast<std::size_t>(keep[i] & 1);
    }
  }
  return n;
}

std::size_t render(const Slots& s, const ViewConstants& kc, std::uint32_t* clusters, std::size_t count,
                   const Target& target, std::size_t* candidates) {
  const Broadcast b(kc);
  vi members = vi{};
  std::size_t n = 0;
  ClusterLanes lanes;
  for (std::size_t k = 0; k < count; ++k) {
    const std::uint32_t cluster = clusters[k];
    const std::size_t base = static_cast<std::size_t>(cluster) * kLanes;
    lanes.single = 0;
    lanes.quad = 0;
    lanes.general = 0;
    vi member = vi{};
    for (std::size_t o = 0; o < kLanes; o += kWidth) {
      const vi m = project(s, b, base, n * kLanes, o, target, lanes);
      members -= m;
      member |= m;
    }
    splat_cluster(lanes, kc, target.depth);
    clusters[n] = cluster;  // n <= k: the entries written above stay when the cluster has a candidate
    n += bits(member) != 0 ? 1 : 0;
  }
  std::size_t total = 0;
  for (std::size_t i = 0; i < kWidth; ++i) total += static_cast<std::size_t>(members[i]);
  *candidates = total;
  return n;
}

double sum_visible(const Slots& s, const ViewConstants& kc, const std::uint32_t* clusters, std::size_t count,
                   const Target& target) {
  const Broadcast b(kc);
  const float* __restrict depth = target.depth;
  const vi lane_bit = lane_bits();
  double total = 0.0;
  // Blocks of clusters: first the depth test of every lane and the list of clusters with a visible lane,
  // then the weights of the listed clusters in a loop without data-dependent branches, which the CPU
  // overlaps across clusters (the weights are long dependency chains: log2, exp2, division, root).
  std::uint32_t listed[kBlockClusters];
  std::uint32_t visible_bits[kBlockClusters];
  for (std::size_t k0 = 0; k0 < count; k0 += kBlockClusters) {
    const std::size_t end = count - k0 < kBlockClusters ? count : k0 + kBlockClusters;
    std::size_t n = 0;
    for (std::size_t k = k0; k < end; ++k) {
      std::uint32_t visible = 0;
      for (std::size_t h = 0; h < kLanes / kWidth; ++h) {
        const std::size_t e = k * kLanes + h * kWidth;
        visible |= bits(gather(depth, load(target.pixel + e)) <= load(target.threshold + e)) << (h * kWidth);
      }
      listed[n] = static_cast<std::uint32_t>(k);
      visible_bits[n] = visible;
      n += visible != 0 ? 1 : 0;
    }
    vf partial = vf{};  // at most 2 kBlockClusters terms per lane in float, then double
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t base = static_cast<std::size_t>(clusters[listed[i]]) * kLanes;
      for (std::size_t h = 0; h < kLanes / kWidth; ++h) {
        const vi visible = (broadcast(static_cast<std::int32_t>(visible_bits[i] >> (h * kWidth))) & lane_bit) != 0;
        partial += select(visible, weights(s, b, base + h * kWidth), vf{});
      }
    }
    for (std::size_t i = 0; i < kWidth; ++i) total += static_cast<double>(partial[i]);
  }
  return total;
}

#undef VANTAGE_KERNEL_INLINE

}  // namespace vantage::criterion_kernel::VANTAGE_KERNEL_NS
