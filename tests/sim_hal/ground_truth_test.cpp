#include <catch2/catch.hpp>
#include <cmath>

#include "core/model/primitive_pool.hpp"
#include "sim_hal/ground_truth/ground_truth.hpp"
#include "sim_hal/sim_error.hpp"
#include "test_meshes.hpp"

using namespace vantage;
using namespace vantage::sim;

namespace {

GridGeometry small_grid() {
  GridGeometry g;
  g.cells_per_side = 20;
  g.cell_size_m = 2.0;
  return g;
}

using test::small_intrinsics;

PrimitivePool<8192> g_pool;  // static storage: pools are big

}  // namespace

TEST_CASE("visible set of a box: the sides and not the base underneath nor the top above the cameras", "[sim_hal][ground_truth]") {
  const EmbreeScene scene{test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(5, 5, 5))};
  const OccupancyGrid occupancy(scene.mesh(), small_grid(), 0.5);
  GroundTruthConfig config;
  config.sample_count = 6000;
  const GroundTruth truth(scene, occupancy, small_intrinsics(), config);
  std::size_t sides = 0;
  for (std::size_t i = 0; i < truth.samples().size(); ++i) {
    const SurfaceSample& s = truth.samples()[i];
    const bool side = std::abs(s.normal.z()) < 0.5;
    sides += side ? 1 : 0;
    if (s.normal.z() < -0.5) {
      CHECK(truth.visible()[i] == 0);  // under the base: seen from no cell
    }
    CHECK((truth.visible()[i] != 0) == side);
  }
  CHECK(truth.visible_count() == sides);
  CHECK(truth.visible_area() == Approx(600.0 * sides / 6000.0));
  CHECK(truth.surface_area() == Approx(600.0));
}

TEST_CASE("a surface seen only at grazing incidence is not part of the visible set", "[sim_hal][ground_truth]") {
  // A horizontal square 0.4 below the cameras' plane, facing up: every free cell sees it front-facing,
  // but at most at cos incidence 0.4 / 2.6 (the nearest free cell is about 2.6 away horizontally).
  TriangleMesh sheet;
  sheet.vertices = {{-0.5f, -0.5f, -0.4f}, {0.5f, -0.5f, -0.4f}, {0.5f, 0.5f, -0.4f}, {-0.5f, 0.5f, -0.4f}};
  sheet.triangles = {{0, 1, 2}, {0, 2, 3}};
  const EmbreeScene scene{sheet};
  const OccupancyGrid occupancy(scene.mesh(), small_grid(), 0.5);
  GroundTruthConfig geometric;
  geometric.sample_count = 500;
  geometric.image_margin_px = 0.0;
  geometric.min_cos_incidence = 0.0;
  const GroundTruth any_view(scene, occupancy, small_intrinsics(), geometric);
  CHECK(any_view.visible_count() == 500u);
  GroundTruthConfig observable;  // the defaults: the oracle's thresholds
  observable.sample_count = 500;
  CHECK(observable.min_cos_incidence == Approx(0.2));
  const GroundTruth measurable(scene, occupancy, small_intrinsics(), observable);
  CHECK(measurable.visible_count() == 0u);
  GroundTruthConfig bad;
  bad.min_cos_incidence = 1.0;
  CHECK_THROWS_AS(GroundTruth(scene, occupancy, small_intrinsics(), bad), SimError);
}

TEST_CASE("an occluded sample is not visible and a cell's view looks at the grid centre", "[sim_hal][ground_truth]") {
  // A small box hidden inside a big hollow-less box: the inner one is occluded from everywhere.
  TriangleMesh mesh = test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(5, 5, 5));
  const TriangleMesh inner = test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(1, 1, 1));
  const auto base = static_cast<std::uint32_t>(mesh.vertices.size());
  for (const auto& v : inner.vertices) mesh.vertices.push_back(v);
  for (const auto& t : inner.triangles) mesh.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
  const EmbreeScene scene{mesh};
  const GridGeometry g = small_grid();
  const Viewpoint view = grid_cell_viewpoint(g, GridCell{19, 10});
  CHECK((view.R_world_cam.col(2) - Eigen::Vector3d(-1, 0, 0)).norm() < 0.1);
  CHECK(!GroundTruth::visible_from(scene, small_intrinsics(), view, Eigen::Vector3d(1, 0, 0), Eigen::Vector3d::UnitX()));
  CHECK(GroundTruth::visible_from(scene, small_intrinsics(), view, Eigen::Vector3d(5, 0, 0), Eigen::Vector3d::UnitX()));
  CHECK(!GroundTruth::visible_from(scene, small_intrinsics(), view, Eigen::Vector3d(5, 0, 0), -Eigen::Vector3d::UnitX()));
}

TEST_CASE("coverage and accuracy and average sigma follow their definitions", "[sim_hal][ground_truth]") {
  const EmbreeScene scene{test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(5, 5, 5))};
  const OccupancyGrid occupancy(scene.mesh(), small_grid(), 0.5);
  GroundTruthConfig config;
  config.sample_count = 4000;
  config.coverage_distance = 0.5;
  config.sigma_target = 0.01;
  const GroundTruth truth(scene, occupancy, small_intrinsics(), config);
  g_pool.clear();
  CHECK(truth.coverage(g_pool, 0.5, 0.01) == 0.0);

  // One precise primitive 0.1 outside every visible sample.
  const auto& samples = truth.samples();
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (truth.visible()[i] == 0) continue;
    Primitive p;
    p.X_world = samples[i].position + 0.1 * samples[i].normal;
    p.Sigma_world = Eigen::Vector3d(0.003, 0.004, 0.012).cwiseAbs2().asDiagonal();
    PrimitiveIndex index;
    REQUIRE(ok(g_pool.insert(p, &index)));
  }
  const double sigma = std::sqrt((0.003 * 0.003 + 0.004 * 0.004 + 0.012 * 0.012) / 3.0);
  CHECK(primitive_sigma(g_pool[0]) == Approx(sigma));
  CHECK(GroundTruth::average_sigma(g_pool) == Approx(sigma));
  CHECK(truth.coverage(g_pool, 0.5, 0.01) == 1.0);
  CHECK(truth.coverage(g_pool, 0.05, 0.01) == 0.0);    // every primitive is 0.1 away
  CHECK(truth.coverage(g_pool, 0.5, 0.005) == 0.0);    // none is precise enough
  double rms = 0, p95 = 0, mx = 0;
  truth.accuracy(g_pool, &rms, &p95, &mx);
  CHECK(rms == Approx(0.1).epsilon(1e-4));
  CHECK(p95 == Approx(0.1).epsilon(1e-4));
  CHECK(mx == Approx(0.1).epsilon(1e-4));

  // Remove the primitives over half the box's sides: coverage drops to the remaining share.
  std::size_t kept = 0, total = 0;
  for (PrimitiveIndex i = 0; i < g_pool.index_bound(); ++i) {
    ++total;
    if (g_pool[i].X_world.x() > 5.05) {
      REQUIRE(ok(g_pool.erase(i)));
    } else {
      ++kept;
    }
  }
  const Evaluation e = truth.evaluate(g_pool);
  CHECK(e.primitive_count == kept);
  // Samples on the x = 5 face lose coverage, except within 0.5 of the neighbouring faces' primitives.
  CHECK(e.coverage < static_cast<double>(kept) / total + 0.05);
  CHECK(e.coverage > static_cast<double>(kept) / total - 0.01);
}

TEST_CASE("verified coverage counts a precise primitive only within k of its own sigmas of the surface", "[sim_hal][ground_truth]") {
  const EmbreeScene scene{test::make_box(Eigen::Vector3f::Zero(), Eigen::Vector3f(5, 5, 5))};
  const OccupancyGrid occupancy(scene.mesh(), small_grid(), 0.5);
  GroundTruthConfig config;
  config.sample_count = 4000;
  const GroundTruth truth(scene, occupancy, small_intrinsics(), config);
  g_pool.clear();
  std::size_t precise = 99, verified = 99;
  CHECK(truth.verified_coverage(g_pool, 0.5, 0.01, 3.0, &precise, &verified) == 0.0);
  CHECK(precise == 0);
  CHECK(verified == 0);

  // Every visible sample gets a primitive 0.02 outside it. Its standard deviation along the surface normal
  // is 0.01 (2 sigmas off) where the sample's x is below 0, 0.005 (4 sigmas off) elsewhere; across the
  // normal 0.001, so sigma(P) stays below the 0.01 target either way. The sides at x = +-5 are the
  // exception: their normal is x itself, so they fall wholly in one group each.
  std::size_t near = 0, far = 0;
  const auto& samples = truth.samples();
  for (std::size_t i = 0; i < samples.size(); ++i) {
    if (truth.visible()[i] == 0) continue;
    const Eigen::Vector3d n = samples[i].normal;
    const double along = samples[i].position.x() < 0.0 ? 0.01 : 0.005;
    (along == 0.01 ? near : far) += 1;
    Primitive p;
    p.X_world = samples[i].position + 0.02 * n;
    p.Sigma_world = 1e-6 * Eigen::Matrix3d::Identity() + (along * along - 1e-6) * n * n.transpose();
    REQUIRE(primitive_sigma(p) < 0.01);
    PrimitiveIndex index;
    REQUIRE(ok(g_pool.insert(p, &index)));
  }
  REQUIRE(near > 100);
  REQUIRE(far > 100);
  CHECK(truth.coverage(g_pool, 0.5, 0.01) == 1.0);
  const double covered = truth.verified_coverage(g_pool, 0.5, 0.01, 3.0, &precise, &verified);
  CHECK(precise == near + far);
  CHECK(verified == near);
  // The covered share is at least the near group's and below 1: samples of the far group within 0.5 of a
  // near primitive count too, the rest not.
  CHECK(covered >= static_cast<double>(near) / static_cast<double>(near + far) - 1e-12);
  CHECK(covered < 1.0);
  // With k = 5 both groups lie within their sigmas; with k = 1 neither does.
  CHECK(truth.verified_coverage(g_pool, 0.5, 0.01, 5.0, &precise, &verified) == 1.0);
  CHECK(verified == near + far);
  CHECK(truth.verified_coverage(g_pool, 0.5, 0.01, 1.0, &precise, &verified) == 0.0);
  CHECK(verified == 0);
  // Above the sigma target nothing is precise, verified or not; a NaN k verifies nothing.
  CHECK(truth.verified_coverage(g_pool, 0.5, 0.002, 5.0, &precise, &verified) == 0.0);  // sigma(P) 0.0030 and 0.0058
  CHECK(precise == 0);
  CHECK(truth.verified_coverage(g_pool, 0.5, 0.01, std::nan(""), &precise, &verified) == 0.0);
  CHECK(verified == 0);
}
