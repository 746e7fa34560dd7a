#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <termios.h>
#include <unistd.h>

#include "hal/mavlink/link.hpp"

namespace vantage::hal::mavlink {
namespace {

bool baud_constant(int baud, speed_t* out) {
  switch (baud) {
    case 9600: *out = B9600; return true;
    case 19200: *out = B19200; return true;
    case 38400: *out = B38400; return true;
    case 57600: *out = B57600; return true;
    case 115200: *out = B115200; return true;
    case 230400: *out = B230400; return true;
    case 460800: *out = B460800; return true;
    case 921600: *out = B921600; return true;
    case 1500000: *out = B1500000; return true;
    default: return false;
  }
}

}  // namespace

SerialLink::~SerialLink() { close(); }

void SerialLink::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

std::string SerialLink::open(const std::string& path, int baud) {
  close();
  speed_t speed = 0;
  if (!baud_constant(baud, &speed)) return "serial: unsupported baud rate " + std::to_string(baud);
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return "serial: " + path + ": " + std::strerror(errno);
  termios tty{};
  if (::tcgetattr(fd, &tty) != 0) {
    const std::string error = "serial: " + path + " is not a terminal device: " + std::strerror(errno);
    ::close(fd);
    return error;
  }
  ::cfmakeraw(&tty);
  tty.c_cflag |= CLOCAL | CREAD;
  tty.c_cflag &= ~(CSTOPB | CRTSCTS | PARENB);
  tty.c_cc[VMIN] = 0;
  tty.c_cc[VTIME] = 0;
  ::cfsetispeed(&tty, speed);
  ::cfsetospeed(&tty, speed);
  if (::tcsetattr(fd, TCSANOW, &tty) != 0) {
    const std::string error = "serial: " + path + ": tcsetattr: " + std::strerror(errno);
    ::close(fd);
    return error;
  }
  ::tcflush(fd, TCIOFLUSH);
  fd_ = fd;
  std::snprintf(name_, sizeof name_, "serial:%s:%d", path.c_str(), baud);
  return {};
}

bool SerialLink::send(const std::uint8_t* data, std::size_t length) {
  if (fd_ < 0) return false;
  std::size_t done = 0;
  // A full output queue drops the rest of the frame rather than blocking the control loop.
  while (done < length) {
    const ssize_t n = ::write(fd_, data + done, length - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    done += static_cast<std::size_t>(n);
  }
  return true;
}

long SerialLink::receive(std::uint8_t* buffer, std::size_t capacity) {
  if (fd_ < 0) return -1;
  const ssize_t n = ::read(fd_, buffer, capacity);
  if (n < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return 0;
    return -1;
  }
  return static_cast<long>(n);
}

std::string parse_endpoint(const std::string& text, Endpoint* out) {
  const std::size_t first = text.find(':');
  const std::size_t last = text.rfind(':');
  if (first == std::string::npos || last == first) {
    return "endpoint '" + text + "' is not udp:HOST:PORT or serial:PATH:BAUD";
  }
  const std::string kind = text.substr(0, first);
  const std::string middle = text.substr(first + 1, last - first - 1);
  const std::string number = text.substr(last + 1);
  char* end = nullptr;
  const long value = std::strtol(number.c_str(), &end, 10);
  if (number.empty() || *end != '\0' || value <= 0) return "endpoint '" + text + "': '" + number + "' is not a positive number";
  if (kind == "udp") {
    if (value > 65535) return "endpoint '" + text + "': port out of range";
    out->kind = Endpoint::Kind::kUdp;
  } else if (kind == "serial") {
    out->kind = Endpoint::Kind::kSerial;
  } else {
    return "endpoint '" + text + "': kind '" + kind + "' is not udp or serial";
  }
  if (middle.empty()) return "endpoint '" + text + "': empty host or path";
  out->host_or_path = middle;
  out->port_or_baud = static_cast<int>(value);
  return {};
}

}  // namespace vantage::hal::mavlink
