#include <arpa/inet.h>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include "hal/mavlink/link.hpp"

namespace vantage::hal::mavlink {

static_assert(sizeof(sockaddr_in) <= 16, "remote_ holds a sockaddr_in");

UdpLink::~UdpLink() { close(); }

void UdpLink::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

std::string UdpLink::open(const std::string& host, std::uint16_t port, std::uint16_t local_port) {
  close();
  sockaddr_in remote{};
  remote.sin_family = AF_INET;
  remote.sin_port = htons(port);
  if (inet_pton(AF_INET, host.c_str(), &remote.sin_addr) != 1) {
    return "udp: '" + host + "' is not an IPv4 address";
  }
  if (port == 0) return "udp: vehicle port 0 is not a port";
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) return std::string("udp: socket: ") + std::strerror(errno);
  sockaddr_in local{};
  local.sin_family = AF_INET;
  local.sin_port = htons(local_port);
  local.sin_addr.s_addr = htonl(INADDR_ANY);
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&local), sizeof local) != 0) {
    const std::string error = std::string("udp: bind to local port ") + std::to_string(local_port) + ": " + std::strerror(errno);
    ::close(fd);
    return error;
  }
  fd_ = fd;
  std::memcpy(remote_, &remote, sizeof remote);
  std::snprintf(name_, sizeof name_, "udp:%s:%u", host.c_str(), static_cast<unsigned>(port));
  return {};
}

std::uint16_t UdpLink::local_port() const {
  if (fd_ < 0) return 0;
  sockaddr_in local{};
  socklen_t length = sizeof local;
  if (::getsockname(fd_, reinterpret_cast<sockaddr*>(&local), &length) != 0) return 0;
  return ntohs(local.sin_port);
}

bool UdpLink::send(const std::uint8_t* data, std::size_t length) {
  if (fd_ < 0) return false;
  const ssize_t sent = ::sendto(fd_, data, length, MSG_NOSIGNAL, reinterpret_cast<const sockaddr*>(remote_),
                                sizeof(sockaddr_in));
  return sent == static_cast<ssize_t>(length);
}

long UdpLink::receive(std::uint8_t* buffer, std::size_t capacity) {
  if (fd_ < 0) return -1;
  sockaddr_in from{};
  socklen_t from_length = sizeof from;
  const ssize_t got = ::recvfrom(fd_, buffer, capacity, 0, reinterpret_cast<sockaddr*>(&from), &from_length);
  if (got < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return 0;
    // ICMP port unreachable (vehicle not listening yet) surfaces as ECONNREFUSED on some stacks: not fatal.
    if (errno == ECONNREFUSED) return 0;
    return -1;
  }
  // Only the vehicle's address may talk to us.
  const sockaddr_in* remote = reinterpret_cast<const sockaddr_in*>(remote_);
  if (from.sin_addr.s_addr != remote->sin_addr.s_addr || from.sin_port != remote->sin_port) return 0;
  return static_cast<long>(got);
}

}  // namespace vantage::hal::mavlink
