#pragma once
// A vector with inline storage of compile-time capacity. push_back on a full vector returns kPoolFull
// and leaves the vector unchanged: "full" means size() == capacity().
#include <array>
#include <cstddef>

#include "core/common/span.hpp"
#include "core/common/status.hpp"

namespace vantage {

template <typename T, std::size_t N>
class FixedVector {
 public:
  static_assert(N > 0, "FixedVector needs a positive capacity");

  Status push_back(const T& value) {
    if (size_ == N) return Status::kPoolFull;
    items_[size_++] = value;
    return Status::kOk;
  }
  void pop_back() {
    if (size_ > 0) --size_;
  }
  void clear() { size_ = 0; }

  static constexpr std::size_t capacity() { return N; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  bool full() const { return size_ == N; }

  T& operator[](std::size_t i) { return items_[i]; }
  const T& operator[](std::size_t i) const { return items_[i]; }
  T& back() { return items_[size_ - 1]; }
  const T& back() const { return items_[size_ - 1]; }
  T* begin() { return items_.data(); }
  T* end() { return items_.data() + size_; }
  const T* begin() const { return items_.data(); }
  const T* end() const { return items_.data() + size_; }

  Span<T> view() { return Span<T>(items_.data(), size_); }
  Span<const T> view() const { return Span<const T>(items_.data(), size_); }

 private:
  std::array<T, N> items_{};
  std::size_t size_ = 0;
};

}  // namespace vantage
