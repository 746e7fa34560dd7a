// Null drivers say what is missing and never pretend to work.
#include <catch2/catch.hpp>

#include <string>
#include <vector>

#include "hal/null/null_drivers.hpp"

using namespace vantage;
using namespace vantage::hal;

TEST_CASE("the null camera names what is missing and delivers no frame", "[null]") {
  NullCamera camera("built without libcamera");
  CHECK(std::string(camera.name()) == "null:no camera (built without libcamera)");
  std::vector<std::uint8_t> pixels(640 * 480, 7);
  MutableGrayImageView view{pixels.data(), 640, 480, 640};
  FrameInfo info;
  info.sequence = 42;
  CHECK(camera.grab(view, info, 10) == CaptureStatus::kNotStarted);
  CHECK(info.sequence == 42);
  CHECK(pixels[0] == 7);
}

TEST_CASE("the null vehicle refuses every command and has no pose", "[null]") {
  NullMotion motion("no autopilot link configured");
  CHECK(std::string(motion.name()) == "null:no vehicle (no autopilot link configured)");
  Viewpoint target;
  CHECK(motion.command(target) == MotionFault::kRejected);
  motion.update(0.1);
  CHECK_FALSE(motion.current_pose().valid);
  CHECK_FALSE(motion.arrived());
  CHECK(motion.fault() == MotionFault::kRejected);
}
