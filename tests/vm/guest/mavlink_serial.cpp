// Guest program: the MAVLink motion driver over a real serial line. In the VM, /dev/ttyMAV0 links to
// QEMU's second UART (a 16550: ttyS1 on x86, a PCI 16550 on arm), whose host end is bridged to the
// node-mavlink vehicle peer (tests/vm/run-with-peer.sh). It exercises SerialLink's termios setup on a
// kernel tty driver, not a pty: link up, pose received, a commanded viewpoint reached. Prints PASS/FAIL
// lines (see guest-init.sh).
// usage: vm_mavlink_serial <tty> <baud>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>

#include "core/geometry/viewpoint.hpp"
#include "hal/mavlink/link.hpp"
#include "hal/mavlink/mavlink_motion.hpp"
#include "hal/steady_clock.hpp"

using namespace vantage;
using namespace vantage::hal::mavlink;

namespace {

// Updates the driver every 10 ms until done() or the timeout; true when done.
bool pump(MavlinkMotion& motion, int timeout_ms, const std::function<bool()>& done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (std::chrono::steady_clock::now() < deadline) {
    motion.update(0.01);
    if (done()) return true;
    ::usleep(10000);
  }
  return done();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::printf("FAIL mavlink_serial: usage: vm_mavlink_serial <tty> <baud>\n");
    return 2;
  }
  SerialLink link;
  const std::string error = link.open(argv[1], std::atoi(argv[2]));
  if (!error.empty()) {
    std::printf("FAIL mavlink_serial_open: %s\n", error.c_str());
    return 1;
  }
  std::printf("PASS mavlink_serial_open: %s\n", link.name());

  hal::SteadyClock clock;
  MavlinkMotionConfig config;
  MavlinkMotion motion(link, clock, config);
  motion.start();
  if (!pump(motion, 8000, [&] { return motion.link_up() && motion.current_pose().valid; })) {
    std::printf("FAIL mavlink_serial_link: no heartbeat and pose from the peer in 8 s (heartbeats %llu, crc errors %llu)\n",
                static_cast<unsigned long long>(motion.stats().heartbeats),
                static_cast<unsigned long long>(motion.parser_stats().crc_errors));
    return 1;
  }
  const Eigen::Vector3d start = motion.current_pose().pose.position_world;
  std::printf("PASS mavlink_serial_link: heartbeat and pose at world (%.2f, %.2f, %.2f)\n", start.x(), start.y(),
              start.z());

  Viewpoint target;
  if (!ok(look_at(Eigen::Vector3d(2.0, -1.0, 3.0), Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &target))) {
    std::printf("FAIL mavlink_serial_command: look_at failed\n");
    return 1;
  }
  const hal::MotionFault fault = motion.command(target);
  if (fault != hal::MotionFault::kNone) {
    std::printf("FAIL mavlink_serial_command: refused: %s\n", hal::to_string(fault));
    return 1;
  }
  if (!pump(motion, 15000, [&] { return motion.arrived(); })) {
    const Eigen::Vector3d p = motion.current_pose().pose.position_world;
    std::printf("FAIL mavlink_serial_arrive: not at the target in 15 s (at %.2f, %.2f, %.2f; fault %s)\n", p.x(),
                p.y(), p.z(), hal::to_string(motion.fault()));
    return 1;
  }
  const double error_m = (motion.current_pose().pose.position_world - target.position_world).norm();
  std::printf("PASS mavlink_serial_arrive: reached the viewpoint within %.3f m (setpoints sent %llu, crc errors %llu)\n",
              error_m, static_cast<unsigned long long>(motion.stats().setpoints_sent),
              static_cast<unsigned long long>(motion.parser_stats().crc_errors));
  if (motion.parser_stats().crc_errors != 0) {
    std::printf("FAIL mavlink_serial_clean: %llu CRC errors on the serial line\n",
                static_cast<unsigned long long>(motion.parser_stats().crc_errors));
    return 1;
  }
  return 0;
}
