#include "hal/mavlink/signing.hpp"

#include <openssl/sha.h>

#include <cstring>
#include <ctime>

#include "hal/mavlink/frame.hpp"

namespace vantage::hal::mavlink {
namespace {
constexpr std::int64_t kUnixSecondsAt2015 = 1420070400;  // 2015-01-01T00:00:00Z
}

std::uint64_t signing_timestamp_now() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  const std::int64_t seconds = static_cast<std::int64_t>(now.tv_sec) - kUnixSecondsAt2015;
  if (seconds < 0) return 0;
  return static_cast<std::uint64_t>(seconds) * 100'000u + static_cast<std::uint64_t>(now.tv_nsec / 10'000);
}

void compute_signature(const SigningKey& key, const std::uint8_t* frame, std::size_t signed_bytes,
                       std::uint8_t out[6]) {
  // key | frame bytes up to the signature; fixed scratch, one SHA-256 call.
  std::uint8_t buffer[kSigningKeyBytes + kMaxFrameBytes];
  if (signed_bytes > kMaxFrameBytes) signed_bytes = kMaxFrameBytes;
  std::memcpy(buffer, key.data(), kSigningKeyBytes);
  std::memcpy(buffer + kSigningKeyBytes, frame, signed_bytes);
  std::uint8_t digest[SHA256_DIGEST_LENGTH];
  SHA256(buffer, kSigningKeyBytes + signed_bytes, digest);
  std::memcpy(out, digest, 6);
}

const char* to_string(SignatureVerdict verdict) {
  switch (verdict) {
    case SignatureVerdict::kAccepted: return "accepted";
    case SignatureVerdict::kUnsigned: return "unsigned frame while signing is required";
    case SignatureVerdict::kBadSignature: return "bad signature (wrong key or altered frame)";
    case SignatureVerdict::kReplay: return "replayed signing timestamp";
    case SignatureVerdict::kStale: return "signing timestamp more than a minute old";
    case SignatureVerdict::kTooManyStreams: return "too many signed streams";
  }
  return "unknown signature verdict";
}

SignatureVerdict SignatureVerifier::check(const Frame& frame, std::uint64_t local_now) {
  if (!frame.is_signed || frame.size_bytes < kSignatureBytes) return SignatureVerdict::kUnsigned;
  std::uint8_t expected[6];
  const std::size_t signed_bytes = frame.size_bytes - 6;
  compute_signature(key_, frame.bytes, signed_bytes, expected);
  // Constant-time compare: the signature is the only secret-dependent value here.
  std::uint8_t diff = 0;
  for (int i = 0; i < 6; ++i) diff = static_cast<std::uint8_t>(diff | (expected[i] ^ frame.bytes[signed_bytes + i]));
  if (diff != 0) return SignatureVerdict::kBadSignature;

  Stream* stream = nullptr;
  for (std::size_t i = 0; i < stream_count_; ++i) {
    Stream& s = streams_[i];
    if (s.system_id == frame.system_id && s.component_id == frame.component_id && s.link_id == frame.link_id) {
      stream = &s;
      break;
    }
  }
  if (stream != nullptr) {
    if (frame.signing_timestamp <= stream->last_timestamp) return SignatureVerdict::kReplay;
  } else {
    const std::uint64_t reference = local_now > newest_timestamp_ ? local_now : newest_timestamp_;
    if (frame.signing_timestamp + kStaleTicks < reference) return SignatureVerdict::kStale;
    if (stream_count_ == kMaxStreams) return SignatureVerdict::kTooManyStreams;
    stream = &streams_[stream_count_++];
    stream->system_id = frame.system_id;
    stream->component_id = frame.component_id;
    stream->link_id = frame.link_id;
  }
  stream->last_timestamp = frame.signing_timestamp;
  if (frame.signing_timestamp > newest_timestamp_) newest_timestamp_ = frame.signing_timestamp;
  return SignatureVerdict::kAccepted;
}

}  // namespace vantage::hal::mavlink
