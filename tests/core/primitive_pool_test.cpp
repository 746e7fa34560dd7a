#include <catch2/catch.hpp>

#include "core/model/primitive_pool.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage;

TEST_CASE("a full pool refuses inserts, counts them and changes nothing") {
  static PrimitivePool<4> pool;
  pool.clear();
  Primitive p;
  for (int i = 0; i < 4; ++i) {
    p.radius = static_cast<float>(i);
    PrimitiveIndex index = kInvalidPrimitive;
    REQUIRE(ok(pool.insert(p, &index)));
    CHECK(index == static_cast<PrimitiveIndex>(i));
  }
  CHECK(pool.full());
  PrimitiveIndex index = kInvalidPrimitive;
  CHECK(pool.insert(p, &index) == Status::kPoolFull);
  CHECK(index == kInvalidPrimitive);
  CHECK(pool.full_rejections() == 1);
  CHECK(pool.size() == 4);
}

TEST_CASE("indices are stable across erase and freed slots are reused") {
  static PrimitivePool<8> pool;
  pool.clear();
  Primitive p;
  PrimitiveIndex a, b, c;
  p.radius = 1.0f;
  REQUIRE(ok(pool.insert(p, &a)));
  p.radius = 2.0f;
  REQUIRE(ok(pool.insert(p, &b)));
  p.radius = 3.0f;
  REQUIRE(ok(pool.insert(p, &c)));
  REQUIRE(ok(pool.erase(b)));
  CHECK_FALSE(pool.is_alive(b));
  CHECK(pool[a].radius == 1.0f);
  CHECK(pool[c].radius == 3.0f);
  CHECK(pool.erase(b) == Status::kNotFound);
  PrimitiveIndex d;
  REQUIRE(ok(pool.insert(p, &d)));
  CHECK(d == b);
  CHECK(pool.size() == 3);
}

TEST_CASE("a primitive with NaN is refused") {
  static PrimitivePool<2> pool;
  pool.clear();
  Primitive p;
  p.X_world.x() = std::nan("");
  PrimitiveIndex index;
  CHECK(pool.insert(p, &index) == Status::kNonFiniteInput);
  CHECK(pool.size() == 0);
}

TEST_CASE("the default pool holds at least 131072 primitives and inserting allocates nothing") {
  static PrimitivePool<> pool;
  STATIC_REQUIRE(PrimitivePool<>::kCapacity >= 131072);
  Primitive p;
  PrimitiveIndex index;
  REQUIRE_NO_ALLOCATION(REQUIRE(ok(pool.insert(p, &index))));
  REQUIRE_NO_ALLOCATION(REQUIRE(ok(pool.erase(index))));
}
