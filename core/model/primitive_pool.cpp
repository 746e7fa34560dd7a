#include "core/model/primitive_pool.hpp"

#include <cmath>

namespace vantage {

PrimitivePoolView::PrimitivePoolView(Primitive* items, std::uint8_t* alive, PrimitiveIndex* free_list,
                                     std::size_t capacity)
    : items_(items), alive_(alive), free_list_(free_list), capacity_(capacity) {}

Status PrimitivePoolView::insert(const Primitive& primitive, PrimitiveIndex* index_out) {
  if (!primitive.X_world.allFinite() || !primitive.Sigma_world.allFinite() || !primitive.normal_world.allFinite() ||
      !std::isfinite(primitive.radius) || !std::isfinite(primitive.saliency_h)) {
    return Status::kNonFiniteInput;
  }
  PrimitiveIndex index;
  if (free_count_ > 0) {
    index = free_list_[--free_count_];
  } else if (index_bound_ < capacity_) {
    index = index_bound_++;
  } else {
    ++full_rejections_;
    return Status::kPoolFull;
  }
  items_[index] = primitive;
  alive_[index] = 1;
  ++size_;
  ++revision_;
  if (index_out != nullptr) *index_out = index;
  return Status::kOk;
}

Status PrimitivePoolView::erase(PrimitiveIndex index) {
  if (!is_alive(index)) return Status::kNotFound;
  alive_[index] = 0;
  free_list_[free_count_++] = index;
  --size_;
  ++revision_;
  return Status::kOk;
}

void PrimitivePoolView::clear() {
  for (PrimitiveIndex i = 0; i < index_bound_; ++i) alive_[i] = 0;
  size_ = 0;
  free_count_ = 0;
  index_bound_ = 0;
  ++revision_;
}

}  // namespace vantage
