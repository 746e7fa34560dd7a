// hal/mavlink against node-mavlink (an independent MAVLink 2 implementation) over UDP on 127.0.0.1.
#include <catch2/catch.hpp>

#include <chrono>
#include <cmath>
#include <functional>
#include <unistd.h>
#include <string>

#include "core/geometry/viewpoint.hpp"
#include "hal/mavlink/frame.hpp"
#include "hal/mavlink/link.hpp"
#include "hal/mavlink/mavlink_motion.hpp"
#include "hal/steady_clock.hpp"
#include "tests/hal/support/peer_process.hpp"

using namespace vantage;
using namespace vantage::hal::mavlink;
using vantage::test::json_has;
using vantage::test::json_number;
using vantage::test::PeerProcess;

namespace {

const char* kKeyHex = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";

SigningKey key_from_hex(const std::string& hex) {
  SigningKey key{};
  for (std::size_t i = 0; i < key.size(); ++i) key[i] = static_cast<std::uint8_t>(std::stoi(hex.substr(2 * i, 2), nullptr, 16));
  return key;
}

// Updates the driver every 10 ms and collects the peer's lines until done() or the timeout.
bool pump(MavlinkMotion& motion, PeerProcess& peer, int timeout_ms, const std::function<bool()>& done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (std::chrono::steady_clock::now() < deadline) {
    motion.update(0.01);
    if (done()) return true;
    std::string line;
    peer.read_line(&line, 10);
  }
  return done();
}

bool peer_said(const PeerProcess& peer, const std::function<bool(const std::string&)>& match) {
  for (const std::string& line : peer.lines()) {
    if (match(line)) return true;
  }
  return false;
}

struct Rig {
  PeerProcess peer;
  UdpLink link;
  hal::SteadyClock clock;
  MavlinkMotionConfig config;

  std::string start(const std::vector<std::string>& peer_args) {
    const std::string error = peer.start(peer_args);
    if (!error.empty()) return error;
    return link.open("127.0.0.1", peer.port());
  }
};

}  // namespace

TEST_CASE("heartbeats, pose and commands interoperate with node-mavlink both ways", "[mavlink_peer]") {
  Rig rig;
  REQUIRE(rig.start({"--duration-s", "6", "--start-ned", "1,2,-3"}) == "");
  MavlinkMotion motion(rig.link, rig.clock, rig.config);
  motion.start();
  const bool up = pump(motion, rig.peer, 4000, [&] {
    return motion.link_up() && motion.current_pose().valid && motion.stats().commands_acked >= 2;
  });
  INFO("parser crc errors " << motion.parser_stats().crc_errors);
  REQUIRE(up);
  // Their frames decode in our parser: the pose is the peer's start (NED 1,2,-3 -> world E=2, N=1, U=3).
  const Eigen::Vector3d p = motion.current_pose().pose.position_world;
  CHECK(p.x() == Approx(2.0).margin(1e-5));
  CHECK(p.y() == Approx(1.0).margin(1e-5));
  CHECK(p.z() == Approx(3.0).margin(1e-5));
  CHECK(motion.parser_stats().crc_errors == 0);
  // Our frames decode in node-mavlink (which checks the CRC): heartbeat fields and the stream requests.
  CHECK(peer_said(rig.peer, [](const std::string& l) {
    return json_has(l, "\"msg\":\"HEARTBEAT\"") && json_number(l, "sysid") == 1 && json_number(l, "compid") == 191 &&
           json_number(l, "type") == 18 && json_number(l, "autopilot") == 8 && json_number(l, "mavlink_version") == 3 &&
           json_has(l, "\"v2\":true");
  }));
  CHECK(peer_said(rig.peer, [](const std::string& l) {
    return json_has(l, "\"msg\":\"COMMAND_LONG\"") && json_number(l, "command") == 511 && json_number(l, "param1") == 32 &&
           json_number(l, "param2") == 50000 && json_number(l, "target_system") == 1;
  }));
}

TEST_CASE("a commanded viewpoint is sent as a NED setpoint and the vehicle converges to it", "[mavlink_peer]") {
  Rig rig;
  REQUIRE(rig.start({"--duration-s", "8", "--speed-mps", "4", "--start-ned", "0,0,-2"}) == "");
  rig.config.frame.world_origin_ned = Eigen::Vector3d(0.5, -0.5, 0.0);
  MavlinkMotion motion(rig.link, rig.clock, rig.config);
  motion.start();
  REQUIRE(pump(motion, rig.peer, 4000, [&] { return motion.link_up() && motion.current_pose().valid; }));

  Viewpoint target;
  REQUIRE(ok(look_at(Eigen::Vector3d(3.0, -4.0, 5.0), Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &target)));
  REQUIRE(motion.command(target) == hal::MotionFault::kNone);
  const bool arrived = pump(motion, rig.peer, 6000, [&] { return motion.arrived(); });
  REQUIRE(arrived);
  // The setpoint node-mavlink decoded: NED = origin + (y, x, -z) = (0.5-4, -0.5+3, -5); heading toward
  // the origin; only position and yaw are used.
  double yaw = 0, tilt = 0;
  REQUIRE(heading_and_tilt(target, &yaw, &tilt));
  CHECK(peer_said(rig.peer, [&](const std::string& l) {
    return json_has(l, "SET_POSITION_TARGET_LOCAL_NED") && std::fabs(json_number(l, "x") + 3.5) < 1e-5 &&
           std::fabs(json_number(l, "y") - 2.5) < 1e-5 && std::fabs(json_number(l, "z") + 5.0) < 1e-5 &&
           std::fabs(json_number(l, "yaw") - yaw) < 1e-5 && json_number(l, "type_mask") == 0x09F8 &&
           json_number(l, "frame") == 1 && json_number(l, "target_system") == 1 && json_number(l, "target_component") == 1;
  }));
  const hal::PoseReport pose = motion.current_pose();
  CHECK((pose.pose.position_world - target.position_world).norm() < rig.config.arrive_tolerance_m);
  // The reported camera looks where the commanded one did (heading from the vehicle, tilt as commanded).
  CHECK(pose.pose.R_world_cam.col(2).dot(target.R_world_cam.col(2)) > std::cos(0.06));
}

TEST_CASE("silence from the vehicle is link loss: fault, hold, commands refused", "[mavlink_peer]") {
  Rig rig;
  REQUIRE(rig.start({"--duration-s", "6", "--silent-after-s", "1.2", "--start-ned", "1,1,-2"}) == "");
  rig.config.heartbeat_period_s = 0.5;
  rig.config.link_loss_timeout_s = 1.5;
  MavlinkMotion motion(rig.link, rig.clock, rig.config);
  motion.start();
  REQUIRE(pump(motion, rig.peer, 1100, [&] { return motion.link_up() && motion.current_pose().valid; }));
  Viewpoint target;
  REQUIRE(ok(look_at(Eigen::Vector3d(9.0, 9.0, 2.0), Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), &target)));
  REQUIRE(motion.command(target) == hal::MotionFault::kNone);
  REQUIRE(pump(motion, rig.peer, 4000, [&] { return motion.fault() == hal::MotionFault::kLinkLost; }));
  CHECK(motion.stats().link_losses == 1);
  CHECK(motion.holding());
  // Hold = the last reported position, not the stale target.
  const Eigen::Vector3d last_world = motion.current_pose().pose.position_world;
  CHECK((rig.config.frame.world_from_ned(motion.setpoint_ned()) - last_world).norm() < 1e-6);
  CHECK((last_world - target.position_world).norm() > 1.0);
  CHECK(motion.command(target) == hal::MotionFault::kLinkLost);
  CHECK_FALSE(motion.arrived());
}

TEST_CASE("no vehicle at all is link loss after the timeout", "[mavlink_peer]") {
  UdpLink link;
  REQUIRE(link.open("127.0.0.1", 9) == "");  // discard port: nobody answers
  hal::SteadyClock clock;
  MavlinkMotionConfig config;
  config.heartbeat_period_s = 0.2;
  config.link_loss_timeout_s = 0.5;
  MavlinkMotion motion(link, clock, config);
  motion.start();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (motion.fault() == hal::MotionFault::kNone && std::chrono::steady_clock::now() < deadline) {
    motion.update(0.01);
    ::usleep(10000);
  }
  CHECK(motion.fault() == hal::MotionFault::kLinkLost);
  CHECK_FALSE(motion.current_pose().valid);
}

TEST_CASE("malformed, truncated and wrong-crc frames from the peer are rejected, good ones kept", "[mavlink_peer]") {
  Rig rig;
  REQUIRE(rig.start({"--duration-s", "6", "--bad-frames"}) == "");
  MavlinkMotion motion(rig.link, rig.clock, rig.config);
  motion.start();
  REQUIRE(pump(motion, rig.peer, 4500, [&] { return motion.stats().heartbeats >= 3; }));
  const ParserStats& stats = motion.parser_stats();
  CHECK(stats.crc_errors >= 4);   // a wrong CRC and a truncated frame per second
  CHECK(stats.bad_lengths >= 2);  // a heartbeat claiming 200 bytes per second
  CHECK(stats.discarded_bytes > 0);
  CHECK(motion.current_pose().valid);
  CHECK(motion.link_up());
}

TEST_CASE("ODOMETRY alone gives the pose", "[mavlink_peer]") {
  Rig rig;
  REQUIRE(rig.start({"--duration-s", "5", "--odometry", "--start-ned", "4,-1,-6"}) == "");
  MavlinkMotion motion(rig.link, rig.clock, rig.config);
  motion.start();
  REQUIRE(pump(motion, rig.peer, 4000, [&] { return motion.current_pose().valid; }));
  const Eigen::Vector3d p = motion.current_pose().pose.position_world;
  CHECK(p.x() == Approx(-1.0).margin(1e-5));
  CHECK(p.y() == Approx(4.0).margin(1e-5));
  CHECK(p.z() == Approx(6.0).margin(1e-5));
}

TEST_CASE("signing with the right key works both ways", "[mavlink_peer][signing]") {
  Rig rig;
  REQUIRE(rig.start({"--duration-s", "6", "--key-hex", kKeyHex}) == "");
  rig.config.signing = true;
  rig.config.signing_key = key_from_hex(kKeyHex);
  MavlinkMotion motion(rig.link, rig.clock, rig.config);
  motion.start();
  REQUIRE(pump(motion, rig.peer, 4000, [&] { return motion.link_up() && motion.current_pose().valid; }));
  CHECK(motion.stats().signature_rejected == 0);
  CHECK(motion.stats().replay_rejected == 0);
  CHECK(peer_said(rig.peer, [](const std::string& l) {
    return json_has(l, "\"msg\":\"HEARTBEAT\"") && json_has(l, "\"signed\":true");
  }));
  CHECK_FALSE(peer_said(rig.peer, [](const std::string& l) { return json_has(l, "rx_bad_signature"); }));
}

TEST_CASE("signing with a wrong key rejects everything both ways", "[mavlink_peer][signing]") {
  Rig rig;
  REQUIRE(rig.start({"--duration-s", "5", "--key-hex", kKeyHex}) == "");
  rig.config.signing = true;
  rig.config.signing_key = key_from_hex(kKeyHex);
  rig.config.signing_key[31] ^= 0x80;
  MavlinkMotion motion(rig.link, rig.clock, rig.config);
  motion.start();
  pump(motion, rig.peer, 2500, [] { return false; });
  CHECK_FALSE(motion.link_up());
  CHECK_FALSE(motion.current_pose().valid);
  CHECK(motion.stats().signature_rejected >= 2);
  CHECK(peer_said(rig.peer, [](const std::string& l) { return json_has(l, "rx_bad_signature"); }));
}

TEST_CASE("an unsigned vehicle is refused when signing is required", "[mavlink_peer][signing]") {
  Rig rig;
  REQUIRE(rig.start({"--duration-s", "5"}) == "");
  rig.config.signing = true;
  rig.config.signing_key = key_from_hex(kKeyHex);
  MavlinkMotion motion(rig.link, rig.clock, rig.config);
  motion.start();
  pump(motion, rig.peer, 2500, [] { return false; });
  CHECK_FALSE(motion.link_up());
  CHECK(motion.stats().unsigned_rejected >= 2);
}

TEST_CASE("replayed signed frames from the peer are rejected", "[mavlink_peer][signing]") {
  PeerProcess peer;
  REQUIRE(peer.start({"--duration-s", "5", "--key-hex", kKeyHex}) == "");
  UdpLink link;
  REQUIRE(link.open("127.0.0.1", peer.port()) == "");
  const SigningKey key = key_from_hex(kKeyHex);
  FrameWriter writer(1, 191);
  writer.enable_signing(key, 1);
  std::uint8_t tx[kMaxFrameBytes];
  Heartbeat hb;
  hb.type = 18;
  const std::size_t size = writer.write(hb, tx);
  REQUIRE(link.send(tx, size));
  // Capture one signed datagram from the peer.
  std::vector<std::uint8_t> captured;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  std::uint8_t rx[2048];
  while (captured.empty() && std::chrono::steady_clock::now() < deadline) {
    const long n = link.receive(rx, sizeof rx);
    if (n > 0) captured.assign(rx, rx + n);
    else ::usleep(5000);
  }
  REQUIRE_FALSE(captured.empty());
  SignatureVerifier verifier(key);
  auto verdict_of = [&](const std::vector<std::uint8_t>& bytes) {
    FrameParser parser;
    REQUIRE(parser.write(bytes.data(), bytes.size()) == bytes.size());
    Frame frame;
    REQUIRE(parser.next(&frame));
    return verifier.check(frame, signing_timestamp_now());
  };
  CHECK(verdict_of(captured) == SignatureVerdict::kAccepted);
  CHECK(verdict_of(captured) == SignatureVerdict::kReplay);
}
