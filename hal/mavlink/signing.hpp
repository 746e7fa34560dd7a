#pragma once
// MAVLink 2 message signing: a 13-byte trailer (link id, 48-bit timestamp in 10 us units since
// 2015-01-01 00:00:00 UTC, and the first 6 bytes of SHA-256(key | header | payload | crc | link id |
// timestamp)). SHA-256 comes from OpenSSL. Replay protection follows the MAVLink signing rules: per
// (system, component, link) stream a timestamp must strictly increase, and a new stream must not be
// more than a minute older than the newest timestamp seen or the local clock.
#include <array>
#include <cstddef>
#include <cstdint>

namespace vantage::hal::mavlink {

constexpr std::size_t kSigningKeyBytes = 32;
using SigningKey = std::array<std::uint8_t, kSigningKeyBytes>;

// 10 us ticks since 2015-01-01 from the real-time clock (what signing timestamps count).
std::uint64_t signing_timestamp_now();

// Writes the 6-byte signature for frame[0 .. length_without_signature + 7) (that is: the frame up to and
// including link id and timestamp) into out.
void compute_signature(const SigningKey& key, const std::uint8_t* frame, std::size_t signed_bytes,
                       std::uint8_t out[6]);

enum class SignatureVerdict : std::uint8_t {
  kAccepted = 0,
  kUnsigned,      // signing is required and the frame carries no signature
  kBadSignature,  // wrong key or altered frame
  kReplay,        // timestamp not newer than the stream's last one
  kStale,         // new stream whose timestamp is more than a minute old
  kTooManyStreams,
};
const char* to_string(SignatureVerdict verdict);

struct Frame;

// Checks signed frames against one key. Fixed table of streams; never allocates.
class SignatureVerifier {
 public:
  static constexpr std::size_t kMaxStreams = 16;
  static constexpr std::uint64_t kStaleTicks = 6'000'000;  // one minute in 10 us ticks

  explicit SignatureVerifier(const SigningKey& key) : key_(key) {}
  // local_now: signing_timestamp_now() (a parameter so tests can pin it).
  SignatureVerdict check(const Frame& frame, std::uint64_t local_now);

 private:
  struct Stream {
    std::uint8_t system_id = 0;
    std::uint8_t component_id = 0;
    std::uint8_t link_id = 0;
    std::uint64_t last_timestamp = 0;
  };
  SigningKey key_;
  std::array<Stream, kMaxStreams> streams_{};
  std::size_t stream_count_ = 0;
  std::uint64_t newest_timestamp_ = 0;
};

}  // namespace vantage::hal::mavlink
