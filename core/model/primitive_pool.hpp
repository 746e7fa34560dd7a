#pragma once
// Fixed-capacity pool of primitives with stable indices and a free list. "Full" means every slot is
// alive: insert() then returns kPoolFull, counts the rejection, and changes nothing. Algorithms take a
// PrimitivePoolView (capacity-free); only the owner, PrimitivePool<N>, knows N.
#include <array>
#include <cstddef>
#include <cstdint>

#include "core/common/status.hpp"
#include "core/model/primitive.hpp"

namespace vantage {

// Default capacity: enough for a quasi-dense model of the 70K-triangle bunny with room to spare.
inline constexpr std::size_t kDefaultPrimitiveCapacity = 131072;

class PrimitivePoolView {
 public:
  PrimitivePoolView(const PrimitivePoolView&) = delete;
  PrimitivePoolView& operator=(const PrimitivePoolView&) = delete;

  // Copies primitive into a free slot. kNonFiniteInput for NaN/Inf fields, kPoolFull when full.
  Status insert(const Primitive& primitive, PrimitiveIndex* index_out);
  // Frees the slot; the index may be reused by a later insert. kNotFound for a dead or bad index.
  Status erase(PrimitiveIndex index);
  void clear();

  bool is_alive(PrimitiveIndex index) const { return index < capacity_ && alive_[index] != 0; }
  Primitive& operator[](PrimitiveIndex index) { return items_[index]; }
  const Primitive& operator[](PrimitiveIndex index) const { return items_[index]; }

  std::size_t size() const { return size_; }
  std::size_t capacity() const { return capacity_; }
  bool full() const { return size_ == capacity_; }
  // Every alive index is below this bound: iterate [0, index_bound()) and skip !is_alive.
  PrimitiveIndex index_bound() const { return index_bound_; }
  // How many inserts were refused because the pool was full.
  std::uint64_t full_rejections() const { return full_rejections_; }
  // Bumped on every insert, erase or clear, so caches of derived per-primitive data know to refresh.
  std::uint64_t revision() const { return revision_; }
  void mark_modified() { ++revision_; }

 protected:
  PrimitivePoolView(Primitive* items, std::uint8_t* alive, PrimitiveIndex* free_list, std::size_t capacity);
  ~PrimitivePoolView() = default;

 private:
  Primitive* items_;
  std::uint8_t* alive_;
  PrimitiveIndex* free_list_;  // stack of free indices; free_count_ valid entries
  std::size_t capacity_;
  std::size_t size_ = 0;
  std::size_t free_count_ = 0;
  PrimitiveIndex index_bound_ = 0;
  std::uint64_t full_rejections_ = 0;
  std::uint64_t revision_ = 0;
};

// The pool's arrays, a base class so they are constructed before PrimitivePoolView receives pointers to them.
template <std::size_t N>
struct PrimitivePoolStorage {
  std::array<Primitive, N> items_{};
  std::array<std::uint8_t, N> alive_{};
  std::array<PrimitiveIndex, N> free_list_{};
};

template <std::size_t N = kDefaultPrimitiveCapacity>
class PrimitivePool : private PrimitivePoolStorage<N>, public PrimitivePoolView {
 public:
  static_assert(N > 0 && N < kInvalidPrimitive, "pool capacity must fit a PrimitiveIndex");
  static constexpr std::size_t kCapacity = N;

  PrimitivePool()
      : PrimitivePoolView(Storage::items_.data(), Storage::alive_.data(), Storage::free_list_.data(), N) {}

 private:
  using Storage = PrimitivePoolStorage<N>;  // qualified: the view has members of the same names
};

}  // namespace vantage
