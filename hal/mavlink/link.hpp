#pragma once
// A byte link to the vehicle: UDP datagrams or a serial line. Non-blocking; the motion driver polls it.
#include <cstddef>
#include <cstdint>
#include <string>

namespace vantage::hal::mavlink {

class ByteLink {
 public:
  // false when the bytes could not be handed to the OS (the frame is lost; the link stays usable).
  virtual bool send(const std::uint8_t* data, std::size_t length) = 0;
  // Bytes read into buffer (> 0), 0 when nothing is waiting, -1 on a link error.
  virtual long receive(std::uint8_t* buffer, std::size_t capacity) = 0;
  virtual const char* name() const = 0;

 protected:
  ~ByteLink() = default;
};

// UDP to the vehicle at host:port from an ephemeral (or given) local port. The companion speaks first:
// vehicles and routers answer the address the last datagram came from.
class UdpLink final : public ByteLink {
 public:
  UdpLink() = default;
  ~UdpLink();
  UdpLink(const UdpLink&) = delete;
  UdpLink& operator=(const UdpLink&) = delete;

  // Empty string on success, else one line saying what failed.
  std::string open(const std::string& host, std::uint16_t port, std::uint16_t local_port = 0);
  void close();
  bool is_open() const { return fd_ >= 0; }
  std::uint16_t local_port() const;

  bool send(const std::uint8_t* data, std::size_t length) override;
  long receive(std::uint8_t* buffer, std::size_t capacity) override;
  const char* name() const override { return name_; }

 private:
  int fd_ = -1;
  char name_[64] = "udp:closed";
  unsigned char remote_[16] = {};  // sockaddr_in
};

// A serial line through termios: raw 8N1, no flow control, non-blocking.
class SerialLink final : public ByteLink {
 public:
  SerialLink() = default;
  ~SerialLink();
  SerialLink(const SerialLink&) = delete;
  SerialLink& operator=(const SerialLink&) = delete;

  std::string open(const std::string& path, int baud);
  void close();
  bool is_open() const { return fd_ >= 0; }

  bool send(const std::uint8_t* data, std::size_t length) override;
  long receive(std::uint8_t* buffer, std::size_t capacity) override;
  const char* name() const override { return name_; }

 private:
  int fd_ = -1;
  char name_[96] = "serial:closed";
};

// "udp:HOST:PORT" or "serial:PATH:BAUD" split into parts; empty string on success.
struct Endpoint {
  enum class Kind { kUdp, kSerial } kind = Kind::kUdp;
  std::string host_or_path;
  int port_or_baud = 0;
};
std::string parse_endpoint(const std::string& text, Endpoint* out);

}  // namespace vantage::hal::mavlink
