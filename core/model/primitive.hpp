#pragma once
// A planar surface primitive P_i = [X_i, Sigma_i, S_ij] (paper section III), with the footprint and
// texture data the criterion and the measurement front end need. World frame, scene units.
#include <array>
#include <cstdint>

#include <Eigen/Core>

namespace vantage {

// Side p of the reference patch S (p x p pixels); the paper leaves p to the user.
inline constexpr int kPatchSize = 7;
static_assert(kPatchSize % 2 == 1 && kPatchSize >= 3, "the patch needs a centre pixel");

using PrimitiveIndex = std::uint32_t;
inline constexpr PrimitiveIndex kInvalidPrimitive = 0xFFFFFFFFu;

namespace primitive_flags {
inline constexpr std::uint16_t kNone = 0;
inline constexpr std::uint16_t kMerged = 1u << 0;       // absorbed neighbours (adaptive scale)
inline constexpr std::uint16_t kLostTrack = 1u << 1;    // last search failed
// Its last K predicted-in-view observations were all rejected (failed match or gated): images do not
// consume its uncertainty, so the criterion leaves it out of F and U (core/planning/README.md, "Why
// coverage stalls"). Set and cleared by the measurement source; an accepted update clears it.
inline constexpr std::uint16_t kUnconsumed = 1u << 2;
// A new primitive whose depth no view has constrained yet: it rests on its two-view spawn match, and the
// matches accepted since came from views where a wrong depth would not have shown (nearly collinear with
// its seed ray). Set and cleared by the measurement source (core/frontend/EXPERIMENTS.md, "Confirmation by
// parallax"); the criterion and the planner still count it, accuracy figures and exports tell it apart.
inline constexpr std::uint16_t kProvisional = 1u << 3;
}  // namespace primitive_flags

struct Primitive {
  Eigen::Vector3d X_world = Eigen::Vector3d::Zero();               // position estimate
  Eigen::Matrix3d Sigma_world = Eigen::Matrix3d::Identity();       // position covariance, units^2
  Eigen::Vector3f normal_world = Eigen::Vector3f::UnitZ();         // unit surface normal
  float radius = 0.0f;          // radius of the planar footprint (the primitive's scale), scene units
  float saliency_h = 0.0f;      // h(P) in [0, 1] from the patch autocorrelation (eq. 6)
  std::array<std::uint8_t, kPatchSize * kPatchSize> patch{};       // reference patch S, row-major
  std::uint32_t creating_view = 0;      // index of the image that created it
  std::uint32_t observation_count = 0;  // EKF updates accepted
  std::uint16_t flags = primitive_flags::kNone;
};

}  // namespace vantage
