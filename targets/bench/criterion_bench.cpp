// NBV criterion over the paper's view grid (60 x 60 cells, 2 units, elevation 0) on a 70K-primitive
// model sampled from the bunny. Target: the full grid in <= 0.5 s with 2 threads (>= 7,200 views/s).
// Run (Release): vantage-bench --benchmark_filter=Criterion --benchmark_repetitions=5
//                --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <thread>
#include <vector>

#include "core/criterion/criterion_model.hpp"
#include "core/criterion/view_grid.hpp"
#include "targets/bench/bench_models.hpp"

namespace {

using vantage::CriterionModel;
using vantage::CriterionScratch;
using vantage::ViewGrid;

constexpr int kMaxThreads = 2;
constexpr std::int32_t kGridSide = 60;

struct Fixture {
  CriterionModel<> model;
  CriterionScratch<vantage::kDefaultPrimitiveCapacity> scratch[kMaxThreads];
  ViewGrid<kGridSide> grid;
};

// Built once: the model refreshed from the bunny pool, the grid configured around it.
Fixture* fixture(benchmark::State& state) {
  static std::unique_ptr<Fixture> f;
  static std::string error;
  if (!f && error.empty()) {
    vantage::PrimitivePoolView* pool = nullptr;
    const vantage::bench::BunnyModel& bunny = vantage::bench::bunny_model(&pool);
    if (!bunny.ok) {
      error = "bunny model: " + bunny.error;
    } else {
      f = std::make_unique<Fixture>();
      vantage::Status s = f->model.refresh(*pool);
      if (vantage::ok(s)) s = f->grid.configure(bunny.grid, Eigen::Vector3d::Zero());
      if (vantage::ok(s)) s = f->grid.update_free_mask(f->model, vantage::kDefaultSafetyMargin);
      if (!vantage::ok(s)) {
        error = std::string("criterion setup: ") + vantage::to_string(s);
        f.reset();
      }
    }
  }
  if (!f) state.SkipWithError(error.c_str());
  return f.get();
}

// Whole grid per iteration, cells split into contiguous halves per thread.
void BM_CriterionFullGrid(benchmark::State& state) {
  Fixture* f = fixture(state);
  if (f == nullptr) return;
  vantage::PrimitivePoolView* pool = nullptr;
  const vantage::PinholeIntrinsics intrinsics = vantage::bench::bunny_model(&pool).intrinsics;
  const int threads = static_cast<int>(state.range(0));
  const std::int32_t cells = f->grid.cell_count();
  for (auto _ : state) {
    vantage::Status status[kMaxThreads] = {vantage::Status::kOk, vantage::Status::kOk};
    std::vector<std::thread> workers;
    for (int t = 0; t < threads; ++t) {
      const std::int32_t begin = cells * t / threads;
      const std::int32_t end = cells * (t + 1) / threads;
      workers.emplace_back([&, t, begin, end] {
        status[t] = f->grid.evaluate(f->model, intrinsics, begin, end, f->scratch[t]);
      });
    }
    for (std::thread& w : workers) w.join();
    for (int t = 0; t < threads; ++t) {
      if (!vantage::ok(status[t])) {
        state.SkipWithError(vantage::to_string(status[t]));
        return;
      }
    }
    const vantage::Status finalized = f->grid.finalize();
    if (!vantage::ok(finalized)) {
      state.SkipWithError(vantage::to_string(finalized));
      return;
    }
    benchmark::DoNotOptimize(f->grid.nbv());
  }
  state.counters["views_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * cells, benchmark::Counter::kIsRate);
  state.counters["clusters_kept_pct"] =
      100.0 * static_cast<double>(f->scratch[0].clusters_kept()) / static_cast<double>(f->scratch[0].clusters_total());
}
BENCHMARK(BM_CriterionFullGrid)->Arg(1)->Arg(2)->ArgName("threads")->Unit(benchmark::kMillisecond)->UseRealTime();

// One model update: eigen-free terms, Morton clustering and bounds for 70K primitives.
void BM_CriterionRefresh(benchmark::State& state) {
  Fixture* f = fixture(state);
  if (f == nullptr) return;
  vantage::PrimitivePoolView* pool = nullptr;
  (void)vantage::bench::bunny_model(&pool);
  for (auto _ : state) {
    const vantage::Status s = f->model.refresh(*pool);
    if (!vantage::ok(s)) {
      state.SkipWithError(vantage::to_string(s));
      return;
    }
  }
  state.counters["primitives"] = static_cast<double>(f->model.primitive_count());
  double cone_deg = 0.0, radius = 0.0;
  int wide = 0;
  for (std::size_t c = 0; c < f->model.cluster_count(); ++c) {
    const vantage::ClusterBounds& b = f->model.cluster(c);
    if (b.cos_half_angle <= 0.0f) ++wide; else cone_deg += std::acos(b.cos_half_angle) * 57.2957795;
    radius += b.radius;
  }
  state.counters["cone_deg_mean"] = cone_deg / (f->model.cluster_count() - wide);
  state.counters["wide_cones"] = wide;
  state.counters["sphere_radius_mean"] = radius / f->model.cluster_count();
}
BENCHMARK(BM_CriterionRefresh)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

namespace {

// Views on the calling thread (CPU time is meaningful here, unlike in the threaded runs): every 37th cell
// of the grid per iteration (98 views, near and far, all azimuths), the same set every iteration.
void BM_CriterionSingleView(benchmark::State& state) {
  Fixture* f = fixture(state);
  if (f == nullptr) return;
  vantage::PrimitivePoolView* pool = nullptr;
  const vantage::PinholeIntrinsics intrinsics = vantage::bench::bunny_model(&pool).intrinsics;
  double F = 0.0;
  std::size_t views = 0;
  std::size_t candidates = 0;
  std::size_t kept = 0;
  std::size_t total = 0;
  for (auto _ : state) {
    for (std::int32_t cell = 0; cell < f->grid.cell_count(); cell += 37) {
      const vantage::Status s =
          f->model.evaluate(f->grid.viewpoint(f->grid.geometry().cell_at(cell)), intrinsics, f->scratch[0], &F);
      if (!vantage::ok(s)) {
        state.SkipWithError(vantage::to_string(s));
        return;
      }
      benchmark::DoNotOptimize(F);
      ++views;
      candidates += f->scratch[0].candidates();
      kept += f->scratch[0].clusters_kept();
      total += f->scratch[0].clusters_total();
    }
  }
  state.counters["views_per_cpu_s"] = benchmark::Counter(static_cast<double>(views), benchmark::Counter::kIsRate);
  state.counters["clusters_kept_pct"] = 100.0 * static_cast<double>(kept) / static_cast<double>(total);
  state.counters["candidates"] = static_cast<double>(candidates) / static_cast<double>(views);
}
BENCHMARK(BM_CriterionSingleView)->Unit(benchmark::kMicrosecond);

}  // namespace
