#pragma once
// MAVLink 2 framing: a writer that builds frames (optionally signed) in a caller's fixed buffer, and a
// bounded byte-wise parser that finds, checks and hands out frames without allocating.
//
// Frame: STX 0xFD | len | incompat | compat | seq | sysid | compid | msgid (3, LE) | payload (len) |
// crc (2, LE: CRC-16/MCRF4XX over len..payload plus the message's CRC_EXTRA) | signature (13, when
// incompat bit 0 is set). MAVLink 1 frames (STX 0xFE) are not accepted and are skipped as noise.
#include <array>
#include <cstddef>
#include <cstdint>

#include "hal/mavlink/messages.hpp"
#include "hal/mavlink/signing.hpp"

namespace vantage::hal::mavlink {

constexpr std::uint8_t kStx = 0xFD;
constexpr std::size_t kHeaderBytes = 10;  // STX included
constexpr std::size_t kChecksumBytes = 2;
constexpr std::size_t kSignatureBytes = 13;
constexpr std::size_t kMaxPayloadBytes = 255;
constexpr std::size_t kMaxFrameBytes = kHeaderBytes + kMaxPayloadBytes + kChecksumBytes + kSignatureBytes;
constexpr std::uint8_t kIncompatSigned = 0x01;

// A checked frame as handed out by FrameParser. Pointers stay valid until the parser's next call.
struct Frame {
  std::uint8_t sequence = 0;
  std::uint8_t system_id = 0;
  std::uint8_t component_id = 0;
  std::uint8_t incompat_flags = 0;
  std::uint32_t message_id = 0;
  std::uint8_t payload_length = 0;      // as on the wire (trailing zeros may be truncated)
  const std::uint8_t* payload = nullptr;  // zero-extended to kMaxPayloadBytes
  bool is_signed = false;
  std::uint8_t link_id = 0;
  std::uint64_t signing_timestamp = 0;  // 10 us ticks since 2015-01-01
  const std::uint8_t* bytes = nullptr;  // the whole frame as received
  std::size_t size_bytes = 0;
};

class FrameWriter {
 public:
  FrameWriter(std::uint8_t system_id, std::uint8_t component_id)
      : system_id_(system_id), component_id_(component_id) {}

  // Every frame written after this carries a signature with this key and link id.
  void enable_signing(const SigningKey& key, std::uint8_t link_id);

  // Builds one frame of message m into out (kMaxFrameBytes) and returns its length. The signing
  // timestamp is the larger of signing_timestamp_now() and the last one plus one.
  template <typename Message>
  std::size_t write(const Message& m, std::uint8_t* out) {
    std::array<std::uint8_t, kMaxPayloadBytes> payload{};
    const std::size_t length = encode(m, payload.data());
    return write_payload(Message::kId, payload.data(), length, out);
  }
  // The same for a raw payload (tests use it to build frames a codec does not know).
  std::size_t write_payload(std::uint32_t message_id, const std::uint8_t* payload, std::size_t length,
                            std::uint8_t* out);

  std::uint8_t next_sequence() const { return sequence_; }

 private:
  std::uint8_t system_id_;
  std::uint8_t component_id_;
  std::uint8_t sequence_ = 0;
  bool signing_ = false;
  SigningKey key_{};
  std::uint8_t link_id_ = 0;
  std::uint64_t last_timestamp_ = 0;
};

// Counters of what the parser threw away (all monotonically increasing).
struct ParserStats {
  std::uint64_t frames = 0;           // frames handed out
  std::uint64_t discarded_bytes = 0;  // bytes skipped while hunting for a frame start
  std::uint64_t crc_errors = 0;
  std::uint64_t unknown_messages = 0;  // message ids this codec does not know (skipped, CRC not checkable)
  std::uint64_t bad_lengths = 0;       // payload longer than the message allows
  std::uint64_t bad_flags = 0;         // incompatibility flags other than "signed"
};

// Byte-stream to frames. Holds at most two frames' worth of bytes; on any failure it drops one byte and
// hunts for the next STX inside what it already holds, so a truncated frame does not take the next good
// frame down with it.
class FrameParser {
 public:
  // Takes as many of the bytes as fit in the window; returns how many it took. Call next() until it
  // returns false, then write the rest.
  std::size_t write(const std::uint8_t* data, std::size_t length);
  // The next valid frame in the window; false when more bytes are needed.
  bool next(Frame* out);
  // Drops everything held (e.g. after the link was reopened).
  void reset() { head_ = tail_ = 0; }

  const ParserStats& stats() const { return stats_; }
  std::size_t buffered_bytes() const { return tail_ - head_; }

 private:
  void drop(std::size_t count, bool count_as_discarded);

  std::array<std::uint8_t, 2 * kMaxFrameBytes> window_{};
  std::size_t head_ = 0;
  std::size_t tail_ = 0;
  std::array<std::uint8_t, kMaxPayloadBytes> payload_{};
  ParserStats stats_;
};

}  // namespace vantage::hal::mavlink
