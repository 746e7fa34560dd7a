// NBV criterion over the paper's view grid (60 x 60 cells, 2 units, elevation 0) on a 70K-primitive
// model sampled from the bunny. Target: the full grid in <= 0.5 s with 2 threads (>= 7,200 views/s).
// Run (Release): vantage-bench --benchmark_filter=Criterion --benchmark_repetitions=5
//                --benchmark_report_aggregates_only=true
// The label names the kernel the views ran (core/criterion/block_kernel.hpp: AVX2+FMA when the CPU has it);
// VANTAGE_CRITERION_KERNEL=baseline runs the portable build instead.
#include <benchmark/benchmark.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "core/criterion/criterion_model.hpp"
#include "core/criterion/view_grid.hpp"
#include "targets/bench/bench_models.hpp"
#include "targets/bench/thread_cpu_time.hpp"

namespace {

using vantage::CriterionModel;
using vantage::CriterionScratch;
using vantage::ViewGrid;
using vantage::bench::thread_cpu_s;

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
      // VANTAGE_CRITERION_KERNEL=baseline measures the portable build of the view loops.
      const char* kernel = std::getenv("VANTAGE_CRITERION_KERNEL");
      if (kernel != nullptr && std::string(kernel) == "baseline") {
        for (auto& scratch : f->scratch) {
          if (vantage::ok(s)) s = scratch.select_kernel(vantage::CriterionKernel::kBaseline);
        }
      } else if (kernel != nullptr && std::string(kernel) != "auto") {
        error = std::string("VANTAGE_CRITERION_KERNEL: '") + kernel + "' is neither 'baseline' nor 'auto'";
        f.reset();
      }
      if (f && !vantage::ok(s)) {
        error = std::string("criterion setup: ") + vantage::to_string(s);
        f.reset();
      }
    }
  }
  if (!f) state.SkipWithError(error.c_str());
  return f.get();
}

// Whole grid per iteration, rows of cells shared out dynamically between the threads.
void BM_CriterionFullGrid(benchmark::State& state) {
  Fixture* f = fixture(state);
  if (f == nullptr) return;
  vantage::PrimitivePoolView* pool = nullptr;
  const vantage::PinholeIntrinsics intrinsics = vantage::bench::bunny_model(&pool).intrinsics;
  const int threads = static_cast<int>(state.range(0));
  const std::int32_t cells = f->grid.cell_count();
  double cpu_total_s = 0.0;  // CPU time of the workers (the shared machine's wall time says little)
  for (auto _ : state) {
    double worker_cpu_s[kMaxThreads] = {0.0, 0.0};
    vantage::Status status[kMaxThreads] = {vantage::Status::kOk, vantage::Status::kOk};
    std::vector<std::thread> workers;
    // Rows of cells handed out through a shared counter: near and far cells cost very different
    // amounts, so fixed halves leave one thread idle at the end (ViewGrid::evaluate takes any range).
    std::atomic<std::int32_t> next_row{0};
    for (int t = 0; t < threads; ++t) {
      workers.emplace_back([&, t] {
        const double cpu_begin_s = thread_cpu_s();
        for (;;) {
          const std::int32_t begin = next_row.fetch_add(1) * kGridSide;
          if (begin >= cells) break;
          const std::int32_t end = begin + kGridSide < cells ? begin + kGridSide : cells;
          status[t] = f->grid.evaluate(f->model, intrinsics, begin, end, f->scratch[t]);
          if (!vantage::ok(status[t])) break;
        }
        worker_cpu_s[t] = thread_cpu_s() - cpu_begin_s;
      });
    }
    for (std::thread& w : workers) w.join();
    for (int t = 0; t < threads; ++t) cpu_total_s += worker_cpu_s[t];
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
  state.SetLabel(std::string("kernel: ") + vantage::to_string(f->scratch[0].kernel()));
  state.counters["views_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * cells, benchmark::Counter::kIsRate);
  state.counters["clusters_kept_pct"] =
      100.0 * static_cast<double>(f->scratch[0].clusters_kept()) / static_cast<double>(f->scratch[0].clusters_total());
  // Summed over the workers: grid time on `threads` uncontended cores ~ worker_cpu_s_per_grid / threads.
  state.counters["worker_cpu_s_per_grid"] = cpu_total_s / static_cast<double>(state.iterations());
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
    const vantage::ClusterBounds b = f->model.cluster(c);
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
  state.SetLabel(std::string("kernel: ") + vantage::to_string(f->scratch[0].kernel()));
  state.counters["views_per_cpu_s"] = benchmark::Counter(static_cast<double>(views), benchmark::Counter::kIsRate);
  state.counters["clusters_kept_pct"] = 100.0 * static_cast<double>(kept) / static_cast<double>(total);
  state.counters["candidates"] = static_cast<double>(candidates) / static_cast<double>(views);
}
BENCHMARK(BM_CriterionSingleView)->Unit(benchmark::kMicrosecond);

}  // namespace
