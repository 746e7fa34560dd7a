#pragma once
// --normal-oracle: before each update, every alive primitive of the image front end adopts the surface's
// normal at its seed (ImageFrontEnd::adopt_normal): the least-squares plane through the mesh points its
// reference patch shows, ray-cast through the patch's pixels from its creating view, facing that view,
// with a tilt variance of kNormalOracleTiltVariance. A diagnostic, never a configuration: it measures what
// normals as good as the truth would buy a mission (core/frontend/EXPERIMENTS.md, "Session 24"), as
// TailOracle measures a perfect test for the matches' tail.
#include <cstdint>
#include <cstdio>
#include <vector>

#include <Eigen/Core>

#include "core/frontend/image_front_end.hpp"
#include "sim_hal/scene/embree_scene.hpp"

namespace vantage::sim {

// (0.57 degrees)^2: the oracle's normals are the patch plane's, exact up to the mesh's relief.
inline constexpr double kNormalOracleTiltVariance = 1e-4;

// The plane through the mesh points that the kPatchSize x kPatchSize pixels around seed_px show from view
// (rays through the pixel centres; at least half of them must hit): its unit normal, turned toward the
// view, in *normal_world. False, output untouched, when too few rays hit or the points are degenerate.
bool patch_plane_normal(const EmbreeScene& scene, const PinholeIntrinsics& intrinsics, const Eigen::Vector2d& seed_px,
                        const Viewpoint& view, Eigen::Vector3d* normal_world);

class NormalOracle {
 public:
  NormalOracle(const EmbreeScene& scene, const PinholeIntrinsics& intrinsics, std::int32_t seed_stride_px)
      : scene_(scene), intrinsics_(intrinsics), stride_px_(seed_stride_px) {}
  // Every alive primitive whose creating view front_end still holds adopts its seed's patch plane normal.
  // A primitive's truth depends only on its creating view and seed, so it is cast once per (slot, view,
  // seed) and kept.
  void apply(ImageFrontEnd& front_end, PrimitivePoolView& pool);
  std::uint64_t adopted() const { return adopted_; }
  std::uint64_t without_truth() const { return without_truth_; }  // asked, but no patch plane to give
  // One line: normals adopted over the mission, and those asked without a truth.
  void print(std::FILE* out) const;

 private:
  struct Truth {
    std::uint32_t creating_view = 0;
    Eigen::Vector2d seed_px = Eigen::Vector2d::Constant(-1.0);
    bool found = false;
    Eigen::Vector3d normal_world = Eigen::Vector3d::Zero();
  };
  const EmbreeScene& scene_;
  PinholeIntrinsics intrinsics_;
  std::int32_t stride_px_;
  std::vector<Truth> truths_;  // by pool slot
  std::uint64_t adopted_ = 0;
  std::uint64_t without_truth_ = 0;
};

}  // namespace vantage::sim
