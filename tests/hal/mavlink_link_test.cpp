// MavlinkMotion over a real UDP socket on 127.0.0.1 with the test playing the vehicle: a flood of
// garbage mixed with good frames costs bounded work per update(), and the good frames still get through.
#include <catch2/catch.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <random>
#include <vector>

#include "hal/mavlink/frame.hpp"
#include "hal/mavlink/link.hpp"
#include "hal/mavlink/mavlink_motion.hpp"
#include "hal/steady_clock.hpp"

using namespace vantage;
using namespace vantage::hal::mavlink;

namespace {

// A UDP socket on 127.0.0.1 standing in for the vehicle.
struct FakeVehicle {
  int fd = -1;
  sockaddr_in companion{};
  bool have_companion = false;
  FakeVehicle() {
    fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
    int size = 8 << 20;
    ::setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &size, sizeof size);
  }
  ~FakeVehicle() { ::close(fd); }
  std::uint16_t port() const {
    sockaddr_in a{};
    socklen_t n = sizeof a;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &n);
    return ntohs(a.sin_port);
  }
  // Learns the companion's address from its first datagram.
  bool listen() {
    std::uint8_t buffer[512];
    socklen_t n = sizeof companion;
    const ssize_t got = ::recvfrom(fd, buffer, sizeof buffer, 0, reinterpret_cast<sockaddr*>(&companion), &n);
    if (got > 0) have_companion = true;
    return have_companion;
  }
  void send(const std::vector<std::uint8_t>& bytes) {
    ::sendto(fd, bytes.data(), bytes.size(), 0, reinterpret_cast<const sockaddr*>(&companion), sizeof companion);
  }
};

std::vector<std::uint8_t> frame_of(FrameWriter& writer, const Heartbeat& hb) {
  std::uint8_t buffer[kMaxFrameBytes];
  const std::size_t n = writer.write(hb, buffer);
  return std::vector<std::uint8_t>(buffer, buffer + n);
}

// A MavlinkMotion on a UDP link to a FakeVehicle.
struct VehicleOnUdp {
  FakeVehicle vehicle;
  UdpLink link;
  hal::SteadyClock clock;
  MavlinkMotionConfig config;
  MavlinkMotion motion{link, clock, config};

  // Opens the link, starts the motion driver and waits until the vehicle has heard the companion.
  bool connect() {
    if (!link.open("127.0.0.1", vehicle.port()).empty()) return false;
    motion.start();
    for (int i = 0; i < 100 && !vehicle.listen(); ++i) ::usleep(1000);
    return vehicle.have_companion;
  }
};

}  // namespace

TEST_CASE("a UDP flood of garbage costs bounded work per update and good frames get through", "[mavlink][flood]") {
  VehicleOnUdp setup;
  REQUIRE(setup.connect());
  FakeVehicle& vehicle = setup.vehicle;
  MavlinkMotion& motion = setup.motion;

  FrameWriter writer(1, 1);
  Heartbeat hb;
  hb.type = 2;
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255);
  // 2000 datagrams of 1400 random bytes (many start bytes), one good heartbeat after every 200.
  std::size_t sent_heartbeats = 0;
  for (int d = 0; d < 2000; ++d) {
    std::vector<std::uint8_t> garbage(1400);
    for (auto& b : garbage) b = static_cast<std::uint8_t>(byte(rng));
    for (std::size_t i = 0; i < garbage.size(); i += 11) garbage[i] = kStx;
    vehicle.send(garbage);
    if (d % 200 == 199) {
      vehicle.send(frame_of(writer, hb));
      ++sent_heartbeats;
    }
  }
  // Every update takes at most kMaxBytesPerUpdate bytes: count updates until the socket is drained.
  int updates = 0;
  while (motion.stats().heartbeats < sent_heartbeats && updates < 1000) {
    motion.update(0.0);
    ++updates;
  }
  // Heartbeats that the kernel dropped with the excess never arrive; those that arrived are all parsed.
  CHECK(motion.stats().heartbeats >= 1);
  CHECK(updates >= 2);  // 2.8 MB cannot be taken in one update
  CHECK(motion.parser_stats().discarded_bytes > 100000);
  CHECK(motion.stats().link_errors == 0);
  // Once drained, a fresh heartbeat is seen at the next update.
  for (int i = 0; i < 50; ++i) motion.update(0.0);
  const std::uint64_t before = motion.stats().heartbeats;
  vehicle.send(frame_of(writer, hb));
  for (int i = 0; i < 100 && motion.stats().heartbeats == before; ++i) {
    ::usleep(1000);
    motion.update(0.0);
  }
  CHECK(motion.stats().heartbeats == before + 1);
  CHECK(motion.link_up());
}

TEST_CASE("datagrams from another address are ignored", "[mavlink]") {
  VehicleOnUdp setup;
  REQUIRE(setup.connect());
  FakeVehicle& vehicle = setup.vehicle;
  MavlinkMotion& motion = setup.motion;
  FakeVehicle intruder;
  intruder.companion = vehicle.companion;
  intruder.have_companion = true;
  FrameWriter writer(1, 1);
  Heartbeat hb;
  intruder.send(frame_of(writer, hb));
  for (int i = 0; i < 20; ++i) {
    ::usleep(1000);
    motion.update(0.0);
  }
  CHECK(motion.stats().heartbeats == 0);
  vehicle.send(frame_of(writer, hb));
  for (int i = 0; i < 100 && motion.stats().heartbeats == 0; ++i) {
    ::usleep(1000);
    motion.update(0.0);
  }
  CHECK(motion.stats().heartbeats == 1);
}

TEST_CASE("endpoints parse or say what is wrong", "[mavlink]") {
  Endpoint e;
  REQUIRE(parse_endpoint("udp:127.0.0.1:14540", &e) == "");
  CHECK(e.kind == Endpoint::Kind::kUdp);
  CHECK(e.host_or_path == "127.0.0.1");
  CHECK(e.port_or_baud == 14540);
  REQUIRE(parse_endpoint("serial:/dev/ttyAMA0:921600", &e) == "");
  CHECK(e.kind == Endpoint::Kind::kSerial);
  CHECK(e.host_or_path == "/dev/ttyAMA0");
  CHECK(parse_endpoint("udp:127.0.0.1", &e) == "endpoint 'udp:127.0.0.1' is not udp:HOST:PORT or serial:PATH:BAUD");
  CHECK(parse_endpoint("udp:127.0.0.1:70000", &e) == "endpoint 'udp:127.0.0.1:70000': port out of range");
  CHECK(parse_endpoint("tcp:127.0.0.1:5760", &e) == "endpoint 'tcp:127.0.0.1:5760': kind 'tcp' is not udp or serial");
  UdpLink udp;
  CHECK(udp.open("localhost", 14540) == "udp: 'localhost' is not an IPv4 address");
  SerialLink serial;
  CHECK(serial.open("/dev/null", 57600).find("serial: /dev/null is not a terminal device") == 0);
  CHECK(serial.open("/dev/ttyVANTAGE-absent", 57600) == "serial: /dev/ttyVANTAGE-absent: No such file or directory");
  CHECK(serial.open("/dev/null", 12345) == "serial: unsupported baud rate 12345");
}
