#include "hal/mavlink/frame.hpp"

#include <cstring>

#include "hal/mavlink/crc16.hpp"
#include "hal/mavlink/wire.hpp"

namespace vantage::hal::mavlink {

void FrameWriter::enable_signing(const SigningKey& key, std::uint8_t link_id) {
  signing_ = true;
  key_ = key;
  link_id_ = link_id;
}

std::size_t FrameWriter::write_payload(std::uint32_t message_id, const std::uint8_t* payload, std::size_t length,
                                       std::uint8_t* out) {
  const MessageSpec* spec = find_message_spec(message_id);
  if (length > kMaxPayloadBytes) length = kMaxPayloadBytes;
  // MAVLink 2 drops trailing zero bytes of the payload (at least one byte stays).
  while (length > 1 && payload[length - 1] == 0) --length;
  out[0] = kStx;
  out[1] = static_cast<std::uint8_t>(length);
  out[2] = signing_ ? kIncompatSigned : 0;
  out[3] = 0;
  out[4] = sequence_++;
  out[5] = system_id_;
  out[6] = component_id_;
  out[7] = static_cast<std::uint8_t>(message_id);
  out[8] = static_cast<std::uint8_t>(message_id >> 8);
  out[9] = static_cast<std::uint8_t>(message_id >> 16);
  std::memcpy(out + kHeaderBytes, payload, length);
  std::uint16_t crc = crc16(out + 1, kHeaderBytes - 1 + length);
  crc = crc16_accumulate(spec != nullptr ? spec->crc_extra : 0, crc);
  put_u16(out + kHeaderBytes + length, crc);
  std::size_t size = kHeaderBytes + length + kChecksumBytes;
  if (!signing_) return size;
  std::uint64_t timestamp = signing_timestamp_now();
  if (timestamp <= last_timestamp_) timestamp = last_timestamp_ + 1;
  last_timestamp_ = timestamp;
  out[size] = link_id_;
  for (int i = 0; i < 6; ++i) out[size + 1 + i] = static_cast<std::uint8_t>(timestamp >> (8 * i));
  compute_signature(key_, out, size + 7, out + size + 7);
  return size + kSignatureBytes;
}

void FrameParser::drop(std::size_t count, bool count_as_discarded) {
  head_ += count;
  if (count_as_discarded) stats_.discarded_bytes += count;
  if (head_ == tail_) head_ = tail_ = 0;
}

std::size_t FrameParser::write(const std::uint8_t* data, std::size_t length) {
  if (head_ > 0) {
    std::memmove(window_.data(), window_.data() + head_, tail_ - head_);
    tail_ -= head_;
    head_ = 0;
  }
  const std::size_t room = window_.size() - tail_;
  const std::size_t taken = length < room ? length : room;
  std::memcpy(window_.data() + tail_, data, taken);
  tail_ += taken;
  return taken;
}

bool FrameParser::next(Frame* out) {
  while (tail_ > head_) {
    const std::uint8_t* start = window_.data() + head_;
    const std::size_t available = tail_ - head_;
    if (start[0] != kStx) {
      const void* stx = std::memchr(start, kStx, available);
      drop(stx != nullptr ? static_cast<std::size_t>(static_cast<const std::uint8_t*>(stx) - start) : available, true);
      continue;
    }
    if (available < kHeaderBytes) return false;
    const std::uint8_t length = start[1];
    const std::uint8_t incompat = start[2];
    if ((incompat & ~kIncompatSigned) != 0) {
      ++stats_.bad_flags;
      drop(1, true);
      continue;
    }
    const bool is_signed = (incompat & kIncompatSigned) != 0;
    const std::uint32_t message_id = static_cast<std::uint32_t>(start[7]) | (static_cast<std::uint32_t>(start[8]) << 8) |
                                     (static_cast<std::uint32_t>(start[9]) << 16);
    // Known id and plausible length are checked from the header alone, so a bogus length never makes
    // the parser wait for (and swallow) the frames behind it.
    const MessageSpec* spec = find_message_spec(message_id);
    if (spec == nullptr) {
      ++stats_.unknown_messages;
      drop(1, true);
      continue;
    }
    if (length > spec->max_length) {
      ++stats_.bad_lengths;
      drop(1, true);
      continue;
    }
    const std::size_t frame_size = kHeaderBytes + length + kChecksumBytes + (is_signed ? kSignatureBytes : 0);
    if (available < frame_size) return false;
    std::uint16_t crc = crc16(start + 1, kHeaderBytes - 1 + length);
    crc = crc16_accumulate(spec->crc_extra, crc);
    if (crc != get_u16(start + kHeaderBytes + length)) {
      ++stats_.crc_errors;
      drop(1, true);
      continue;
    }
    payload_.fill(0);
    std::memcpy(payload_.data(), start + kHeaderBytes, length);
    out->sequence = start[4];
    out->system_id = start[5];
    out->component_id = start[6];
    out->incompat_flags = incompat;
    out->message_id = message_id;
    out->payload_length = length;
    out->payload = payload_.data();
    out->is_signed = is_signed;
    out->link_id = 0;
    out->signing_timestamp = 0;
    if (is_signed) {
      const std::uint8_t* signature = start + kHeaderBytes + length + kChecksumBytes;
      out->link_id = signature[0];
      std::uint64_t timestamp = 0;
      for (int i = 5; i >= 0; --i) timestamp = (timestamp << 8) | signature[1 + i];
      out->signing_timestamp = timestamp;
    }
    out->bytes = start;
    out->size_bytes = frame_size;
    ++stats_.frames;
    // The frame's bytes stay in the window (for signature checks) until the next write().
    head_ += frame_size;
    return true;
  }
  head_ = tail_ = 0;
  return false;
}

}  // namespace vantage::hal::mavlink
