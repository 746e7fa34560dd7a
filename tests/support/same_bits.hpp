#pragma once

// Bit-for-bit equality of two Eigen matrices: the check that a lane (batch) version of a function does the
// scalar one's operations in the same order. (== would pass -0.0 against 0.0 and fail NaN against NaN.)
#include <cstring>

#include <Eigen/Core>

namespace vantage::test {

template <typename Derived>
bool same_bits(const Eigen::MatrixBase<Derived>& a, const Eigen::MatrixBase<Derived>& b) {
  return std::memcmp(a.derived().data(), b.derived().data(), sizeof(typename Derived::Scalar) * a.size()) == 0;
}

}  // namespace vantage::test
