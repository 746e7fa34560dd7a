#pragma once
// The NBV criterion of the paper (section IV, eqs. 4-9) over a model of primitives, heap-free.
//
//   f(nu, P) = || v^T Psi ||, Psi = [l1 e1, l2 e2, l3 e3] (eq. 4), v the unit viewing direction to X.
//              Psi Psi^T = Sigma^2, so f = sqrt(v^T Sigma^2 v) = |Sigma v|: the cache keeps Sigma, no
//              per-view eigen-decomposition (compute_psi below gives Psi itself; a test checks both agree).
//   g(nu, P) = projected area, in pixels of the camera's image, of the primitive's planar footprint (disc
//              of `radius` with `normal_world`): pi r^2 fx fy (n . (x_cam - X)) / z^3 for a small disc;
//              0 when back-facing, behind the camera, centre outside the image, or occluded.
//   h(P)     = Primitive::saliency_h (core/criterion/saliency.hpp, set when the primitive is created).
//   C = g^h / f (eq. 7) and F(nu) = sum_i w_i C_i (eq. 8), w = det Sigma (eq. 9), over visible
//   primitives only: an invisible primitive (g = 0) adds exactly 0, never 0^0 = 1. A primitive flagged
//   primitive_flags::kUnconsumed (its observations keep being rejected) has w = 0 but still occludes.
//
// CriterionModel<Capacity>::refresh() computes everything that does not depend on nu once per model
// update: Sigma and det Sigma (in float, relative to the model's largest variance so that tiny
// covariances do not underflow), h, the footprint, and an order of the primitives into spatial clusters
// of kClusterSize with a bounding sphere and a normal cone each. A view then (1) rejects whole clusters
// that lie outside its frustum or face away from it, (2) splats the front-facing primitives of the rest
// into a software depth buffer (DepthBuffer), computing each one's contribution in the same
// vectorizable loop, and (3) sums the contributions of those that pass the depth test.
//
// Evaluation is const on the model and writes only to a caller-owned CriterionScratch, so several
// threads may evaluate views of one model at once, each with its own scratch (the core starts none).
#include <array>
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

#include "core/common/span.hpp"
#include "core/common/status.hpp"
#include "core/criterion/depth_buffer.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/model/primitive.hpp"
#include "core/model/primitive_pool.hpp"

namespace vantage {

inline constexpr std::size_t kClusterSize = 16;

constexpr std::size_t round_up_to_clusters(std::size_t n) { return (n + kClusterSize - 1) / kClusterSize * kClusterSize; }

// Psi = [l1 e1, l2 e2, l3 e3] of eq. 4 (eigenvalues descending). Sigma must be SPD (caller checks).
Eigen::Matrix3d compute_psi(const Eigen::Matrix3d& Sigma);

// One primitive seen from one viewpoint, in double precision (for tests and diagnostics).
struct CriterionTerms {
  bool visible = false;      // front-facing, centre in the image, passes the depth test
  double g_px2 = 0.0;        // projected footprint area, camera pixels (0 when not visible)
  double f = 0.0;            // || v^T Psi ||, scene units^2
  double h = 0.0;            // saliency exponent
  double w = 0.0;            // det Sigma, units^6
  double contribution = 0.0; // w g^h / f when visible, else exactly 0
};

// Bounds of one cluster: sphere around every footprint, and a cone around every normal.
struct ClusterBounds {
  float centre_x = 0.0f;
  float centre_y = 0.0f;
  float centre_z = 0.0f;
  float radius = 0.0f;
  float axis_x = 0.0f;  // unit mean normal; zero when the cone is too wide to cull (>= 90 degrees)
  float axis_y = 0.0f;
  float axis_z = 0.0f;
  float sin_half_angle = 1.0f;
  float cos_half_angle = 0.0f;
};

// Which build of the view loops runs (block_kernel.hpp): the baseline ISA of the target (SSE2 on x86-64,
// NEON on aarch64) or, on x86-64 CPUs with AVX2 and FMA, a build for those. kAuto: the fastest the CPU
// supports. The builds agree on F to float rounding (test).
enum class CriterionKernel : std::uint8_t { kAuto, kBaseline, kAvx2Fma };
const char* to_string(CriterionKernel kernel);
// Whether this binary and CPU can run `kernel` (kAuto and kBaseline always).
bool criterion_kernel_supported(CriterionKernel kernel);
// The kernel kAuto runs here.
CriterionKernel best_criterion_kernel();

// Per-thread working memory of a view evaluation: the depth buffer, the surviving clusters, and one
// entry (pixel, visibility threshold) per lane of every surviving cluster. Capacity-free view;
// CriterionScratch<Capacity, W, H> owns.
class CriterionScratchView {
 public:
  CriterionScratchView(const CriterionScratchView&) = delete;
  CriterionScratchView& operator=(const CriterionScratchView&) = delete;

  DepthBufferView& depth() { return depth_; }
  const DepthBufferView& depth() const { return depth_; }
  std::size_t capacity() const { return capacity_; }
  // Statistics of the last evaluation (culling effectiveness).
  std::size_t clusters_total() const { return clusters_total_; }
  std::size_t clusters_kept() const { return clusters_kept_; }
  // Primitives of the kept clusters that are front-facing with their centre in the image.
  std::size_t candidates() const { return candidates_; }

  // The kernel this scratch's evaluations run (default kAuto). kInvalidArgument, nothing changed, when
  // this CPU or build cannot run it (criterion_kernel_supported).
  Status select_kernel(CriterionKernel kernel);
  // The kernel actually run: the selected one, kAuto resolved to best_criterion_kernel().
  CriterionKernel kernel() const;

 protected:
  CriterionScratchView(DepthBufferView& depth, std::uint32_t* clusters, std::int32_t* pixel, float* threshold,
                       std::size_t capacity)
      : depth_(depth), clusters_(clusters), pixel_(pixel), threshold_(threshold), capacity_(capacity) {}
  ~CriterionScratchView() = default;

 private:
  friend class CriterionModelView;
  DepthBufferView& depth_;
  std::uint32_t* clusters_;  // after a render: the kept clusters with a candidate
  std::int32_t* pixel_;     // entry k * kClusterSize + i: lane i of clusters_[k]
  float* threshold_;        // visible when depth[pixel] <= threshold (-1: cannot be visible)
  std::size_t capacity_;    // primitives (a multiple of kClusterSize)
  std::size_t clusters_total_ = 0;
  std::size_t clusters_kept_ = 0;
  std::size_t clusters_rendered_ = 0;  // clusters_[0, clusters_rendered_): kept, with a candidate
  std::size_t candidates_ = 0;
  CriterionKernel kernel_ = CriterionKernel::kAuto;
};

// The scratch's buffers, a base class constructed before CriterionScratchView receives pointers to them.
template <std::size_t Slots, std::int32_t W, std::int32_t H>
struct CriterionScratchStorage {
  DepthBuffer<W, H> depth_buffer_;
  std::array<std::uint32_t, Slots / kClusterSize> clusters_{};
  std::array<std::int32_t, Slots> pixel_{};
  std::array<float, Slots> threshold_{};
};

template <std::size_t Capacity, std::int32_t W = 160, std::int32_t H = 120>
class CriterionScratch : private CriterionScratchStorage<round_up_to_clusters(Capacity), W, H>,
                         public CriterionScratchView {
 public:
  static constexpr std::size_t kSlots = round_up_to_clusters(Capacity);
  static_assert(Capacity > 0, "scratch needs a positive capacity");
  CriterionScratch()
      : CriterionScratchView(Storage::depth_buffer_, Storage::clusters_.data(), Storage::pixel_.data(),
                             Storage::threshold_.data(), kSlots) {}

 private:
  using Storage = CriterionScratchStorage<kSlots, W, H>;  // qualified: the view has members of the same names
};

// Structure-of-arrays storage of the cluster bounds (ClusterBounds field by field), readable up to a
// multiple of kClusterVector clusters (the culling loop reads whole vectors).
inline constexpr std::size_t kClusterVector = 8;
struct ClusterArrays {
  float* centre_x;
  float* centre_y;
  float* centre_z;
  float* radius;
  float* axis_x;
  float* axis_y;
  float* axis_z;
  float* sin_half_angle;
  float* cos_half_angle;
};

// Structure-of-arrays storage of the per-primitive terms, one entry per slot (slots in cluster order).
struct CriterionArrays {
  float* x;
  float* y;
  float* z;
  float* nx;
  float* ny;
  float* nz;
  float* s00;  // Sigma / scale, upper triangle
  float* s01;
  float* s02;
  float* s11;
  float* s12;
  float* s22;
  float* log2_wa;  // log2(det(Sigma / scale) * (pi r^2)^h)
  float* h;
  float* radius;
  PrimitiveIndex* index;  // pool index of the slot
  std::uint64_t* sort_keys;
  ClusterArrays clusters;
};

class CriterionModelView {
 public:
  CriterionModelView(const CriterionModelView&) = delete;
  CriterionModelView& operator=(const CriterionModelView&) = delete;

  // Recomputes every view-independent term from the pool's alive primitives. On error the cache is
  // unchanged and rejected_index() names the primitive: kNonFiniteInput (NaN/Inf position, normal,
  // radius, h or Sigma), kNotSpd (Sigma), kInvalidArgument (zero normal, negative radius, h outside
  // [0, 1]); kPoolFull when the pool holds more alive primitives than this cache's capacity.
  Status refresh(const PrimitivePoolView& pool);

  // F(nu) into *F_out (unchanged on error). kNonFiniteInput / kInvalidArgument for a bad pose or
  // intrinsics, kInvalidImage for zero-size intrinsics, kInvalidArgument when scratch is too small.
  Status evaluate(const Viewpoint& view, const PinholeIntrinsics& intrinsics, CriterionScratchView& scratch,
                  double* F_out) const;

  // The pool indices of the primitives visible from view (front-facing, centre in the image, not
  // occluded), in cluster order. Writes min(count, out.size()) indices and the full count into
  // *count_out; kPoolFull when out was too small. Errors as evaluate(), *count_out = 0.
  Status visible_primitives(const Viewpoint& view, const PinholeIntrinsics& intrinsics, CriterionScratchView& scratch,
                            Span<PrimitiveIndex> out, std::size_t* count_out) const;

  // The terms of one primitive from view, in double precision (slow: renders the whole view).
  // kNotFound when index is not in the cache. Errors as evaluate().
  Status primitive_terms(const Viewpoint& view, const PinholeIntrinsics& intrinsics, CriterionScratchView& scratch,
                         PrimitiveIndex index, CriterionTerms* out) const;

  std::size_t primitive_count() const { return count_; }
  std::size_t cluster_count() const { return round_up_to_clusters(count_) / kClusterSize; }
  std::size_t capacity() const { return capacity_; }
  // Revision of the pool at the last successful refresh (PrimitivePoolView::revision()).
  std::uint64_t pool_revision() const { return pool_revision_; }
  bool refreshed() const { return refreshed_; }
  PrimitiveIndex rejected_index() const { return rejected_index_; }
  // Scale s with Sigma = s * Sigma' in the cache (largest mean variance of the model).
  double variance_scale() const { return scale_; }

  // Read-only access to the slots [0, primitive_count()) for other core algorithms (free mask).
  const float* slot_x() const { return arrays_.x; }
  const float* slot_y() const { return arrays_.y; }
  const float* slot_z() const { return arrays_.z; }
  const float* slot_radius() const { return arrays_.radius; }
  const PrimitiveIndex* slot_index() const { return arrays_.index; }
  ClusterBounds cluster(std::size_t c) const;

 protected:
  CriterionModelView(const CriterionArrays& arrays, std::size_t capacity) : arrays_(arrays), capacity_(capacity) {}
  ~CriterionModelView() = default;

 private:
  struct ViewSetup;
  Status prepare(const Viewpoint& view, const PinholeIntrinsics& intrinsics, CriterionScratchView& scratch,
                 ViewSetup* setup) const;
  // Culls, splats and fills the scratch entries and setup's view constants (prepare validated everything).
  void render(ViewSetup& setup, CriterionScratchView& scratch) const;

  CriterionArrays arrays_;
  std::size_t capacity_;  // slots, a multiple of kClusterSize
  std::size_t count_ = 0;
  double scale_ = 1.0;
  std::uint64_t pool_revision_ = 0;
  PrimitiveIndex rejected_index_ = kInvalidPrimitive;
  bool refreshed_ = false;
};

// The cache's arrays (slots, and cluster bounds rounded up to whole vectors), a base class constructed before
// CriterionModelView receives pointers to them.
template <std::size_t Slots>
struct CriterionModelStorage {
  static constexpr std::size_t kClusterSlots =
      (Slots / kClusterSize + kClusterVector - 1) / kClusterVector * kClusterVector;
  CriterionArrays arrays() {
    const ClusterArrays clusters{cx_.data(), cy_.data(), cz_.data(), cr_.data(),  ax_.data(),
                                 ay_.data(), az_.data(), sin_.data(), cos_.data()};
    return CriterionArrays{x_.data(),   y_.data(),   z_.data(),   nx_.data(),    ny_.data(),   nz_.data(),
                           s00_.data(), s01_.data(), s02_.data(), s11_.data(),   s12_.data(),  s22_.data(),
                           lwa_.data(), h_.data(),   r_.data(),   index_.data(), keys_.data(), clusters};
  }
  std::array<float, Slots> x_{}, y_{}, z_{}, nx_{}, ny_{}, nz_{};
  std::array<float, Slots> s00_{}, s01_{}, s02_{}, s11_{}, s12_{}, s22_{};
  std::array<float, Slots> lwa_{}, h_{}, r_{};
  std::array<PrimitiveIndex, Slots> index_{};
  std::array<std::uint64_t, Slots> keys_{};
  std::array<float, kClusterSlots> cx_{}, cy_{}, cz_{}, cr_{}, ax_{}, ay_{}, az_{}, sin_{}, cos_{};
};

// Owner of the cache for up to Capacity primitives: about 72 bytes per primitive.
template <std::size_t Capacity = kDefaultPrimitiveCapacity>
class CriterionModel : private CriterionModelStorage<round_up_to_clusters(Capacity)>, public CriterionModelView {
 public:
  static_assert(Capacity > 0, "criterion model needs a positive capacity");
  static constexpr std::size_t kSlots = round_up_to_clusters(Capacity);
  CriterionModel() : CriterionModelView(CriterionModelStorage<kSlots>::arrays(), kSlots) {}
};

}  // namespace vantage
