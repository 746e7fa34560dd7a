#pragma once
// ScopedTrackObserver: shows a front end's tracked observations to an observer for one scope, and
// unsets it on the way out, also when a REQUIRE inside the scope throws (the observer is usually a local
// that would otherwise be left dangling for the next test case).
#include "core/frontend/image_front_end.hpp"

namespace vantage::test {

class ScopedTrackObserver {
 public:
  ScopedTrackObserver(ImageFrontEnd& front_end, TrackObserver& observer) : front_end_(front_end) {
    front_end_.set_observer(&observer);
  }
  ~ScopedTrackObserver() { front_end_.set_observer(nullptr); }
  ScopedTrackObserver(const ScopedTrackObserver&) = delete;
  ScopedTrackObserver& operator=(const ScopedTrackObserver&) = delete;

 private:
  ImageFrontEnd& front_end_;
};

}  // namespace vantage::test
