#include <cmath>
#include <random>

#include <catch2/catch.hpp>

#include "core/criterion/fast_math.hpp"

using namespace vantage;

TEST_CASE("fast log2 and exp2 reproduce pow within 2.5e-4 relative") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> log_x(-40.0f, 40.0f);
  std::uniform_real_distribution<float> exponent(0.0f, 1.0f);
  double worst_log = 0.0;
  double worst_pow = 0.0;
  for (int i = 0; i < 100000; ++i) {
    const float x = std::exp(log_x(rng));
    const float h = exponent(rng);
    worst_log = std::fmax(worst_log, std::abs(fast::log2(x) - std::log2(static_cast<double>(x))));
    const double expected = std::pow(static_cast<double>(x), static_cast<double>(h));
    const double got = fast::exp2(h * fast::log2(x));
    worst_pow = std::fmax(worst_pow, std::abs(got - expected) / expected);
  }
  CHECK(worst_log < 1.5e-4);
  CHECK(worst_pow < 2.5e-4);
  CHECK(fast::exp2(0.0f) == Approx(1.0f).epsilon(1e-6));
  CHECK(fast::exp2(-1000.0f) > 0.0f);  // clamped, finite
  CHECK(std::isfinite(fast::exp2(1000.0f)));
}
