// MAVLink 2 codec, framing, parser and signing, without a peer.
#include <catch2/catch.hpp>

#include <cstring>
#include <random>
#include <vector>

#include "hal/mavlink/crc16.hpp"
#include "hal/mavlink/frame.hpp"
#include "hal/mavlink/messages.hpp"
#include "tests/support/no_allocation.hpp"

using namespace vantage::hal::mavlink;

namespace {

std::vector<Frame> parse_all(FrameParser& parser, const std::vector<std::uint8_t>& bytes,
                             std::vector<std::vector<std::uint8_t>>* payloads = nullptr) {
  std::vector<Frame> frames;
  std::size_t offset = 0;
  while (offset < bytes.size()) {
    offset += parser.write(bytes.data() + offset, bytes.size() - offset);
    Frame frame;
    while (parser.next(&frame)) {
      frames.push_back(frame);
      if (payloads != nullptr) payloads->emplace_back(frame.payload, frame.payload + 255);
    }
  }
  return frames;
}

template <typename Message>
std::vector<std::uint8_t> frame_bytes(FrameWriter& writer, const Message& message) {
  std::uint8_t buffer[kMaxFrameBytes];
  const std::size_t size = writer.write(message, buffer);
  return std::vector<std::uint8_t>(buffer, buffer + size);
}

}  // namespace

TEST_CASE("crc16 is CRC-16/MCRF4XX", "[mavlink]") {
  // The catalogue check value of CRC-16/MCRF4XX over "123456789".
  const char* text = "123456789";
  REQUIRE(crc16(reinterpret_cast<const std::uint8_t*>(text), 9) == 0x6F91);
}

TEST_CASE("crc extras and lengths match the common dialect", "[mavlink]") {
  struct Expected { std::uint32_t id; std::uint8_t crc_extra; std::uint8_t base; std::uint8_t max; };
  const Expected expected[] = {{0, 50, 9, 9},     {84, 143, 53, 53}, {85, 140, 51, 51}, {32, 185, 28, 28},
                               {30, 39, 28, 28},  {331, 91, 230, 233}, {76, 152, 33, 33}, {77, 143, 3, 10}};
  for (const Expected& e : expected) {
    const MessageSpec* spec = find_message_spec(e.id);
    REQUIRE(spec != nullptr);
    CHECK(spec->crc_extra == e.crc_extra);
    CHECK(spec->base_length == e.base);
    CHECK(spec->max_length == e.max);
  }
  REQUIRE(find_message_spec(1) == nullptr);
}

TEST_CASE("a heartbeat frame has the MAVLink 2 layout", "[mavlink]") {
  FrameWriter writer(1, 191);
  Heartbeat hb;
  hb.type = 18;
  hb.autopilot = 8;
  hb.system_status = 4;
  const auto bytes = frame_bytes(writer, hb);
  REQUIRE(bytes.size() == 10 + 9 + 2);
  CHECK(bytes[0] == 0xFD);
  CHECK(bytes[1] == 9);
  CHECK(bytes[2] == 0);
  CHECK(bytes[4] == 0);  // first sequence number
  CHECK(bytes[5] == 1);
  CHECK(bytes[6] == 191);
  CHECK(bytes[7] == 0);
  CHECK(bytes[10 + 4] == 18);
  CHECK(bytes[10 + 8] == 3);
  std::uint16_t crc = crc16(bytes.data() + 1, 9 + 9);
  crc = crc16_accumulate(50, crc);
  CHECK(bytes[19] == (crc & 0xFF));
  CHECK(bytes[20] == (crc >> 8));
}

TEST_CASE("trailing zero payload bytes are truncated and restored", "[mavlink]") {
  FrameWriter writer(1, 191);
  CommandAck ack;
  ack.command = 511;
  ack.result = 0;
  const auto bytes = frame_bytes(writer, ack);
  CHECK(bytes[1] == 2);  // only the command survives; result 0 and the extensions are zeros
  FrameParser parser;
  const auto frames = parse_all(parser, bytes);
  REQUIRE(frames.size() == 1);
  CommandAck decoded;
  decode(frames[0].payload, &decoded);
  CHECK(decoded.command == 511);
  CHECK(decoded.result == 0);
}

TEST_CASE("every message round-trips through writer and parser", "[mavlink]") {
  FrameWriter writer(1, 1);
  FrameParser parser;
  SetPositionTargetLocalNed sp;
  sp.time_boot_ms = 123456;
  sp.x = 1.5f; sp.y = -2.25f; sp.z = -3.0f; sp.yaw = 0.75f;
  sp.type_mask = kIgnoreVelocity | kIgnoreAcceleration | kIgnoreYawRate;
  sp.target_system = 1; sp.target_component = 1;
  Odometry odo;
  odo.time_usec = 0x0102030405060708ull;
  odo.x = 4; odo.y = 5; odo.z = -6;
  odo.q = {0.5f, 0.5f, -0.5f, 0.5f};
  odo.pose_covariance[20] = 7.0f;
  odo.quality = -3;
  Attitude att;
  att.yaw = -1.25f;
  att.rollspeed = 0.5f;
  LocalPositionNed lp;
  lp.x = 9; lp.vz = -0.5f;
  CommandLong cmd;
  cmd.param = {1, 2, 3, 4, 5, 6, 7};
  cmd.command = 17;
  cmd.confirmation = 2;
  PositionTargetLocalNed pt;
  pt.x = 3; pt.type_mask = 0x0DF8; pt.coordinate_frame = 1;

  std::vector<std::uint8_t> stream;
  for (const auto& part : {frame_bytes(writer, sp), frame_bytes(writer, odo), frame_bytes(writer, att),
                           frame_bytes(writer, lp), frame_bytes(writer, cmd), frame_bytes(writer, pt)}) {
    stream.insert(stream.end(), part.begin(), part.end());
  }
  std::vector<std::vector<std::uint8_t>> payloads;
  const auto frames = parse_all(parser, stream, &payloads);
  REQUIRE(frames.size() == 6);
  for (std::size_t i = 0; i < frames.size(); ++i) CHECK(frames[i].sequence == i);

  SetPositionTargetLocalNed sp2;
  decode(payloads[0].data(), &sp2);
  CHECK(sp2.time_boot_ms == 123456);
  CHECK(sp2.x == 1.5f);
  CHECK(sp2.y == -2.25f);
  CHECK(sp2.z == -3.0f);
  CHECK(sp2.yaw == 0.75f);
  CHECK(sp2.type_mask == sp.type_mask);
  CHECK(sp2.coordinate_frame == 1);
  Odometry odo2;
  decode(payloads[1].data(), &odo2);
  CHECK(odo2.time_usec == odo.time_usec);
  CHECK(odo2.q == odo.q);
  CHECK(odo2.pose_covariance[20] == 7.0f);
  CHECK(odo2.frame_id == 1);
  CHECK(odo2.child_frame_id == 12);
  CHECK(odo2.quality == -3);
  Attitude att2;
  decode(payloads[2].data(), &att2);
  CHECK(att2.yaw == -1.25f);
  CHECK(att2.rollspeed == 0.5f);
  LocalPositionNed lp2;
  decode(payloads[3].data(), &lp2);
  CHECK(lp2.x == 9.0f);
  CHECK(lp2.vz == -0.5f);
  CommandLong cmd2;
  decode(payloads[4].data(), &cmd2);
  CHECK(cmd2.param == cmd.param);
  CHECK(cmd2.command == 17);
  CHECK(cmd2.confirmation == 2);
  PositionTargetLocalNed pt2;
  decode(payloads[5].data(), &pt2);
  CHECK(pt2.x == 3.0f);
  CHECK(pt2.type_mask == 0x0DF8);
}

TEST_CASE("wrong crc, truncated, bad length and bad flags are rejected without losing good frames", "[mavlink]") {
  FrameWriter writer(1, 1);
  Heartbeat hb;
  hb.type = 2;
  const auto good = frame_bytes(writer, hb);
  auto bad_crc = good;
  bad_crc[good.size() - 1] ^= 0x01;
  const std::vector<std::uint8_t> truncated(good.begin(), good.begin() + 12);
  auto bad_length = good;
  bad_length[1] = 100;  // heartbeat is at most 9 bytes
  auto bad_flags = good;
  bad_flags[2] = 0x02;
  auto unknown = good;
  unknown[7] = 1;  // SYS_STATUS: not in this codec

  std::vector<std::uint8_t> stream;
  const std::vector<const std::vector<std::uint8_t>*> parts = {&bad_crc, &good, &truncated, &good, &bad_length, &good, &bad_flags, &good, &unknown, &good};
  for (const std::vector<std::uint8_t>* part : parts) {
    stream.insert(stream.end(), part->begin(), part->end());
  }
  FrameParser parser;
  const auto frames = parse_all(parser, stream);
  CHECK(frames.size() == 5);
  CHECK(parser.stats().crc_errors == 2);  // the wrong CRC, and the truncated frame completed by the next
  CHECK(parser.stats().bad_lengths == 1);
  CHECK(parser.stats().bad_flags == 1);
  CHECK(parser.stats().unknown_messages == 1);
}

TEST_CASE("an oversized payload for a known message is a bad length", "[mavlink]") {
  FrameWriter writer(1, 1);
  std::uint8_t payload[20] = {};
  payload[19] = 1;
  std::uint8_t buffer[kMaxFrameBytes];
  const std::size_t size = writer.write_payload(kHeartbeatId, payload, sizeof payload, buffer);
  FrameParser parser;
  std::vector<std::uint8_t> stream(buffer, buffer + size);
  const auto frames = parse_all(parser, stream);
  CHECK(frames.empty());
  CHECK(parser.stats().bad_lengths == 1);
}

TEST_CASE("random garbage never yields a frame and never grows the parser", "[mavlink]") {
  std::mt19937 rng(1234);
  std::uniform_int_distribution<int> byte(0, 255);
  std::vector<std::uint8_t> garbage(1 << 20);
  for (auto& b : garbage) b = static_cast<std::uint8_t>(byte(rng));
  // Many start bytes make the parser work hardest.
  for (std::size_t i = 0; i < garbage.size(); i += 7) garbage[i] = kStx;
  FrameParser parser;
  std::size_t frames = 0;
  REQUIRE_NO_ALLOCATION({
    std::size_t offset = 0;
    while (offset < garbage.size()) {
      offset += parser.write(garbage.data() + offset, garbage.size() - offset);
      Frame frame;
      while (parser.next(&frame)) ++frames;
      REQUIRE(parser.buffered_bytes() <= 2 * kMaxFrameBytes);
    }
  });
  // A 16-bit CRC lets about one random candidate in 65536 through; 1 MiB of noise has far fewer
  // candidates with a known id and a valid length, so any frame here would be a parser bug.
  CHECK(frames == 0);
}

TEST_CASE("a flood of good frames parses without allocating", "[mavlink]") {
  FrameWriter writer(1, 1);
  LocalPositionNed lp;
  lp.x = 1;
  const auto one = frame_bytes(writer, lp);
  std::vector<std::uint8_t> flood;
  for (int i = 0; i < 20000; ++i) flood.insert(flood.end(), one.begin(), one.end());
  FrameParser parser;
  std::size_t frames = 0;
  REQUIRE_NO_ALLOCATION({
    std::size_t offset = 0;
    while (offset < flood.size()) {
      offset += parser.write(flood.data() + offset, flood.size() - offset);
      Frame frame;
      while (parser.next(&frame)) ++frames;
    }
  });
  CHECK(frames == 20000);
}

TEST_CASE("signed frames verify with the right key only", "[mavlink][signing]") {
  SigningKey key{};
  for (std::size_t i = 0; i < key.size(); ++i) key[i] = static_cast<std::uint8_t>(i * 7 + 1);
  SigningKey wrong = key;
  wrong[0] ^= 0xFF;
  FrameWriter writer(1, 1);
  writer.enable_signing(key, 3);
  Heartbeat hb;
  const auto bytes = frame_bytes(writer, hb);
  REQUIRE(bytes.size() == 10 + 9 + 2 + 13);
  CHECK((bytes[2] & kIncompatSigned) != 0);
  FrameParser parser;
  std::vector<std::uint8_t> copy = bytes;
  auto frames = parse_all(parser, copy);
  REQUIRE(frames.size() == 1);
  CHECK(frames[0].is_signed);
  CHECK(frames[0].link_id == 3);
  const std::uint64_t now = signing_timestamp_now();
  CHECK(frames[0].signing_timestamp <= now);
  CHECK(frames[0].signing_timestamp + 100000 > now);

  SignatureVerifier right_verifier(key);
  SignatureVerifier wrong_verifier(wrong);
  CHECK(wrong_verifier.check(frames[0], now) == SignatureVerdict::kBadSignature);
  CHECK(right_verifier.check(frames[0], now) == SignatureVerdict::kAccepted);
  // The same frame again is a replay.
  CHECK(right_verifier.check(frames[0], now) == SignatureVerdict::kReplay);
}

TEST_CASE("signature replay and stale rules", "[mavlink][signing]") {
  SigningKey key{};
  key.fill(0x42);
  FrameWriter writer(1, 1);
  writer.enable_signing(key, 0);
  Heartbeat hb;
  const auto first = frame_bytes(writer, hb);
  const auto second = frame_bytes(writer, hb);
  FrameParser parser;
  std::vector<std::uint8_t> stream = first;
  stream.insert(stream.end(), second.begin(), second.end());
  std::vector<std::uint8_t> raw_first(first), raw_second(second);
  const auto frames = parse_all(parser, stream);
  REQUIRE(frames.size() == 2);
  CHECK(frames[1].signing_timestamp > frames[0].signing_timestamp);

  // Check from copies (the parser's pointers are only good until its next call).
  FrameParser p1, p2;
  const auto f1 = parse_all(p1, raw_first);
  const auto f2 = parse_all(p2, raw_second);
  const std::uint64_t now = signing_timestamp_now();
  SignatureVerifier verifier(key);
  CHECK(verifier.check(f2[0], now) == SignatureVerdict::kAccepted);
  CHECK(verifier.check(f1[0], now) == SignatureVerdict::kReplay);  // older than the last one

  SignatureVerifier late(key);
  CHECK(late.check(f1[0], now + 2 * SignatureVerifier::kStaleTicks) == SignatureVerdict::kStale);

  FrameWriter plain(1, 1);
  const auto unsigned_bytes = frame_bytes(plain, hb);
  FrameParser p3;
  std::vector<std::uint8_t> copy = unsigned_bytes;
  const auto f3 = parse_all(p3, copy);
  CHECK(verifier.check(f3[0], now) == SignatureVerdict::kUnsigned);

  // Altering a payload byte (and fixing the CRC so the parser accepts it) breaks the signature.
  std::vector<std::uint8_t> altered = raw_second;
  altered[10 + 4] ^= 0x01;
  std::uint16_t crc = crc16(altered.data() + 1, 9 + altered[1]);
  crc = crc16_accumulate(50, crc);
  altered[10 + altered[1]] = static_cast<std::uint8_t>(crc);
  altered[11 + altered[1]] = static_cast<std::uint8_t>(crc >> 8);
  FrameParser p4;
  const auto f4 = parse_all(p4, altered);
  REQUIRE(f4.size() == 1);
  SignatureVerifier fresh(key);
  CHECK(fresh.check(f4[0], now) == SignatureVerdict::kBadSignature);
}
